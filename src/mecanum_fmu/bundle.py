"""Where the Python an FMU of ours carries sits in it (models/embed.py writes it, the loader
models/loader/loader.c reads it), and what of it a process with its own Python never opens."""
from __future__ import annotations

from collections.abc import Iterable

HOME = "resources/python/"          # the bundled standard library: stdlib.zip, lib-dynload/
MANIFEST = HOME + "MANIFEST"        # the loader's list of the bundled files (size, SHA-256)
LIBPYTHON = "libpython"             # binaries/<platform>/libpython3.X.so.1.0


def unopened_in_python(names: Iterable[str]) -> set[str]:
    """The members of an FMU of ours (it has a MANIFEST) that a process running Python of its
    own never opens: the loader uses that interpreter (or refuses one of another version), so
    the bundled one, its libpython and its standard library, stays shut (9 of the 10 MB each
    FMU unpacks to). The MANIFEST is read (the loader checks pythonfmu's library by it). None
    of another FMU's members."""
    names = set(names)
    if MANIFEST not in names:
        return set()
    return {n for n in names if n != MANIFEST and (
        n.startswith(HOME) or n.startswith("binaries/")
        and n.rsplit("/", 1)[-1].startswith(LIBPYTHON))}
