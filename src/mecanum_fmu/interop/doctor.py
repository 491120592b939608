"""`python -m mecanum_fmu doctor`: what each bundled FMU needs in another FMI tool.

The FMUs are pythonfmu FMUs: their shared library runs the CPython C API. `make fmus` links
each Linux binary to the libpython of the interpreter that built it (a needed-library entry
plus a runpath, models/link.py), so a host that is not Python itself (OMSimulator, Ecos'
`ecos`, a C program) loads it with nothing set - as long as that libpython is where the
runpath says. doctor reports, per FMU, the libpython it needs and whether it is found, and what
to do where it is not (FMUs built elsewhere by plain pythonfmu still need LD_PRELOAD).
"""
from __future__ import annotations

import sys
import zipfile
from pathlib import Path

from ..models.link import binary_needs, find_libpython  # noqa: F401  (also imported from here)


def doctor_lines(fmu_dir: Path | None = None) -> list[str]:
    from ..models.catalog import MODELS
    from ..models.library import bundled_fmu_path, default_fmu_dir, is_current

    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    lib = find_libpython()
    lines = [f"python: {sys.executable} ({sys.version.split()[0]}); shared libpython: "
             f"{lib or 'none (statically linked)'}", f"FMUs ({fmu_dir}):"]
    for name in MODELS:
        path = bundled_fmu_path(name, fmu_dir)
        if not path.is_file():
            lines.append(f"  {name}: missing - build with `python -m mecanum_fmu fmus`")
            continue
        state = "up to date" if is_current(name, path) else "stale - rebuild with `python -m mecanum_fmu fmus`"
        lines.append(f"  {name}: {state}; {_needs_line(path, name)}")
    lines += _advice(lib)
    return lines


def _needs_line(path: Path, name: str) -> str:
    try:
        with zipfile.ZipFile(path) as zf:
            needs = binary_needs(zf.read(f"binaries/linux64/{name}.so"))
    except (KeyError, OSError, zipfile.BadZipFile):
        return "no Linux binary"
    if needs is None:
        return "cannot inspect the binary (patchelf not installed)"
    if needs.soname is None:
        return "not linked to a libpython: non-Python hosts need LD_PRELOAD=<libpython>"
    where = f"found: {needs.found}" if needs.found else f"NOT FOUND in {needs.runpath}"
    return f"needs {needs.soname} (Python {_version(needs.soname)}), {where}"


def _version(soname: str) -> str:
    return soname.removeprefix("libpython").split(".so")[0] or "?"


def _advice(lib: Path | None) -> list[str]:
    return [
        "a non-Python host (OMSimulator, Ecos' ecos, a C program) loads these FMUs as they are "
        "when the libpython above is found (docs/openmodelica.md).",
        "where it is NOT FOUND (the FMUs were copied to another machine): rebuild them there "
        "with `python -m mecanum_fmu fmus`, or install that Python version's shared library "
        "and point LD_LIBRARY_PATH at its folder.",
        "FMUs built elsewhere by plain pythonfmu (not linked): run the host with "
        f"LD_PRELOAD={lib or '<a shared libpython of the same version>'}",
        f"if the host cannot find Python's standard library, also set PYTHONHOME={sys.base_prefix}",
        "the FMUs ship pythonfmu's runtime and their slave script in resources/ (standard "
        "library only); no extra Python packages are needed"]
