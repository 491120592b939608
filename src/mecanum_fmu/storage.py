"""Where the project keeps files of its own, and how it writes archives.

- cache_root(): one rule for every cache (built FMUs of a plain install, SSP extractions):
  $XDG_CACHE_HOME/mecanum_fmu, else ~/.cache/mecanum_fmu.
- write_zip(): the one deterministic archive writer (FMUs and SSPs): sorted members, a fixed
  date, fixed permissions, deflated; written under a temporary name and renamed, so a reader
  never sees a half-written archive and two writes of the same content are byte-identical.
"""
from __future__ import annotations

import os
import zipfile
from pathlib import Path
from typing import Mapping

FIXED_DATE = (1980, 1, 1, 0, 0, 0)


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mecanum_fmu"


def write_zip(path: Path, members: Mapping[str, bytes], compresslevel: int | None = None) -> Path:
    """Write members (archive name -> bytes) as a deterministic zip at path, atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".part")
    try:
        with zipfile.ZipFile(partial, "w") as zf:
            for name in sorted(members):
                info = zipfile.ZipInfo(name, date_time=FIXED_DATE)
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                info.create_system = 3
                zf.writestr(info, members[name], compresslevel=compresslevel)
        os.replace(partial, path)
    finally:
        if partial.exists():
            partial.unlink()
    return path
