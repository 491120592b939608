"""Draw the plots in a second process that imports matplotlib while this one simulates.

Importing matplotlib costs about as much as a short run. `PlotWorker.start()` (the CLI calls it
before loading the scenario) launches `python -m mecanum_fmu.report.plot_worker`, which imports the
plotting code at once; `expect(graph)` sends it the run's column names and settings, and it
builds the dashboard's frame (axes, titles, ticks) while the parent simulates, then waits on its
stdin.
`draft()` sends it the results as soon as they exist (pickled: parent to its own child, never
user text): it draws every panel but the ground truth's while the parent integrates the truth
and estimates the error. `finish()` sends the Evaluation's truth; the worker draws the truth's
panels into their empty cells, writes the PNGs and `finish` returns their paths. `cancel()` lets
it go. On a machine with a free core the import is hidden.
A worker that cannot start (no interpreter executable, e.g. embedded Python) falls back to
drawing in this process.
"""
from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import threading
import weakref
from pathlib import Path

import numpy as np

from ..results import Results

PACKAGE_PARENT = Path(__file__).resolve().parents[1]     # so the child finds this package


class PlotFailed(RuntimeError):
    """The worker could not write the plots; the message is the child's own error."""


class PlotWorker:
    def __init__(self, proc: subprocess.Popen | None):
        self._proc = proc
        self._sent = 0          # messages sent: the frame's hint, the draft, the truth
        self._writer: threading.Thread | None = None
        self._write_failed = False
        if proc is not None:     # a run that raised before finish(): the worker goes with it
            weakref.finalize(self, _stop, proc)

    @classmethod
    def start(cls) -> "PlotWorker":
        """Launch the worker; it imports matplotlib at once. Call `expect` when the graph is
        known, `draft` when the results are, `finish` when the Evaluation is."""
        if not sys.executable:
            return cls(None)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(PACKAGE_PARENT),
                                                          env.get("PYTHONPATH")]))
        env.setdefault("MPLBACKEND", "Agg")
        try:
            return cls(subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=env))
        except OSError:
            return cls(None)

    def expect(self, graph, roles) -> None:
        """Tell the worker what the run records (and the roles: topology(graph).roles), so it
        prepares the dashboard's frame."""
        if self._sent == 0:
            self._send(_frame_hint(graph, roles))

    def draft(self, results, roles, title: str = "") -> None:
        """Hand the worker the results (and the roles the Evaluation will carry) as soon as
        they exist: it draws every panel but the ground truth's while this process
        evaluates the run."""
        if self._sent == 0:
            self._send(None)        # no frame was asked for: the draft makes its own
        if self._sent == 1:
            self._send((results, roles, title))

    def _send(self, obj) -> None:
        """Write one message from a thread: a large one must not hold this process up while
        the worker is still busy (importing, building the frame)."""
        self._sent += 1
        if self._proc is None:
            return
        self._join()
        data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
        self._writer = threading.Thread(target=self._write, args=(self._proc.stdin, data),
                                        daemon=True)
        self._writer.start()

    def _write(self, stream, data: bytes) -> None:
        try:
            stream.write(data)
            stream.flush()
        except (OSError, ValueError):     # it died (or was cancelled): draw here instead
            self._write_failed = True

    def _join(self) -> None:
        if self._writer is not None:
            self._writer.join()
            self._writer = None

    def finish(self, results, evaluation, out_dir: Path, title: str = "") -> list[Path]:
        """Have the worker write the plots of the run and its Evaluation (or draw them here
        without a worker); the PNG paths."""
        self.draft(results, evaluation.roles, title)
        self._join()
        if self._write_failed:
            self.cancel()
        if self._proc is None:
            return _draw(results, evaluation.roles, evaluation.truth, str(out_dir), title)
        proc, self._proc = self._proc, None
        job = (evaluation.truth, str(out_dir))
        try:
            out, _ = proc.communicate(pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL))
        except BrokenPipeError:      # the worker died before reading: its exit says why
            out = proc.stdout.read() if proc.stdout else b""
            proc.wait()
        return _answer(out, proc.returncode)

    def cancel(self) -> None:
        """No plots after all (the run failed): stop the worker."""
        proc, self._proc = self._proc, None
        if proc is not None:
            proc.kill()         # first: a message being written fails at once
            self._join()
            _stop(proc)


