"""Shared fixtures: the four bundled FMUs, built once per test session."""
import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

try:
    import mecanum_fmu  # noqa: F401
except ImportError:  # package not installed: fall back to the src layout
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

MODEL_NAMES = ("VelocitySource", "Center2Wheel", "Wheel2Center", "PoseIntegrator", "PathFollower",
               # the other chassis (docs/chassis.md, tests/test_chassis.py)
               "OmniCenter2Wheel", "OmniWheel2Center", "FieldToBody", "Bicycle", "SteeringSource")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    """The folder of the bundled FMUs (a scenario's --fmu-dir), built once into a fresh
    temporary folder.

    Build before any FMU is loaded into this process: the build imports each slave script
    under its FMU module name and must not meet an already loaded copy.
    """
    from mecanum_fmu.models.build import build_all

    dest = tmp_path_factory.mktemp("built_fmus")
    paths = [Path(p) for p in build_all(dest)]
    assert sorted(p.stem for p in paths) == sorted(MODEL_NAMES)
    for path in paths:
        assert path.is_file() and path.parent == dest
    return dest


@pytest.fixture(scope="session")
def built_fmus(fmu_dir):
    """modelName -> Path of the freshly built FMU."""
    return {name: fmu_dir / f"{name}.fmu" for name in MODEL_NAMES}


def pytest_sessionfinish(session, exitstatus):
    session.config._mecanum_exitstatus = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave without interpreter shutdown, as `mecanum_fmu.cli.exit_with` does: with pythonfmu
    FMUs loaded, CPython's finalization aborts now and then. The report is printed by now."""
    if hasattr(config, "_mecanum_exitstatus"):
        from mecanum_fmu.process import exit_now
        exit_now(config._mecanum_exitstatus)
