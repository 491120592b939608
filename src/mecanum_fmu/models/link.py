"""What an FMU's Linux binaries link to: this interpreter's libpython (what `make fmus` bundles,
models/embed.py) and, read from any ELF file, its needed libraries and glibc floor (doctor).

The ELF reading uses pyelftools (PyPI), so it works without binutils and on any build machine.
"""
from __future__ import annotations

import io
import re
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile

BINARY_DIR = "binaries/linux64/"
_GLIBC = re.compile(r"^GLIBC_(\d+(?:\.\d+)*)$")


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


@dataclass(frozen=True)
class Needs:
    """What one ELF shared library asks the dynamic loader for."""
    needed: tuple[str, ...]         # DT_NEEDED entries
    runpath: str | None
    glibc: tuple[int, ...] | None   # the newest GLIBC_x.y symbol version it needs, or None

    @property
    def glibc_text(self) -> str:
        return "glibc " + ".".join(map(str, self.glibc)) if self.glibc else "no glibc version"

    @property
    def libpython(self) -> str | None:
        return next((n for n in self.needed if n.startswith("libpython")), None)


def binary_needs(data: bytes) -> Needs | None:
    """Needs of one ELF shared library (its bytes), or None when it is not ELF."""
    try:
        elf = ELFFile(io.BytesIO(data))
        dynamic = elf.get_section_by_name(".dynamic")
        needed, runpath = [], None
        for tag in dynamic.iter_tags() if dynamic is not None else ():
            if tag.entry.d_tag == "DT_NEEDED":
                needed.append(tag.needed)
            elif tag.entry.d_tag in ("DT_RUNPATH", "DT_RPATH"):
                runpath = getattr(tag, "runpath", None) or getattr(tag, "rpath", None)
        return Needs(tuple(needed), runpath, _glibc_floor(elf))
    except (ELFError, ValueError, KeyError):
        return None


def _glibc_floor(elf: ELFFile) -> tuple[int, ...] | None:
    """The highest GLIBC_ version among the versions the library requires (.gnu.version_r)."""
    section = elf.get_section_by_name(".gnu.version_r")
    versions = []
    for _, auxiliaries in section.iter_versions() if section is not None else ():
        for aux in auxiliaries:
            match = _GLIBC.match(aux.name)
            if match:
                versions.append(tuple(int(p) for p in match.group(1).split(".")))
    return max(versions) if versions else None