def _answer(out: bytes, code: int) -> list[Path]:
    """The PNG paths the worker reported, or PlotFailed with its reason."""
    try:
        answer = json.loads(out.decode() or "{}")
    except ValueError:
        answer = {}
    if code != 0 or "paths" not in answer:
        raise PlotFailed(answer.get("error") or f"the plotting process exited with code {code}")
    return [Path(p) for p in answer["paths"]]


def _stop(proc: subprocess.Popen) -> None:
    if proc.returncode is None:
        proc.kill()
        proc.communicate()


def _frame_hint(graph, roles) -> tuple | None:
    """What the dashboard's frame needs before the run ends: a one-row stand-in for the
    results (the recorded column names and the run's settings), the roles and the title."""
    if graph is None:
        return None
    names = tuple(str(port.ref) for port in graph.recorded)
    exp = graph.scenario.experiment
    stand_in = Results(names, np.zeros(1, dtype=[("time", "f8")] + [(n, "f8") for n in names]),
                       exp.master, exp.start_time, exp.stop_time, exp.step_size, 0, 0.0)
    return stand_in, roles, graph.scenario.name


def _draw(results, roles, truth, out_dir: str, title: str) -> list[Path]:
    from .plots import write_plots     # startup: matplotlib, in the worker only
    return write_plots(results, roles, truth, Path(out_dir), title=title)


def _prepare(hint: tuple | None):
    """Build the dashboard's frame (axes, titles, the ticks of the truth's panels) while the
    run goes on. It is not drawn: a first draw warms no cache that the draft would not fill
    as fast (measured: the draft took as long after it as without it)."""
    from .plots import dashboard_frame
    return None if hint is None else dashboard_frame(*hint)


def _serve(stdin) -> dict | None:
    """Read the three messages and draw (the draft at once, the rest when the truth comes);
    the answer for the parent, or None when it cancelled (closed our stdin) first."""
    from .plots import draft_dashboard, finish_dashboard, save_pngs
    try:
        hint = pickle.load(stdin)
        try:
            frame = _prepare(hint)
        except Exception:       # the draft makes its own frame and says what fails
            frame = None
        results, roles, title = pickle.load(stdin)
        try:
            draft, failure = draft_dashboard(results, roles, title, frame), None
        except Exception as err:
            draft, failure = None, err
        truth, out_dir = pickle.load(stdin)
    except EOFError:
        return None
    try:
        if failure is not None:
            raise failure
        paths = save_pngs(finish_dashboard(draft, truth), out_dir)
    except Exception as err:    # reported by the parent with the files it kept
        return {"error": f"{type(err).__name__}: {err}"}
    return {"paths": [str(p) for p in paths]}


def main() -> int:
    # Ctrl-C reaches the whole process group: the parent reports it, we just stop.
    signal.signal(signal.SIGINT, lambda *_: os._exit(130))
    try:
        from . import plots  # noqa: F401  (matplotlib: the slow part, while the parent works)
    except Exception as err:    # nothing can be drawn: say why when asked
        answer = {"error": f"{type(err).__name__}: {err}"}
        sys.stdin.buffer.read()     # the parent's messages, to the end (or cancelled)
    else:
        answer = _serve(sys.stdin.buffer)
    if answer is None:
        return 0
    sys.stdout.write(json.dumps(answer))
    sys.stdout.flush()
    return 0 if "paths" in answer else 1


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)     # no interpreter shutdown: freeing matplotlib's objects only costs time
