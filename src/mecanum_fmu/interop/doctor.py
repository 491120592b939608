"""`python -m mecanum_fmu doctor`: what each bundled FMU needs on a target machine.

Per FMU: whether it is self-contained (carries its Python: the loader, libpython and the
standard-library modules of its slave, models/embed.py) or needs the host to bring Python;
the glibc floor of its Linux binaries (the newest GLIBC_ symbol version any of them needs,
read from the ELF version tables with pyelftools) and the other system libraries they need;
and the win64 story, which cannot be tested here and is stated as it is.
"""
from __future__ import annotations

import re
import sys
import zipfile
from pathlib import Path

from ..models.embed import HOME, REAL_SUFFIX, damage, summary
from ..models.link import BINARY_DIR, Needs, binary_needs, find_libpython

_WIN_PYTHON = re.compile(rb"python3\d*\.dll", re.IGNORECASE)
_GLIBC_LIBS = {"libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2", "librt.so.1",
               "libutil.so.1", "ld-linux-x86-64.so.2"}


def doctor_lines(fmu_dir: Path | None = None) -> list[str]:
    from ..models.catalog import MODELS
    from ..models.library import bundled_fmu_path, default_fmu_dir, is_current

    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    lib = find_libpython()
    lines = [f"python: {sys.executable} ({sys.version.split()[0]}); shared libpython: "
             f"{lib or 'none (statically linked)'}", "build: " + summary(),
             f"FMUs ({fmu_dir}):"]
    for name in MODELS:
        path = bundled_fmu_path(name, fmu_dir)
        if not path.is_file():
            lines.append(f"  {name}: missing - build with `python -m mecanum_fmu fmus`")
            continue
        state = ("up to date" if is_current(name, path)
                 else "stale - rebuild with `python -m mecanum_fmu fmus`")
        lines.append(f"  {name}: {state}; {fmu_needs(path, name)}")
    return lines + _advice()


def fmu_needs(path: Path, name: str) -> str:
    """One line: self-contained or not, glibc floor and other libraries, win64."""
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            elf = {n: binary_needs(zf.read(n)) for n in names if ".so" in n
                   and (n.startswith(BINARY_DIR) or n.startswith(HOME + "lib-dynload/"))}
            dll = f"binaries/win64/{name}.dll"
            win = zf.read(dll) if dll in names else None
            contained = (f"{BINARY_DIR}{name}{REAL_SUFFIX}" in names and HOME + "stdlib.zip" in names
                         and any(n.startswith(BINARY_DIR + "libpython") for n in names))
            broken = damage(zf.read, names) if contained else None
    except (OSError, zipfile.BadZipFile) as err:
        return f"cannot read the FMU: {err}"
    if f"{BINARY_DIR}{name}.so" not in elf:
        return "no Linux binary"
    if broken:
        return (f"DAMAGED: {broken}; its loader refuses it (fmi2Instantiate returns NULL) - "
                "rebuild it with `python -m mecanum_fmu fmus`")
    linux = ("self-contained (carries its Python; the host needs none)" if contained
             else "NOT self-contained: the host must bring Python " + _built_for(elf))
    return f"linux64: {linux}, {_system_needs(elf.values())}; win64: {_win64(win)}"


def _built_for(elf: dict[str, Needs | None]) -> str:
    lib = next((n.libpython for n in elf.values() if n and n.libpython), None)
    return lib.removeprefix("libpython").split(".so")[0] if lib else "of the builder's version"


def _system_needs(needs) -> str:
    found = [n for n in needs if n is not None]
    floor = max((n.glibc for n in found if n.glibc), default=None)
    bundled = {"libpython"}
    others = sorted({lib for n in found for lib in n.needed
                     if lib not in _GLIBC_LIBS and not any(lib.startswith(b) for b in bundled)})
    text = "glibc >= " + ".".join(map(str, floor)) if floor else "glibc (version unknown)"
    return text + (" and " + ", ".join(others) if others else "")


def _win64(dll: bytes | None) -> str:
    if dll is None:
        return "no binary"
    names = sorted({m.decode() for m in _WIN_PYTHON.findall(dll)})
    return ("pythonfmu's own DLL, NOT self-contained (not testable here): it imports "
            f"{', '.join(names) or 'a Python DLL'}, so a Windows host needs a 64-bit Python 3 "
            "installed with its folder on PATH, and the MSVC 2015+ runtime")


def _advice() -> list[str]:
    return [
        "linux64: a self-contained FMU runs in a host without Python (OMSimulator, Ecos' ecos, "
        "a C program), with nothing set (no LD_PRELOAD, PYTHONHOME or PATH change); in a Python "
        "host of the same major.minor it runs in the host's interpreter; in a Python host of "
        "another version fmi2Instantiate fails with a message in the FMU's log (never a crash).",
        "the glibc floor above is what the target machine needs (ldd --version); the FMUs "
        "ship pythonfmu's runtime and their slave script in resources/ (standard library only).",
        "win64: untested here (no Windows machine); the bundled Python is Linux-only."]
