"""`python -m mecanum_fmu doctor`: what another tool needs to load the bundled FMUs.

The FMUs are pythonfmu 0.7 FMUs: their shared library calls the CPython C API but is not
linked against libpython, so a host that is not Python itself (OMSimulator, libcosim's cosim,
a C program) must load libpython first: LD_PRELOAD. Their slave scripts and pythonfmu's
runtime are shipped in each FMU's resources/ and use only the standard library.
"""
from __future__ import annotations

import sys
import sysconfig
from pathlib import Path

from ..models.link import find_libpython  # noqa: F401  (also imported from here)


def doctor_lines(fmu_dir: Path | None = None) -> list[str]:
    from ..models.catalog import MODELS
    from ..models.library import bundled_fmu_path, default_fmu_dir, is_current

    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    lib = find_libpython()
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    lines = [f"python: {sys.executable} ({sys.version.split()[0]})"]
    if lib is not None:
        lines += [f"libpython: {lib}",
                  "for a non-Python host (OMSimulator, cosim, a C program) run it with:",
                  f"LD_PRELOAD={lib}"]
    else:
        lines += ["libpython: not found - this Python is linked statically "
                  f"(Py_ENABLE_SHARED={sysconfig.get_config_var('Py_ENABLE_SHARED')}); "
                  f"non-Python hosts need a shared libpython{version}.so.1.0 of the same "
                  "version (e.g. the distribution's libpython3.X package)"]
    lines.append(f"  if the host cannot find Python's standard library, also set "
                 f"PYTHONHOME={sys.base_prefix}")
    lines.append(f"FMUs ({fmu_dir}):")
    for name in MODELS:
        path = bundled_fmu_path(name, fmu_dir)
        if not path.is_file():
            state = "missing - build with `python -m mecanum_fmu fmus`"
        elif is_current(name, path):
            state = "up to date"
        else:
            state = "stale - rebuild with `python -m mecanum_fmu fmus`"
        lines.append(f"  {path}  ({state})")
    lines.append("the FMUs ship pythonfmu's runtime and their slave script in resources/ "
                 "(standard library only); no extra Python packages are needed")
    return lines
