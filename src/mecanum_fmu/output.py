"""The results folder of one run or sweep: checked and locked before simulating, written so
that no file ever looks complete when it is not.

- The folder is made (or found) and probed before the run: a file in its place, a folder that
  cannot be written, a name that is too long are bad input (ScenarioError, exit code 2).
  The same rules for every command that writes (make_folder: `fmus --dest`; output_file: a
  single file such as `export-ssp -o`).
- One run at a time per folder: an exclusive lock (fcntl.flock) on LOCK_NAME inside it, removed
  when the run ends; a second run is refused.
- results.csv and summary.json are written under a temporary name in the folder and renamed
  when complete (storage.atomic_path); the files of an earlier run, as its summary.json names
  them (`files`), are removed first, and nothing else: a run that ends half-way never leaves
  an old file that looks like its own, and a user's own files in the folder stay.
"""
from __future__ import annotations

import fcntl
import json
import os
import tempfile
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import MecanumError, Problem, ScenarioError
from .results import Results, csv_writer, write_rows
from .storage import atomic_path, read_regular

# as long as the longest temporary name a run writes here (".summary.json.part"; the plots'
# are close): when the lock can be created, the other file names fit too
LOCK_NAME = ".mecanum_fmu_run.lock"
SUMMARY = "summary.json"
TABLES = ("results.csv", SUMMARY)
SUMMARY_LIMIT = 1 << 20       # a summary.json larger than this is not one of ours


def previous_files(folder: Path) -> set[str]:
    """The file names the summary.json in folder says its run wrote there: plain names of
    regular files in the folder only (a name with a separator, '..', or of a folder or link
    is left alone); empty when there is no readable summary of ours."""
    try:
        data = json.loads(read_regular(folder / SUMMARY, SUMMARY_LIMIT, "a summary.json"))
    except (OSError, ValueError):         # none, unreadable, not JSON (NotARegularFile too)
        return set()
    names = data.get("files") if isinstance(data, dict) else None
    if not isinstance(names, list):
        return set()
    return {n for n in names if isinstance(n, str) and n not in ("", ".", "..")
            and "/" not in n and "\0" not in n and n != LOCK_NAME
            and (folder / n).is_file() and not (folder / n).is_symlink()}


class WriteError(MecanumError):
    """A result file could not be written (a full disk, the folder removed): exit code 1."""

    def __init__(self, folder: Path, err: OSError):
        super().__init__(f"writing the results into {folder} failed: {err.strerror or err}")


def _bad(folder: Path, message: str, option: str = "--out") -> ScenarioError:
    return ScenarioError([Problem(str(folder), f"output folder ({option})", message)])


def _another(option: str) -> str:
    """The fix: 'choose another --out' ('export-ssp -o' -> '-o')."""
    return f"choose another {option.split()[-1]}"


