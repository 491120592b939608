"""The recording of a run: one row of the value buffers per communication point.

Rows are copied into a small chunk (CHUNK_ROWS rows); a full chunk becomes a structured array
that goes to the sink (e.g. the results.csv being written) and to what is kept in memory:
every row by default, or with `keep_rows` about that many evenly spaced rows plus the exact
last row, so that memory stays bounded for any run length.
"""
from __future__ import annotations

import math
import time as _time
from typing import Callable

import numpy as np

from ..scenario.graph import Graph
from ..results import Results
from ..scenario.document import Experiment
from .plan import Buffers

CHUNK_ROWS = 4096


def step_count(experiment: Experiment) -> int:
    """Communication steps from start to stop; a last, shorter step reaches stop_time."""
    start, stop, h = experiment.start_time, experiment.stop_time, experiment.step_size
    n_steps = int(round((stop - start) / h))
    if start + n_steps * h < stop - 1e-9 * h:
        n_steps += 1
    return n_steps


def grid_times(experiment: Experiment, index: np.ndarray, n_steps: int) -> np.ndarray:
    """The communication times of the rows `index`: t_k = start + k*h, computed, not
    accumulated; the last point (k = n_steps) is stop_time itself."""
    times = experiment.start_time + index * experiment.step_size
    if len(index) and index[-1] == n_steps:
        times[-1] = experiment.stop_time
    return times


def time_grid(experiment: Experiment) -> np.ndarray:
    """Every communication time of a complete run, as the recorder lays them out."""
    n_steps = step_count(experiment)
    return grid_times(experiment, np.arange(n_steps + 1), n_steps)


class Recorder:
    """Copies the whole buffers each row (one contiguous copy each) into the current chunk;
    the recorded columns are picked out when a chunk is full (flush)."""

    def __init__(self, graph: Graph, experiment: Experiment, buffers: Buffers, n_steps: int,
                 sink: Callable[[np.ndarray], None] | None = None,
                 keep_rows: int | None = None):
        self.graph, self.experiment, self.buffers = graph, experiment, buffers
        self.n_steps = n_steps
        chunk = min(CHUNK_ROWS, n_steps + 1)
        self.real = np.empty((chunk, len(buffers.real)), dtype=np.float64)
        self.int = np.empty((chunk, len(buffers.int)), dtype=np.int32)
        self.fill = 0           # rows in the current chunk
        self.flushed = 0        # rows handed on by flush()
        self.names = tuple(str(p.ref) for p in graph.recorded)
        self.dtype = [("time", "f8")] + [(name, {"Real": "f8", "Integer": "i4"}.get(p.type, "?"))
                                         for name, p in zip(self.names, graph.recorded)]
        self.sink = sink
        self.stride = 1 if keep_rows is None else max(1, math.ceil((n_steps + 1) / keep_rows))
        self.kept: list[np.ndarray] = []
        self.last: np.ndarray | None = None
        self.sink_seconds = 0.0  # time spent in flush (formatting, writing): not the loop's
        # fed every chunk of whole buffer rows (and the index of its first row) as it is
        # flushed: the embedded pair's error estimate (pair_rows.py)
        self.tap: Callable[[np.ndarray, int], None] | None = None
        # called before the steps in its `at` (their index, t, h): the pair's measured
        # responses (probe.Prober)
        self.probe = None
        self.wall = 0.0

    @property
    def rows(self) -> int:
        return self.flushed + self.fill

    @property
    def last_time(self) -> float:
        """The time of the last row recorded."""
        return float(grid_times(self.experiment, np.array([self.rows - 1]), self.n_steps)[0])

    def record(self, real: np.ndarray | None = None, ints: np.ndarray | None = None) -> None:
        """A row of the buffers now, or of the values `real`, `ints` (the adaptive master's
        rows between its communication points, dense.py)."""
        i = self.fill
        self.real[i] = self.buffers.real if real is None else real
        self.int[i] = self.buffers.int if ints is None else ints
        self.fill = i + 1
        if i + 1 == len(self.real):
            self.flush()

    def flush(self) -> None:
        """The rows of the current chunk as a structured array, to the sink and the memory."""
        if not self.fill:
            return
        tick = _time.perf_counter()
        exp, first, n = self.experiment, self.flushed, self.fill
        if self.tap is not None:
            self.tap(self.real[:n], first)
        index = np.arange(first, first + n)
        data = np.empty(n, dtype=self.dtype)
        data["time"] = grid_times(exp, index, self.n_steps)
        for name, port in zip(self.names, self.graph.recorded):
            source = self.real if port.type == "Real" else self.int
            data[name] = source[:n, self.buffers.slot(port)]
        self.flushed, self.fill = first + n, 0
        self.kept.append(data if self.stride == 1 else data[index % self.stride == 0])
        self.last = data[-1:].copy()
        if self.sink is not None:
            self.sink(data)
        self.sink_seconds += _time.perf_counter() - tick

    def results(self, complete: bool) -> Results:
        """The rows recorded so far (t0 row included): every row, or the decimated ones plus
        the exact last row. A run that did not complete gets no estimate: its tap is let go
        first (what was recorded is the user's, whatever the tap would make of it)."""
        if not complete:
            self.tap = None
        self.flush()
        parts = [k for k in self.kept if len(k)]
        if self.last is not None and (self.flushed - 1) % self.stride:
            parts.append(self.last)
        data = np.concatenate(parts) if parts else np.empty(0, dtype=self.dtype)
        exp = self.experiment
        return Results(self.names, data, exp.master, exp.start_time, exp.stop_time,
                       exp.step_size, max(self.rows - 1, 0), self.wall, complete)
