"""Build the bundled FMUs a scenario names that are missing or stale, before it runs: the one
place that both finds them (library.py) and builds them (build.py, build3.py), so that neither
of those reads the other."""
from __future__ import annotations

from pathlib import Path

from ..errors import Problem, ScenarioError
from .catalog import MODELS
from .library import (bundled_fmu_path, bundled_spec, default_fmu_dir, fmi3_dir, is_current,
                      is_current3)


def build_bundled(scenario, fmu_dir: Path | None = None) -> None:
    """Build the bundled FMUs the scenario (a scenario.Scenario: .components, .label) names
    that are missing or stale (`fmi3/<Model>`: its FMI 3.0 twin in fmu_dir/fmi3). Raises
    ScenarioError naming the component whose build failed."""
    from .build import build_fmu     # startup: pythonfmu, only when building
    from .build3 import build_fmu3
    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    for comp in scenario.components:
        name, fmi3 = bundled_spec(comp.fmu)
        folder = fmi3_dir(fmu_dir) if fmi3 else fmu_dir
        current = is_current3 if fmi3 else is_current
        if name in MODELS and not current(name, bundled_fmu_path(name, folder)):
            try:
                (build_fmu3 if fmi3 else build_fmu)(name, folder)
            except Exception as err:  # the build is ours; report it with the place
                raise ScenarioError([Problem(scenario.label, f"{comp.place}.fmu",
                                             f"building the bundled FMU {comp.fmu} into "
                                             f"{fmu_dir} failed: {err}")]) from err
