"""The adaptive master's rows (dense output): its steps run past the output times, and each
row at an output time comes from the values at the communication points around it.

- A Real value: the polynomial through the communication points of the current segment (the
  points since the last stop: a breakpoint, a jump, the start) that bracket the row, at most
  POINTS of them (the cubic through the last four), at the row's time. Its error is estimated
  by the next divided difference: the quartic through one point more (the cubic's error), or,
  with fewer points in the segment, the interpolant through one point fewer (a bound). That
  estimate, per output the tolerance controls (those with an estimate: the error models' and
  the embedded pair's, adaptive.py), weighed as the step's (e_i / (atol + rtol |y_i|)), must
  stay under SHARE of the tolerance (the rest is the steps' accumulated error's: the
  controller's line ends at 0.85) at the quarters of every step, a row in it or not, or the
  step is cut (DenseRows.ratio): the steps do not depend on the output interval.
- An Integer or Boolean value is held: the value at the last communication point before the
  row (or at the row's time, when a point falls on it).
- A row on a communication point (a stop, the stop time) is that point's values, exact.
- The accumulated error estimate of a row: the estimates at the two points around it, linear
  in time between them, plus the row's own interpolation error (its estimate, as above).
A row waits until its segment has POINTS points or ends (a stop), so that it has its cubic.
"""
from __future__ import annotations

import math

import numpy as np

from .pair_rough import ADAPTIVE_ROUGH, rough_columns
from .recorder import Recorder, grid_times

POINTS = 4
SHARE = 0.15
QUARTERS = np.array([0.25, 0.5, 0.75])   # where on a step its interpolation is checked


def _weights(times: np.ndarray, at: float) -> np.ndarray:
    """The Lagrange weights of the polynomial through `times`, at `at`."""
    diff = at - times
    weights = np.ones(len(times))
    for i in range(len(times)):
        for k in range(len(times)):
            if k != i:
                weights[i] *= diff[k] / (times[i] - times[k])
    return weights


def _combine(weights: np.ndarray, values: np.ndarray) -> np.ndarray:
    """weights . values (rows), summed row after row: the same bits on every CPU (a matrix
    product goes to the BLAS, whose kernel, chosen by the CPU, orders and fuses the sums)."""
    terms = weights[:, None] * values
    total = terms[0].copy()
    for row in terms[1:]:
        total += row
    return total


def interpolate(times: np.ndarray, values: np.ndarray, at: float) -> tuple:
    """(the value at `at`, its signed error estimate (value - better)) from the points
    `times`, `values` (rows): with POINTS + 1 points the cubic through the last POINTS and its
    difference from the quartic through all; with fewer, the polynomial through all and its
    difference from the one without the point farthest from `at` (a bound)."""
    if len(times) > POINTS:
        value = _combine(_weights(times[1:], at), values[1:])
        return value, value - _combine(_weights(times, at), values)
    value = _combine(_weights(times, at), values)
    if len(times) < 3:              # two points give no estimate of the line's error
        return value, np.zeros_like(value)
    keep = np.arange(len(times)) != np.argmax(np.abs(times - at))
    return value, value - _combine(_weights(times[keep], at), values[keep])


