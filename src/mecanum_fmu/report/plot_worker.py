"""Draw the plots in a second process that imports matplotlib while this one simulates.

Importing matplotlib costs about as much as a short run. `PlotWorker.start()` (the CLI calls it
before loading the scenario) launches `python -m mecanum_fmu.report.plot_worker`, which imports the
plotting code at once; `expect(graph)` sends it the run's column names and settings, and it
builds and draws the dashboard's frame (axes, titles: fonts, ticks, caches) while the parent
simulates, then waits on its stdin.
`finish()` sends it the results (pickled: parent to its own child, never user text) and returns
the PNG paths it wrote. `cancel()` lets it go. On a machine with a free core the import is hidden.
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
        self._sent_hint = False
        if proc is not None:     # a run that raised before finish(): the worker goes with it
            weakref.finalize(self, _stop, proc)

    @classmethod
    def start(cls) -> "PlotWorker":
        """Launch the worker; it imports matplotlib at once. Call `expect` when the graph is
        known, `finish` when the results are."""
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
        self._send(_frame_hint(graph, roles))

    def _send(self, obj) -> None:
        if self._proc is None or self._sent_hint:
            return
        self._sent_hint = True
        try:
            self._proc.stdin.write(pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))
            self._proc.stdin.flush()
        except OSError:         # it died: draw here instead
            self.cancel()

    def finish(self, results, evaluation, out_dir: Path, title: str = "") -> list[Path]:
        """Have the worker write the plots of the run and its Evaluation (or draw them here
        without a worker); the PNG paths."""
        job = (results, evaluation.roles, evaluation.truth, str(out_dir), title)
        self._send(None)        # no frame was asked for: the worker only warms up
        if self._proc is None:
            return _draw(*job)
        proc, self._proc = self._proc, None
        try:
            out, _ = proc.communicate(pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL))
        except BrokenPipeError:      # the worker died before reading: its exit says why
            out = proc.stdout.read() if proc.stdout else b""
            proc.wait()
        try:
            answer = json.loads(out.decode() or "{}")
        except ValueError:
            answer = {}
        if proc.returncode != 0 or "paths" not in answer:
            raise PlotFailed(answer.get("error") or
                             f"the plotting process exited with code {proc.returncode}")
        return [Path(p) for p in answer["paths"]]

    def cancel(self) -> None:
        """No plots after all (the run failed): stop the worker."""
        proc, self._proc = self._proc, None
        if proc is not None:
            _stop(proc)


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


def _draw(results, roles, truth, out_dir: str, title: str, frame=None) -> list[Path]:
    from .plots import write_plots     # startup: matplotlib, in the worker only
    return write_plots(results, roles, truth, Path(out_dir), title=title, frame=frame)


def _prepare(hint: tuple | None):
    """Draw the dashboard's frame once (or, without a hint, a small figure): the first draw
    loads fonts and fills caches, and the frame's axes and ticks are then ready."""
    import matplotlib       # startup: the worker's own import, never the parent's
    from .plots import DRAW_RC, dashboard_frame, new_figure
    if hint is not None:
        frame = dashboard_frame(*hint)
        with matplotlib.rc_context(DRAW_RC):
            frame.figure.canvas.draw()
        return frame
    fig = new_figure((2.0, 1.5), layout=None)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], "--", label="warm-up")
    ax.set_title("warm-up")
    ax.legend()
    fig.canvas.draw()
    return None


def main() -> int:
    # Ctrl-C reaches the whole process group: the parent reports it, we just stop.
    signal.signal(signal.SIGINT, lambda *_: os._exit(130))
    try:
        from . import plots  # noqa: F401  (matplotlib: the slow part, while the parent works)
    except Exception:           # drawing will fail again below and say why
        pass
    try:
        hint = pickle.load(sys.stdin.buffer)
    except EOFError:            # cancelled before it began
        return 0
    try:
        frame = _prepare(hint)
    except Exception:
        frame = None
    data = sys.stdin.buffer.read()
    if not data:                # cancelled: the parent closed our stdin
        return 0
    try:
        paths = _draw(*pickle.loads(data), frame=frame)
    except Exception as err:    # reported by the parent with the files it kept
        answer, code = {"error": f"{type(err).__name__}: {err}"}, 1
    else:
        answer, code = {"paths": [str(p) for p in paths]}, 0
    sys.stdout.write(json.dumps(answer))
    sys.stdout.flush()
    return code


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)     # no interpreter shutdown: freeing matplotlib's objects only costs time
