"""The recording of a run: one row of the value buffers per communication point."""
from __future__ import annotations

import numpy as np

from ..graph import Graph
from ..results import Results
from ..scenario import Experiment
from .plan import Buffers


def step_count(experiment: Experiment) -> int:
    """Communication steps from start to stop; a last, shorter step reaches stop_time."""
    start, stop, h = experiment.start_time, experiment.stop_time, experiment.step_size
    n_steps = int(round((stop - start) / h))
    if start + n_steps * h < stop - 1e-9 * h:
        n_steps += 1
    return n_steps


class Recorder:
    """Copies the whole buffers each row (one contiguous copy each); the recorded columns are
    picked out when Results are made."""

    def __init__(self, graph: Graph, experiment: Experiment, buffers: Buffers, n_steps: int):
        self.graph, self.experiment, self.buffers = graph, experiment, buffers
        self.n_steps = n_steps
        self.real = np.empty((n_steps + 1, len(buffers.real)), dtype=np.float64)
        self.int = np.empty((n_steps + 1, len(buffers.int)), dtype=np.int32)
        self.rows = 0
        self.wall = 0.0

    def record(self) -> None:
        self.real[self.rows] = self.buffers.real
        self.int[self.rows] = self.buffers.int
        self.rows += 1

    def results(self, complete: bool) -> Results:
        """The structured array of the rows recorded so far (t0 row included)."""
        exp, rows = self.experiment, self.rows
        names = tuple(str(p.ref) for p in self.graph.recorded)
        dtype = [("time", "f8")] + [(name, {"Real": "f8", "Integer": "i4"}.get(p.type, "?"))
                                    for name, p in zip(names, self.graph.recorded)]
        data = np.empty(rows, dtype=dtype)
        # t_k = start + k*h, computed, not accumulated; the last point is stop_time itself.
        times = exp.start_time + np.arange(rows) * exp.step_size
        if rows == self.n_steps + 1:
            times[-1] = exp.stop_time
        data["time"] = times
        for name, port in zip(names, self.graph.recorded):
            source = self.real if port.type == "Real" else self.int
            data[name] = source[:rows, self.buffers.slot(port)]
        return Results(names, data, exp.master, exp.start_time, exp.stop_time,
                       exp.step_size, max(rows - 1, 0), self.wall, complete)
