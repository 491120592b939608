"""What a sweep checks on the command line before its first run: the worker count against what
this machine can start, and that a --scheduler address answers as a Dask scheduler does.

A Dask scheduler greets every connection first (distributed's TCP comm: an 8-byte little-
endian length, then a message of frames whose first frame is a msgpack mapping naming the
peer's `python` and `compression`). probe_scheduler reads that greeting with a timeout and
bounded sizes before Dask's own client is let near the address: a silent listener or an HTTP
server (which waits for a request) says nothing, garbage bytes are not that greeting, and the
client never reads a length of 3 EiB from them.
"""
from __future__ import annotations

import os
import resource
import socket
import struct
from urllib.parse import urlsplit

import msgpack

from ..errors import Problem, ScenarioError

WORKERS_PER_CORE = 4           # more local worker processes only wait for a core
FILES_PER_WORKER = 16          # descriptors the client holds per local worker (measured: ~9)
FILES_RESERVED = 64            # the client's own: FMUs, the output folder, the terminal
PROBE_TIMEOUT_S = 5.0          # connect, then the greeting
MAX_GREETING = 1 << 16         # bytes; a scheduler's is about 60


def _bad(place: str, message: str) -> ScenarioError:
    return ScenarioError([Problem("command line", place, message)])


def max_local_workers() -> tuple[int, str]:
    """The most local worker processes this machine can start, and why (cores, files)."""
    cores = os.cpu_count() or 1
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    by_files = (max(soft, 0) - FILES_RESERVED) // FILES_PER_WORKER if soft != \
        resource.RLIM_INFINITY else 1 << 30
    by_cores = WORKERS_PER_CORE * cores
    if by_files < by_cores:
        return max(by_files, 0), (f"this process may open {soft} files (ulimit -n) and a local "
                                  f"worker costs about {FILES_PER_WORKER}")
    return by_cores, (f"this machine has {cores} core(s); more than {WORKERS_PER_CORE} "
                      f"worker processes per core only wait for one")


def check_workers(workers: int | None) -> int:
    """The local worker count to start (default: one per core), or ScenarioError."""
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise _bad("--workers", f"{workers!r} is not a worker count; give 1 or more")
    most, why = max_local_workers()
    if most < 1:
        raise _bad("--workers", f"no local worker can be started: {why}; raise the limit "
                                f"(ulimit -n) or use --scheduler")
    if workers > most:
        raise _bad("--workers", f"{workers} local workers is more than this machine can run: "
                                f"{why}; give at most {most}, or use --scheduler")
    return workers


def scheduler_address(text: str) -> tuple[str, int]:
    """(host, port) of a tcp://HOST:PORT address, or ScenarioError."""
    usage = "give tcp://HOST:PORT of one started with `dask scheduler`"
    try:
        parts = urlsplit(text if "://" in text else f"tcp://{text}")
        host, port = parts.hostname, parts.port
    except ValueError as err:
        raise _bad("--scheduler", f"{text!r:.80} is not an address ({err}); {usage}") from None
    if parts.scheme != "tcp" or not host or port is None or parts.path not in ("", "/"):
        raise _bad("--scheduler", f"{text!r:.80} is not a tcp://HOST:PORT address; {usage}")
    return host, port


def probe_scheduler(text: str, timeout: float = PROBE_TIMEOUT_S) -> None:
    """Connect to the address and read a Dask scheduler's greeting, within timeout seconds
    each; ScenarioError naming what answered otherwise."""
    host, port = scheduler_address(text)
    what = f"the Dask scheduler at {text!r:.80}"
    hint = ("give tcp://HOST:PORT of one started with `dask scheduler` (and `dask worker "
            "ADDRESS`s)")
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            greeting = _greeting(sock)
    except socket.timeout:
        raise _bad("--scheduler", f"{what} did not answer within {timeout:g} s (a Dask "
                                  f"scheduler greets at once: something else listens "
                                  f"there, or nothing); {hint}") from None
    except OSError as err:
        raise _bad("--scheduler", f"cannot reach {what}: {err.strerror or err}; "
                                  f"{hint}") from None
    if greeting is None:
        raise _bad("--scheduler", f"what answers at {text!r:.80} is not a Dask scheduler (its "
                                  f"first bytes are not Dask's greeting); {hint}")


def _greeting(sock: socket.socket) -> dict | None:
    """The peer's first message if it is a Dask greeting (a msgpack mapping), else None."""
    head = _read(sock, 8)
    if head is None:
        return None
    (size,) = struct.unpack("<Q", head)
    if not 16 <= size <= MAX_GREETING:
        return None
    body = _read(sock, size)
    if body is None:
        return None
    (count,) = struct.unpack_from("<Q", body)
    if not 1 <= count <= 16 or 8 + 8 * count > size:
        return None
    lengths = struct.unpack_from(f"<{count}Q", body, 8)
    if sum(lengths) != size - 8 - 8 * count:
        return None
    first = body[8 + 8 * count:8 + 8 * count + lengths[0]]
    try:
        message = msgpack.unpackb(first, raw=False)
    except Exception:           # msgpack raises several kinds on bytes that are not its own
        return None
    return message if isinstance(message, dict) and "python" in message else None


def _read(sock: socket.socket, n: int) -> bytes | None:
    """Exactly n bytes, or None when the peer closes first (socket.timeout propagates)."""
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            return None
        data += chunk
    return data
