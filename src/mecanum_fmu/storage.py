"""Where the project keeps files of its own, and how it writes archives.

- cache_root(): one rule for every cache (built FMUs of a plain install, SSP extractions):
  $XDG_CACHE_HOME/mecanum_fmu, else ~/.cache/mecanum_fmu.
- open_regular() / read_regular(): the one way a user's input file is opened: only a regular
  file is accepted (a FIFO, /dev/zero or a socket would hang or never end), checked on the
  open descriptor before anything is read, and read up to a size limit.
- atomic_path() / atomic_open(): the one "write under a temporary name, then rename" of the
  project (result tables, summaries, plots, archives, extracted members): the temporary file
  is `.<name>.part` beside the target (or `.<name>.<random>.part` when several processes may
  write the same target at once), renamed over the target only when the block ends cleanly,
  removed on any error or signal, so a reader never sees a half-written file.
- FileMemo: the one memory of what a file's content gave (an FMU's hash, its GUID), kept
  while the file is the same one (inode, size, modification time) and older than RACY_NS.
- write_zip(): the one deterministic archive writer (FMUs and SSPs): sorted members, a fixed
  date, fixed permissions, deflated; written atomically, so two writes of the same content are
  byte-identical. Members already deflated in another archive (an FMU's bundled Python) can
  be copied as they are (reuse=), so large unchanged members are compressed once, not per
  archive.
"""
from __future__ import annotations

import contextlib
import copy
import errno
import io
import os
import stat
import struct
import tempfile
import time
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator, Mapping, Sequence

FIXED_DATE = (1980, 1, 1, 0, 0, 0)


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mecanum_fmu"


RACY_NS = 2_000_000_000   # a file's value is kept once the file is older than this (2 s)


class FileMemo:
    """compute(path)'s value per file, computed again only when the file changed (another
    inode, size or modification time: a rebuilt FMU is a new file). A file modified less than
    RACY_NS ago is computed again next time: written again within one tick of the file
    system's clock (same inode, same size), it would keep its modification time and look
    unchanged (git's "racy clean" entries)."""

    def __init__(self, compute):
        self.compute = compute
        self.values: dict[tuple, object] = {}

    def __call__(self, path: Path, st: os.stat_result | None = None):
        """The value for path (st: its stat, if already taken). Raises OSError."""
        st = os.stat(path) if st is None else st
        key = (str(Path(path).resolve()), st.st_ino, st.st_size, st.st_mtime_ns)
        if key in self.values:
            return self.values[key]
        value = self.compute(path)
        if time.time_ns() - st.st_mtime_ns > RACY_NS:
            self.values[key] = value
        return value

    def clear(self) -> None:
        self.values.clear()


class NotARegularFile(ValueError):
    """An input path that is a special file or too large; the message is the reason."""


def open_regular(path: Path | str, limit: int, what: str = "an input file"):
    """The regular file at path opened for binary reading, after checking (on the descriptor,
    so nothing can be swapped in between) that it is a regular file of at most limit bytes.
    Raises OSError (missing, a folder, unreadable) or NotARegularFile."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
        if not stat.S_ISREG(info.st_mode):
            raise NotARegularFile(f"is not a regular file (a pipe, device or socket); give "
                                  f"{what}")
        if info.st_size > limit:
            raise NotARegularFile(f"{info.st_size} bytes is too large for {what} (limit "
                                  f"{limit}); is this the right file?")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: Path | str, limit: int, what: str = "an input file") -> bytes:
    """The bytes of the regular file at path (see open_regular); a file that grows past limit
    while being read is refused too."""
    with open_regular(path, limit, what) as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise NotARegularFile(f"is larger than {limit} bytes, the limit for {what}")
    return data


def zip_bytes(members: Mapping[str, bytes], compresslevel: int | None = None,
              reuse: Path | Sequence[Path] = (), stored: bool = False) -> bytes:
    """The deterministic zip of members (archive name -> bytes), as bytes; stored: not
    compressed (what Python's zipimport reads without zlib). With reuse (archives written
    here), a member whose name, size and CRC match one of reuse's is copied
    compressed as it is there, not compressed again (a bundled libpython: 3 s at level 9)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf, _reusable(reuse) as old:
        for name in sorted(members):
            data = members[name]
            known = old.get(name)
            if known is not None and known[0].file_size == len(data) \
                    and known[0].CRC == zlib.crc32(data):
                _copy_compressed(zf, *known)
                continue
            info = zipfile.ZipInfo(name, date_time=FIXED_DATE)
            info.compress_type = zipfile.ZIP_STORED if stored else zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            info.create_system = 3
            zf.writestr(info, data, compresslevel=compresslevel)
    return buffer.getvalue()


