"""Find the FMU behind a component and read its model description (fmpy's reader)."""
from __future__ import annotations

import zipfile
from xml.etree import ElementTree
from pathlib import Path

from fmpy import read_model_description
from fmpy.model_description import ModelDescription

from . import fmu_build


def default_fmu_dir() -> Path:
    """fmus/ in a source checkout; a per-version cache folder for a plain install."""
    repo = fmu_build.PACKAGE_DIR.parent.parent
    if (repo / "pyproject.toml").is_file():
        return repo / "fmus"
    from mecanum_fmu import __version__
    return Path.home() / ".cache" / "mecanum_fmu" / __version__ / "fmus"


def resolve_fmu(spec: str, scenario_dir: Path, fmu_dir: Path) -> Path:
    """A bundled model name -> its FMU (built if missing or stale); otherwise a path
    relative to the scenario file. Raises ValueError with a user-facing reason."""
    if spec in fmu_build.BUNDLED:
        path = fmu_build.bundled_fmu_path(spec, fmu_dir)
        if not fmu_build.is_current(spec, path):
            try:
                fmu_build.build_fmu(spec, fmu_dir)
            except Exception as err:  # the build is ours; report it as an input problem
                raise ValueError(f"building the bundled FMU {spec} into {fmu_dir} failed: {err}") from err
        return path
    if "\0" in spec:
        raise ValueError(f"FMU path {spec!r:.80} contains a NUL character")
    try:
        path = (scenario_dir / spec).resolve() if not Path(spec).is_absolute() else Path(spec)
        exists, is_file, is_dir = path.exists(), path.is_file(), path.is_dir()
    except (OSError, RuntimeError) as err:     # name too long, symlink loop, ...
        raise ValueError(f"FMU {spec!r:.80}: cannot use this path: "
                         f"{getattr(err, 'strerror', None) or err}") from None
    if not exists:
        hint = ""
        if not spec.endswith(".fmu"):
            hint = f" (bundled FMUs: {', '.join(fmu_build.BUNDLED)})"
        raise ValueError(f"FMU {spec!r} not found (looked for {path}){hint}")
    if not is_file:
        raise ValueError(f"FMU {spec!r} is {'a folder' if is_dir else 'a special file'}, "
                         "not an .fmu file")
    return path


def read_description(path: Path) -> ModelDescription:
    """Read and check that the FMU is FMI 2.0 co-simulation. Raises ValueError with the reason."""
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{path.name} is not an FMU (an FMU is a zip archive)")
    try:
        with zipfile.ZipFile(path) as zf:
            if "modelDescription.xml" not in zf.namelist():
                raise ValueError(f"{path.name} has no modelDescription.xml; it is not an FMU")
    except zipfile.BadZipFile as err:
        raise ValueError(f"{path.name} is a damaged zip archive: {err}") from None
    version = _fmi_version(path)        # before fmpy: its FMI 1.0 reader fails on a bare file
    if version is not None and version != "2.0":
        raise ValueError(f"{path.name} is an FMI {version} FMU; this master runs FMI 2.0 "
                         "co-simulation FMUs")
    try:
        md = read_model_description(str(path), validate=False)
    except ValueError:
        raise
    except Exception as err:
        raise ValueError(f"{path.name}: cannot read modelDescription.xml: {err}") from None
    if md.fmiVersion != "2.0":
        raise ValueError(f"{path.name} is an FMI {md.fmiVersion} FMU; this master runs FMI 2.0 "
                         "co-simulation FMUs")
    if md.coSimulation is None:
        raise ValueError(f"{path.name} supports model exchange only; this master needs "
                         "a co-simulation FMU (export it for co-simulation)")
    return md


def _fmi_version(path: Path) -> str | None:
    """The fmiVersion attribute of the root element, or None when it cannot be read."""
    try:
        with zipfile.ZipFile(path) as zf, zf.open("modelDescription.xml") as f:
            for _, elem in ElementTree.iterparse(f, events=("start",)):
                return elem.get("fmiVersion")
    except Exception:       # a broken file is reported by the full read below
        return None
    return None
