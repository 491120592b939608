"""The process-wide FMU state: extractions, kept instances, FMU log messages, callbacks.

One process may run thousands of simulations (a sweep worker does), so what is costly or unsafe
to repeat is done once per process and kept here:

- each FMU content is extracted once (keyed by its sha256), but for the Python an FMU of ours
  carries, which this process, a Python itself, never opens (bundle.unopened_in_python: 9 of
  its 10 MB, 0.06 s of each FMU's start); its shared library is never unloaded: pythonfmu's
  library crashes when unloaded and loaded again in one process;
- instances that ended a run cleanly are kept and reset (fmi2Reset) for the next run instead
  of being freed: every fmi2Instantiate of a pythonfmu FMU runs its slave script again and
  leaks ~18 KB (1,000 runs of four FMUs grew by 70 MB); a reset costs ~0.4 KB;
- every instance has its own log, reached through the callbacks' componentEnvironment, so two
  simulations with an instance of the same name never share messages;
- a pythonfmu FMU imports its slave script by module name into this process's one
  sys.modules: before it is instantiated, another FMU's module of that name is forgotten
  (own_slave_module), so each FMU runs its own script.
"""
from __future__ import annotations

import atexit
import ctypes
import hashlib
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, defaultCallbacks
from fmpy.fmi3 import fmi3LogMessageCallback

from .archive import extract_all
from .bundle import unopened_in_python
from .storage import FileMemo

STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
POOL_MAX = 4          # instances kept per (extraction, GUID, instance name)
LOG_KEEP = 20         # messages kept per instance


@dataclass
class InstanceLog:
    """The FMU's messages for one instance, and the callbacks that deliver them here."""
    key: int
    callbacks: fmi2CallbackFunctions
    messages: list[str] = field(default_factory=list)

    def last(self, n: int = 3) -> str:
        return "; ".join(self.messages[-n:])


@dataclass
class Kept:
    """An instance kept for reuse: the fmpy object, its C component and its log."""
    fmu: object
    component: object
    log: InstanceLog