PART = ".part"


def partial_name(path: Path | str) -> Path:
    """The temporary name atomic_path() writes `path` under (when not unique)."""
    path = Path(path)
    return path.with_name(f".{path.name}{PART}")


class atomic_path:
    """`with atomic_path(target) as temp:` write temp (by name: savefig, write_bytes, ...);
    when the block ends cleanly temp is renamed to target, otherwise (an error, Ctrl-C)
    removed. unique: a fresh random temporary name (several writers of one target).
    For a file written over a longer span (a stream): commit() and discard() by hand."""

    def __init__(self, path: Path | str, unique: bool = False):
        self.path = Path(path)
        if unique:
            fd, name = tempfile.mkstemp(dir=self.path.parent, prefix=f".{self.path.name}.",
                                        suffix=PART)
            os.close(fd)
            self.temp = Path(name)
        else:
            self.temp = partial_name(self.path)

    def commit(self) -> Path:
        """Rename the temporary file to the target (OSError on failure)."""
        os.replace(self.temp, self.path)
        return self.path

    def discard(self) -> None:
        try:
            self.temp.unlink(missing_ok=True)
        except OSError:
            pass

    def __enter__(self) -> Path:
        return self.temp

    def __exit__(self, kind, *rest) -> bool:
        try:
            if kind is None:
                self.commit()
        finally:
            self.discard()
        return False


@contextmanager
def atomic_open(path: Path | str, mode: str = "w", unique: bool = False,
                **kwargs) -> Iterator[IO]:
    """open() on atomic_path(path)'s temporary name: renamed to path when the block ends
    cleanly and the file is closed, removed otherwise."""
    with atomic_path(path, unique) as temp:
        with open(temp, mode, **kwargs) as fh:
            yield fh


@contextlib.contextmanager
def _reusable(paths: Path | Sequence[Path]):
    """name -> (ZipInfo, its compressed bytes) of the deflated members of the archives."""
    out = {}
    for path in [paths] if isinstance(paths, (str, Path)) else paths:
        with zipfile.ZipFile(path) as zf, open(path, "rb") as raw:
            for info in zf.infolist():
                if info.compress_type != zipfile.ZIP_DEFLATED:
                    continue
                raw.seek(info.header_offset)
                header = raw.read(30)
                name_len, extra_len = struct.unpack("<HH", header[26:30])
                raw.seek(info.header_offset + 30 + name_len + extra_len)
                out[info.filename] = (info, raw.read(info.compress_size))
    yield out


def _copy_compressed(zf: zipfile.ZipFile, info: zipfile.ZipInfo, data: bytes) -> None:
    """Append an already deflated member (zipfile has no public call for this; these
    attributes have been stable since Python 2: fp, filelist, NameToInfo, start_dir)."""
    new = copy.copy(info)
    new.header_offset = zf.fp.tell()
    new.extra = b""
    new.flag_bits &= ~0x08          # sizes in the local header, no data descriptor
    zf.fp.write(new.FileHeader(zip64=False))
    zf.fp.write(data)
    zf.filelist.append(new)
    zf.NameToInfo[new.filename] = new
    zf.start_dir = zf.fp.tell()
    zf._didModify = True


def write_zip(path: Path, members: Mapping[str, bytes], compresslevel: int | None = None,
              reuse: Path | Sequence[Path] = ()) -> Path:
    """Write members (archive name -> bytes) as a deterministic zip at path, atomically
    (reuse: see zip_bytes)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, unique=True) as temp:
        temp.write_bytes(zip_bytes(members, compresslevel, reuse))
    return path
