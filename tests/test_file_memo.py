"""storage.FileMemo: a file's value computed once while the file is the same one (the FMU's
hash for the runtime, its GUID for the stale check), again when it changed or is too new."""
import os
import time

from mecanum_fmu.storage import RACY_NS, FileMemo


def _counting():
    calls = []

    def compute(path):
        calls.append(path)
        return path.read_bytes()
    return calls, FileMemo(compute)


def _age(path, seconds: float) -> None:
    then = time.time_ns() - int(seconds * 1e9)
    os.utime(path, ns=(then, then))


def test_an_old_file_is_read_once_and_again_when_replaced_or_changed(tmp_path):
    calls, memo = _counting()
    path = tmp_path / "a.fmu"
    path.write_bytes(b"one")
    _age(path, 10)
    assert memo(path) == memo(path) == b"one" and len(calls) == 1
    fresh = tmp_path / "b.fmu"                     # rebuilt: a new file renamed over it
    fresh.write_bytes(b"two")
    _age(fresh, 10)
    fresh.replace(path)
    assert memo(path) == b"two" and len(calls) == 2
    path.write_bytes(b"three!")                    # the same inode, another size
    _age(path, 10)
    assert memo(path) == b"three!" and len(calls) == 3


def test_a_file_written_within_the_racy_window_is_read_every_time(tmp_path):
    calls, memo = _counting()
    path = tmp_path / "a.fmu"
    then = time.time_ns() - RACY_NS // 4
    path.write_bytes(b"one")
    os.utime(path, ns=(then, then))
    memo(path)
    path.write_bytes(b"two")                # the same inode, size and modification time
    os.utime(path, ns=(then, then))
    assert memo(path) == b"two" and len(calls) == 2
