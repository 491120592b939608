"""Zip archives from users (FMUs, SSPs) read as hostile data.

Every member name is checked before anything is written (no absolute paths, no `..`, no
backslashes, no name that is both a file and a folder), declared sizes are checked against
limits before extraction, and the bytes actually inflated are counted during extraction, so a
zip bomb stops at the limit whatever its headers claim. Damaged archives (bad CRC, truncated,
unknown compression) become an ArchiveError with a one-line reason; a failed extraction leaves
nothing behind.
"""
from __future__ import annotations

import io
import lzma
import re
import shutil
import tempfile
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from .storage import atomic_open

MAX_MEMBER_BYTES = 1 << 30          # one inflated member (an FMU inside an SSP, a binary)
MAX_TOTAL_BYTES = 2 << 30           # everything inflated from one archive
MAX_MEMBERS = 10_000
CHUNK = 1 << 20
# what zipfile and its decompressors raise on a damaged or unsupported archive
ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, lzma.LZMAError, EOFError, NotImplementedError,
              RuntimeError, ValueError, OverflowError, OSError)


class ArchiveError(ValueError):
    """An archive that cannot be used safely; the message is the user-facing reason."""


def _size(n: int) -> str:
    return f"{n / (1 << 30):.3g} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.3g} MiB"


def name_problem(name: str) -> str | None:
    """Why a member name is unsafe to extract, or None. Folder entries end with '/'."""
    if not name or "\0" in name or "\\" in name:
        return "has an empty name, a NUL or a backslash"
    if name.startswith("/") or re.match(r"^[A-Za-z]:", name):
        return "is an absolute path"
    if name == ".":
        return "names the extraction folder itself, not a file in it"
    parts = name.rstrip("/").split("/")
    if any(part in ("", ".", "..") for part in parts):
        return "has an empty, '.' or '..' path part (it could leave the extraction folder)"
    return None


def checked_members(zf: zipfile.ZipFile, max_member: int | None = None,
                    max_total: int | None = None) -> list[zipfile.ZipInfo]:
    """Every member, after checking names and declared sizes (limits: the module's
    MAX_MEMBER_BYTES and MAX_TOTAL_BYTES by default). Raises ArchiveError."""
    max_member = MAX_MEMBER_BYTES if max_member is None else max_member
    max_total = MAX_TOTAL_BYTES if max_total is None else max_total
    infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise ArchiveError(f"has {len(infos)} members (limit {MAX_MEMBERS})")
    # "./" is the archive's own folder (some zip writers add it): nothing to extract
    infos = [info for info in infos if info.filename != "./"]
    files, folders, total = set(), set(), 0
    for info in infos:
        name = info.filename
        problem = name_problem(name)
        if problem:
            raise ArchiveError(f"member {name!r:.120} {problem}")
        stem = name.rstrip("/")
        parents = stem.split("/")[:-1]
        folders.update("/".join(parents[:i + 1]) for i in range(len(parents)))
        if name.endswith("/"):
            folders.add(stem)
            continue
        if stem in files:
            raise ArchiveError(f"member {name!r:.120} appears twice")
        files.add(stem)
        if info.file_size > max_member:
            raise ArchiveError(f"member {name!r:.120} inflates to {_size(info.file_size)} "
                               f"(limit {_size(max_member)} per member)")
        total += info.file_size
    if total > max_total:
        raise ArchiveError(f"inflates to {_size(total)} in all (limit {_size(max_total)})")
    clash = sorted(files & folders)
    if clash:
        raise ArchiveError(f"member {clash[0]!r:.120} is both a file and a folder")
    return infos


def copy_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, out: BinaryIO,
                limit: int | None = None) -> int:
    """Inflate one member into out, counting bytes: never more than limit (default
    MAX_MEMBER_BYTES) or than its declared size. Returns the bytes written. Raises
    ArchiveError."""
    limit = MAX_MEMBER_BYTES if limit is None else limit
    allowed, written = min(limit, info.file_size), 0

    def damaged(err: BaseException) -> ArchiveError:
        return ArchiveError(f"member {info.filename!r:.120} is damaged: "
                            f"{getattr(err, 'strerror', None) or err}")
    try:
        src = zf.open(info)
    except ZIP_ERRORS as err:
        raise damaged(err) from None
    with src:
        while True:
            try:
                chunk = src.read(CHUNK)
            except ZIP_ERRORS as err:
                raise damaged(err) from None
            if not chunk:
                break
            written += len(chunk)
            if written > allowed:
                raise ArchiveError(f"member {info.filename!r:.120} inflates to more than "
                                   + ("its declared size" if allowed == info.file_size
                                      else _size(limit)))
            out.write(chunk)
    return written


def read_member(zf: zipfile.ZipFile, name: str, limit: int) -> bytes:
    """The bytes of one member (at most limit). Raises KeyError when absent, ArchiveError."""
    info = zf.getinfo(name)
    if info.file_size > limit:
        raise ArchiveError(f"member {name!r:.120} inflates to {_size(info.file_size)} "
                           f"(limit {_size(limit)})")
    buffer = io.BytesIO()
    copy_member(zf, info, buffer, limit)
    return buffer.getvalue()


def extract_file(zf: zipfile.ZipFile, info: zipfile.ZipInfo, target: Path,
                 limit: int | None = None) -> Path:
    """Inflate one member to target atomically (a hidden partial file, renamed when
    complete; removed on any failure)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(target, "wb", unique=True) as out:
        copy_member(zf, info, out, limit)
    return target


def extract_all(path: Path | str, prefix: str,
                leave: Callable[[list[str]], set[str]] | None = None) -> str:
    """Extract the archive at path into a new temporary folder and return it, but the members
    leave(all names) names; on any failure the folder is removed and ArchiveError raised."""
    folder = tempfile.mkdtemp(prefix=prefix)
    try:
        with zipfile.ZipFile(path) as zf:
            total = 0
            members = checked_members(zf)
            left = leave([i.filename for i in members]) if leave else set()
            for info in (i for i in members if i.filename not in left):
                target = Path(folder, *info.filename.rstrip("/").split("/"))
                if info.filename.endswith("/"):
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                with open(target, "wb") as out:
                    total += copy_member(zf, info, out)
                if total > MAX_TOTAL_BYTES:
                    raise ArchiveError(f"inflates to more than {_size(MAX_TOTAL_BYTES)}")
    except ArchiveError:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    except ZIP_ERRORS as err:
        shutil.rmtree(folder, ignore_errors=True)
        raise ArchiveError(f"cannot be extracted: {getattr(err, 'strerror', None) or err}") from None
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return folder