class Runtime:
    """Extraction cache, instance pool and instance logs of this process."""

    def __init__(self) -> None:
        self._extracted: dict[str, str] = {}
        self._digest = FileMemo(self._hash)
        self._pool: dict[tuple, list[Kept]] = {}
        self._logs: dict[int, InstanceLog] = {}
        self._next_key = 1
        self._logger = fmi2CallbackLoggerTYPE(self._on_log)
        # FMI 3.0 (master/fmi3.py): the same log, reached through the instance environment
        self.logger3 = fmi3LogMessageCallback(
            lambda env, status, category, message: self._on_log(env, None, status, category,
                                                                message))

    # -- extraction ---------------------------------------------------------------------------
    def extracted(self, path: Path | str) -> str:
        """The folder where this FMU's content is unpacked (once per content and process).
        Raises archive.ArchiveError (unsafe or damaged archive; nothing is left behind) or
        OSError (the FMU cannot be read)."""
        digest = self._digest(Path(path))
        if digest not in self._extracted:
            self._extracted[digest] = extract_all(path, f"mecanum_{Path(path).stem[:40]}_",
                                                  leave=unopened_in_python)
        return self._extracted[digest]

    @staticmethod
    def _hash(path: Path) -> str:
        """The sha256 of the FMU file (kept per file by self._digest, a storage.FileMemo:
        hashing a self-contained FMU took 5 ms, four of them 20 ms, on every run)."""
        sha = hashlib.sha256()
        with open(path, "rb") as f:          # streamed: an FMU may be large
            while chunk := f.read(1 << 20):
                sha.update(chunk)
        return sha.hexdigest()

    def forget_extractions(self) -> None:
        """Delete the extraction folders and forget them: the next run extracts anew (its
        libraries load as new ones; those loaded stay mapped). Kept instances are freed first:
        they read their resources from these folders."""
        self.release_instances()
        self.remove_extractions()
        self._extracted.clear()
        self._digest.clear()

    def remove_extractions(self) -> None:
        """Delete the extraction folders. Only for a process about to leave (libraries stay
        mapped, kept instances are abandoned)."""
        for folder in self._extracted.values():
            shutil.rmtree(folder, ignore_errors=True)

    # -- logs ---------------------------------------------------------------------------------
    def new_log(self) -> InstanceLog:
        """A log of its own for a new instance, with callbacks that point to it."""
        key, self._next_key = self._next_key, self._next_key + 1
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = self._logger
        callbacks.allocateMemory = defaultCallbacks.allocateMemory
        callbacks.freeMemory = defaultCallbacks.freeMemory
        callbacks.componentEnvironment = ctypes.c_void_p(key)
        log = InstanceLog(key, callbacks)
        self._logs[key] = log
        return log

    def _on_log(self, env, instance_name, status, category, message) -> None:
        log = self._logs.get(env or 0)
        if log is None:
            return
        text = " ".join((message.decode("utf-8", "replace") if message else "").split())
        log.messages.append(f"[{STATUS.get(status, status)}] {text}")
        del log.messages[:-LOG_KEEP]

    # -- kept instances -----------------------------------------------------------------------
    def take(self, key: tuple) -> Kept | None:
        pool = self._pool.get(key)
        return pool.pop() if pool else None

    def keep(self, key: tuple, kept: Kept) -> bool:
        """Keep an instance that ended cleanly; False when the pool for key is full."""
        pool = self._pool.setdefault(key, [])
        if len(pool) >= POOL_MAX:
            return False
        kept.log.messages.clear()
        pool.append(kept)
        return True

    def kept_components(self, instance_name: str) -> list:
        """The C components kept for instances called instance_name (for tests)."""
        return [k.component for key, pool in self._pool.items() if key[-1] == instance_name
                for k in pool]

    def release_instances(self) -> int:
        """Free every kept instance; the next run instantiates afresh. Returns how many."""
        freed = 0
        for pool in self._pool.values():
            while pool:
                kept = pool.pop()
                functions = kept.fmu._functions
                functions.get("fmi2FreeInstance", functions.get("fmi3FreeInstance"))(kept.component)
                self.forget_log(kept.log)
                freed += 1
        return freed

    def forget_log(self, log: InstanceLog) -> None:
        self._logs.pop(log.key, None)


def own_slave_module(unzipped: str) -> None:
    """Before a pythonfmu FMU (resources/slavemodule.txt) is instantiated: forget a module of
    its slave's name that another FMU's script put in sys.modules. pythonfmu imports the
    script by that name, and the import would hand back the other FMU's module, so this FMU
    would run the other's script (two FMUs built from a `model.py`, two versions of one
    model). The import then finds this FMU's resources/, which pythonfmu puts first on
    sys.path; instances of the other FMU keep the class they were made from."""
    resources = Path(unzipped) / "resources"
    try:
        name = (resources / "slavemodule.txt").read_text().strip()
    except (OSError, UnicodeDecodeError):     # not a pythonfmu FMU
        return
    module = sys.modules.get(name)
    where = getattr(module, "__file__", None)
    if module is not None and (where is None
                               or Path(where).resolve().parent != resources.resolve()):
        del sys.modules[name]


RUNTIME = Runtime()


def release_instances(remove_extractions: bool = False) -> int:
    """Free every kept instance (the next run instantiates afresh); with remove_extractions,
    also delete the extraction folders (a notebook done with simulating: TMPDIR is left as
    it was; a later run extracts again). Returns how many instances were freed."""
    freed = RUNTIME.release_instances()
    if remove_extractions:
        RUNTIME.forget_extractions()
    return freed


@atexit.register
def _leave() -> None:
    """A script that used the API and ends normally: the kept instances are freed while the
    interpreter is still whole, and TMPDIR is left as the script found it. (The CLI leaves
    through process.exit_now, which does the same without interpreter shutdown.)"""
    RUNTIME.release_instances()
    RUNTIME.remove_extractions()