def make_folder(path: Path, option: str = "--out") -> Path:
    """Create the folder a command writes into (when missing) and probe that it takes a file;
    bad input (ScenarioError naming `option`) when it cannot."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise _bad(path, "is a file, not a folder; give a folder (it is created when "
                         "missing)", option) from None
    except OSError as err:
        raise _bad(path, f"cannot create it: {err.strerror}; {_another(option)}",
                   option) from None
    try:
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as err:
        raise _bad(path, f"cannot write into it: {err.strerror}; {_another(option)}",
                   option) from None
    return path


def check_output_file(path: Path, option: str, example: str) -> None:
    """A file a command writes where the user says (export-ssp -o), before the work: a folder
    in its place or a folder that cannot hold it (read-only, missing rights) is bad input
    naming `option` (ScenarioError, exit code 2); `example` names a file for the fix."""
    if path.is_dir():
        raise ScenarioError([Problem(str(path), option, f"is a folder; give the file to "
                                     f"write, e.g. {path / example}")])
    make_folder(path.parent, option)


def output_file(path: Path | str, write: Callable[[Path], Path], option: str,
                example: str) -> Path:
    """write(path) (an atomic writer: nothing half-written is left), checked as
    check_output_file does; a write that fails is bad input naming `option` too."""
    path = Path(path)
    check_output_file(path, option, example)
    try:
        return write(path)
    except OSError as err:
        raise ScenarioError([Problem(str(path), option, f"cannot write it: "
                                     f"{err.strerror or err}; {_another(option)}")]) from None


class OutputFolder:
    """`with OutputFolder(path) as out:` checks, creates and locks the folder, and removes the
    files the previous run or sweep wrote there (as its summary.json names them under
    "files"; `tables` when it names none), nothing else. The summary written here names the
    files written through the folder (write_json, csv_stream, atomic) and record()ed."""

    def __init__(self, path: Path | str, tables: tuple[str, ...] = TABLES):
        self.path = Path(path)
        self.tables = tables
        self._fd: int | None = None
        self._temps: set[Path] = set()
        self.written: set[str] = set()        # file names, summary.json's "files"
        self._listed: set[str] | None = None  # what the summary on disk names

    def __enter__(self) -> "OutputFolder":
        make_folder(self.path)
        self._lock()
        try:
            for name in previous_files(self.path) | set(self.tables):
                (self.path / name).unlink(missing_ok=True)
        except OSError as err:
            self._unlock()
            raise _bad(self.path / name, f"cannot replace it ({err.strerror}); remove it "
                                         f"or choose another --out") from None
        return self

    def __exit__(self, *exc) -> None:
        for temp in self._temps:
            try:
                temp.unlink(missing_ok=True)
            except OSError:
                pass
        try:
            if self._listed is not None and self._listed != self.written | {SUMMARY}:
                self._relist()
        finally:
            self._unlock()

    def record(self, paths) -> None:
        """Files of this folder written by others (the plots): named in summary.json."""
        self.written.update(Path(p).name for p in paths if Path(p).parent == self.path)

    def _relist(self) -> None:
        """The summary on disk again, naming every file written (record() after it)."""
        try:
            data = json.loads((self.path / SUMMARY).read_text())
            self.write_json(data)
        except (OSError, ValueError, MecanumError):   # gone or unwritable: nothing to name
            pass

    def _lock(self) -> None:
        lock = self.path / LOCK_NAME
        while True:
            try:
                fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except OSError as err:
                raise _bad(self.path, f"cannot write into it: {err.strerror}; choose "
                                      f"another --out") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                raise _bad(self.path, f"another run is writing into {self.path}; wait for "
                                      f"it to end or choose another --out") from None
            try:        # the run that held it may have removed it meanwhile: lock anew
                if os.stat(lock).st_ino == os.fstat(fd).st_ino:
                    self._fd = fd
                    return
            except FileNotFoundError:
                pass
            os.close(fd)

    def _unlock(self) -> None:
        if self._fd is not None:       # removed while still held: see _lock
            try:
                (self.path / LOCK_NAME).unlink(missing_ok=True)
            except OSError:
                pass
            os.close(self._fd)
            self._fd = None

    def atomic(self, name: str) -> atomic_path:
        """storage.atomic_path for a file of this folder; its temporary name is removed when
        the folder is left, whatever happened. The name goes into the summary's "files"."""
        atomic = atomic_path(self.path / name)
        self._temps.add(atomic.temp)
        self.written.add(name)
        return atomic

    def write_json(self, data: dict, name: str = SUMMARY) -> Path:
        """Written whole under a temporary name, then renamed. The summary gets "files": the
        names of the files written into the folder so far, itself included."""
        if name == SUMMARY:
            self.written.add(name)
            data = {**data, "files": sorted(n for n in self.written
                                            if n == name or (self.path / n).is_file())}
        try:
            with self.atomic(name) as temp:
                temp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")
        except OSError as err:
            raise WriteError(self.path, err) from None
        if name == SUMMARY:
            self._listed = set(data["files"])
        else:
            self.written.add(name)
        return self.path / name

    def write_tables(self, stream: "CsvStream", summary: dict) -> list[Path]:
        """results.csv (renamed) and summary.json together, or neither: a results.csv
        without the summary that says how far it got would look complete."""
        try:
            return [stream.finish(), self.write_json(summary)]
        except WriteError:
            for name in TABLES:
                try:
                    (self.path / name).unlink(missing_ok=True)
                except OSError:
                    pass
            raise

    def csv_stream(self, names: tuple[str, ...]) -> "CsvStream":
        return CsvStream(self.atomic("results.csv"), names)


class CsvStream:
    """results.csv written chunk by chunk during the run (a sink for master.simulate) under a
    temporary name; finish() renames it, abort() removes it."""

    def __init__(self, atomic: atomic_path, names: tuple[str, ...]):
        self._atomic = atomic
        self.temp, self.final = atomic.temp, atomic.path
        try:
            self._fh = open(self.temp, "w", newline="")
            self._writer = csv_writer(self._fh, names)
        except OSError as err:
            raise WriteError(self.final.parent, err) from None

    def __call__(self, chunk: np.ndarray) -> None:
        try:
            write_rows(self._writer, chunk)
        except OSError as err:
            raise WriteError(self.final.parent, err) from None

    def finish(self) -> Path:
        try:
            self._fh.close()
            return self._atomic.commit()
        except OSError as err:
            raise WriteError(self.final.parent, err) from None

    def abort(self) -> None:
        try:
            self._fh.close()
        except OSError:     # the disk is full: what is buffered cannot be written
            pass
        self._atomic.discard()


def summarize(graph, results: Results) -> dict:
    """What the run was and how it went, summary.json's first part (a scenario.graph.Graph and
    its Results; the evaluation adds its part: report.evaluation.Evaluation.summary)."""
    scenario = graph.scenario
    return {
        "scenario": scenario.name,
        "file": str(scenario.path),
        "description": scenario.description,
        "master": results.master,
        "start_time": results.start_time,
        "stop_time": results.stop_time,
        "step_size": results.step_size,
        "steps": results.steps,
        "wall_time_s": round(results.wall_time, 6),
        "complete": results.complete,
        "end_time": float(results.time[-1]) if len(results.time) else None,
        **({"ended_by": results.ended_by} if results.ended_by else {}),
        "recorded": list(results.names),
        "fmus": {i.name: {"model": i.model_name, "path": str(i.fmu_path), "guid": i.model.guid}
                 for i in graph.instances},
    }