class DenseRows:
    """The communication points of the current segment (times, Real and Integer buffers,
    estimates) and the rows still to record (`j`: the next row's index). `controlled`: the
    outputs with an estimate, in the estimate's order (adaptive._Loop.names), the first
    `signed` of them signed (the error models'), the others sizes (the pair's)."""

    def __init__(self, recorder: Recorder, tol: tuple[float, float], near: float,
                 controlled: list[str], signed: int, tally: bool = False):
        self.recorder, self.tol, self.near, self.signed = recorder, tol, near, signed
        exp = recorder.experiment
        self.row_times = grid_times(exp, np.arange(recorder.n_steps + 1), recorder.n_steps)
        self.j = 1                      # row 0 (t0) is recorded before the loop
        slot = {str(p.ref): recorder.buffers.slot(p) for p in recorder.graph.recorded
                if p.type == "Real"}
        self.of = [(i, slot[n]) for i, n in enumerate(controlled) if n in slot]
        self.slots = np.array([s for _, s in self.of], dtype=np.intp)
        self.times: list[float] = []
        self.points: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        # `tally` (FMUs the scenario layer knows nothing of): per controlled output, sum
        # h^4 |u4|, sum |change|, largest |u| over the points (_tally)
        self.rough = np.zeros((3, len(self.slots))) if tally else None
        self.tallied = 0

    def row_inside(self, start: float, end: float) -> bool:
        """Whether an output row falls strictly between start and end (a segment's rows are
        interpolated from its points; one on either end is that point's values)."""
        i = int(np.searchsorted(self.row_times, start + self.near, side="right"))
        return i < len(self.row_times) and self.row_times[i] < end - self.near

    def row_after(self, t: float) -> float:
        """The first output row after t (past `near`), or infinity."""
        i = int(np.searchsorted(self.row_times, t + self.near, side="right"))
        return float(self.row_times[i]) if i < len(self.row_times) else math.inf

    def restart(self, t: float, estimate: list[float]) -> None:
        """A new segment from t (a stop, the start): the values now are its first point."""
        self.times, self.points = [], []
        self.add(t, estimate)

    def add(self, t: float, estimate: list[float]) -> None:
        """The values now (an accepted step's end at t) as the segment's last point."""
        buffers = self.recorder.buffers
        self.times.append(t)
        self.points.append((buffers.real.copy(), buffers.int.copy(),
                            np.array(estimate, dtype=float)))
        del self.times[:-POINTS - 1], self.points[:-POINTS - 1]
        if self.rough is not None and len(self.times) == POINTS + 1:
            self._tally()

    def _tally(self) -> None:
        """Add the newest step's fourth difference (h^4 u4 from the fourth divided difference
        over the segment's five points) and change, per controlled output: pair_rough's rule
        on the rows' own points. A jump that the steps crossed unrejected (a staircase on an
        FMU's grid, which the rows would blend) sums to several times its change; a smooth
        curve to (h omega)^3."""
        times = np.array(self.times)
        values = np.array([p[0][self.slots] for p in self.points])
        diff = values
        for order in range(1, POINTS + 1):
            diff = (diff[1:] - diff[:-1]) / (times[order:] - times[:-order])[:, None]
        h = (times[-1] - times[0]) / POINTS     # the points' mean step
        self.rough[0] += 24.0 * h ** 4 * np.abs(diff[0])
        self.rough[1] += np.abs(values[-1] - values[-2])
        np.maximum(self.rough[2], np.abs(values[-1]), out=self.rough[2])
        self.tallied += 1

    def not_smooth(self, names: list[str]) -> list[str]:
        """The controlled outputs (`names`: their names, the estimate's order) whose points
        did not move as smooth curves over the run (_tally)."""
        if self.rough is None:
            return []
        cols = rough_columns(self.rough[:2], self.rough[2], max(self.tallied, 1),
                             ADAPTIVE_ROUGH)
        return [names[self.of[c][0]] for c in cols]

    def ratio(self, end: float) -> float:
        """The largest estimated interpolation error on a step to `end` (the values now are
        its end), at the quarters of the step whether or not a row falls in it (so that the
        steps do not depend on the output interval), over SHARE of the tolerance."""
        if len(self.times) < 2 or not len(self.slots):
            return 0.0
        times = np.array([*self.times[-POINTS:], end])
        values = np.array([*(p[0][self.slots] for p in self.points[-POINTS:]),
                           self.recorder.buffers.real[self.slots]])
        atol, rtol = self.tol
        worst = 0.0
        for at in times[-2] + QUARTERS * (end - times[-2]):
            value, error = interpolate(times, values, at)
            worst = max(worst, float(np.max(np.abs(error) / (atol + rtol * np.abs(value)))))
        return worst / SHARE

    def emit(self, final: bool) -> list:
        """Record the rows up to the last point that are ready (the segment has POINTS points,
        or it ends here: `final`); their estimates, in order."""
        if len(self.times) < POINTS and not final:
            return []
        estimates = []
        last = self.times[-1]
        while self.j < len(self.row_times) and self.row_times[self.j] <= last + self.near:
            estimates.append(self._row(self.row_times[self.j]))
            self.j += 1
        return estimates

    def _row(self, at: float) -> np.ndarray:
        """Record the row at `at`; its accumulated error estimate."""
        times = np.array(self.times)
        on = np.flatnonzero(np.abs(times - at) <= self.near)
        if len(on):
            real, ints, estimate = self.points[on[-1]]
            self.recorder.record(real, ints)
            return estimate
        after = int(np.searchsorted(times, at))
        real, error = interpolate(times, np.array([p[0] for p in self.points]), at)
        (_, ints, before), (_, _, later) = self.points[after - 1], self.points[after]
        self.recorder.record(real, ints)
        share = (at - times[after - 1]) / (times[after] - times[after - 1])
        estimate = before + share * (later - before)
        for i, slot in self.of:
            estimate[i] += error[slot] if i < self.signed else abs(error[slot])
        return estimate
