"""The held inputs' true values read off the sources' known signals, where the run's values do
not tell them: a table's rows closer than two steps (breakpoints.Pieces.short), whose kinks fall
between the communication points faster than a polynomial through the run's rows can follow.

The graph carries its tables as signals known at every time (scenario/tables.Known). The pair
fits each column it rebuilds (a held input, a late output) as an affine map of those signals
on the run's own rows (least squares; under Jacobi node j is read d rows late), and keeps the
map only where it holds on every row to round-off: the FMUs between the tables and the input
are then a fixed linear map (a kinematics chain), whatever they are. The true input's mean
over a step and its values at the step's ends are the map's of the signals', integrated
exactly between the tables' rows (linear or held), wherever they fall. Where the map does not
hold (a saturation, a turning frame, a state between), `failed` says so and Richardson
estimates.
"""
from __future__ import annotations

import numpy as np

# a column's largest misfit, as a share of its largest |value|: the map holds to round-off
FIT = 1e-9
UNTOLD = ("a table's rows are closer than two steps, and the run's rows are too few for the "
          "tables' columns to tell how the held inputs follow them: the values the run sees "
          "do not tell its input between them")
NOT_A_MAP = ("a table's rows are closer than two steps, and the held inputs are not a fixed "
             "linear map of the tables (misfit {misfit:.1e} of their size): the values the run "
             "sees do not tell its input between them")


class KnownInputs:
    """The known signals on one run of n steps (the last one `last` steps long), and per lag
    the map fitted from them to the pair's columns of that lag."""

    def __init__(self, known, exp, n_steps: int, last: float):
        self.start, self.h, self.n, self.last = exp.start_time, exp.step_size, n_steps, last
        self.known = known
        inside = [k.times[(k.times > self.start) & (k.times < exp.stop_time)] for k in known]
        t = np.concatenate([[self.start, exp.stop_time], *inside])
        # (a signal constant over the run tells nothing, and would leave the map ambiguous)
        seen = np.concatenate((self.signals(t, True), self.signals(t, False)))
        self.varied = np.ptp(seen, axis=0) > 0
        self.cum = [_cumulative(k) for k in known]
        self.maps: dict[int, np.ndarray] = {}
        self.failed: str | None = None

    def time(self, nodes: np.ndarray) -> np.ndarray:
        """The times of nodes 0 .. n (node n: the stop time, after a shorter last step)."""
        nodes = np.asarray(nodes, dtype=float)
        return self.start + self.h * np.where(nodes >= self.n, self.n - 1 + self.last, nodes)

    def signals(self, t: np.ndarray, right: bool) -> np.ndarray:
        """Every known signal at times t, side by side."""
        out = [_at(k, t, right) for k in self.known]
        return np.concatenate(out, axis=1) if out else np.zeros((len(t), 0))

    def integrals(self, t: np.ndarray) -> np.ndarray:
        """Every known signal's integral from its first row to t (negative before it), exact
        between the tables' rows: a mean over [t0, t1] is the difference over t1 - t0."""
        out = []
        for k, cum in zip(self.known, self.cum):
            i = np.clip(np.searchsorted(k.times, t, side="right") - 1, 0, len(k.times) - 1)
            dt = (t - k.times[i])[:, None]
            if k.hold:
                out.append(cum[i] + dt * k.values[i])
            else:
                last = (i == len(k.times) - 1)[:, None] | (dt < 0)
                out.append(cum[i] + dt * np.where(last, k.values[i],
                                                  0.5 * (k.values[i] + _at(k, t, True))))
        return np.concatenate(out, axis=1) if out else np.zeros((len(t), 0))

    def _design(self, t: np.ndarray, right: bool = True) -> np.ndarray:
        """The varied signals at t and a column of ones (the map's constant)."""
        return self._affine(self.signals(t, right))

    def _affine(self, signals: np.ndarray) -> np.ndarray:
        """The varied columns of `signals` (one row per time) and a column of ones."""
        return np.column_stack((signals[:, self.varied], np.ones(len(signals))))

    def check(self, window: np.ndarray, lo: int, d: int, cols: np.ndarray,
              needed: np.ndarray) -> np.ndarray:
        """Fit the map of lag d's columns on the window's rows (its first time), or check it
        there; which columns it holds for to round-off. `failed` says why where it does not
        hold for a `needed` one (a held input: the others, late outputs, are read at the
        run's nodes, where the rows tell them)."""
        rows = np.arange(lo, lo + len(window))
        rows = rows[(rows >= d) & (rows - d <= self.n)]
        x, y = self._design(self.time(rows - d)), window[rows - lo][:, cols]
        if d not in self.maps:
            if len(rows) < x.shape[1] or np.linalg.matrix_rank(x) < x.shape[1]:
                self.maps[d] = (np.zeros((x.shape[1], len(cols))),
                                np.zeros(len(cols), dtype=bool))
                self.failed = self.failed or UNTOLD
                return self.maps[d][1]
            self.maps[d] = (np.linalg.lstsq(x, y, rcond=None)[0],
                            np.ones(len(cols), dtype=bool))
        a, fits = self.maps[d]
        if not fits.any() or not len(rows):
            return fits
        misfit = np.max(np.abs(x @ a - y), axis=0, initial=0.0)
        size = np.max(np.abs(y), axis=0, initial=0.0)
        fits &= misfit <= FIT * size
        if np.any(~fits & needed) and not self.failed:
            self.failed = NOT_A_MAP.format(misfit=float(np.max(
                (misfit / np.maximum(size, np.finfo(float).tiny))[needed])))
        return fits

    def told(self) -> bool:
        """Whether the map holds for every column fitted so far (some were): the tables tell
        the true values past the run's last rows too, where Jacobi's late ones lie."""
        return bool(self.maps) and all(fits.all() for _, fits in self.maps.values())

    def designs(self, ks: np.ndarray) -> tuple:
        """Per step k of `ks`: the known signals' mean over it, and their values at its start
        and end, each with the map's constant column (stencils() applies a lag's map). Each
        node's time is read once."""
        first = int(ks.min())
        t = self.time(np.arange(first, int(ks.max()) + 2))
        i0 = ks - first
        integrals = self.integrals(t)
        means = (integrals[i0 + 1] - integrals[i0]) / (t[i0 + 1] - t[i0])[:, None]
        return (self._affine(means), self._design(t, True)[i0],
                self._design(t, False)[i0 + 1])

    def stencils(self, designs: tuple, d: int) -> tuple:
        """Per step and column of lag d: the true value's mean over it, and its values at its
        start and end (designs: of the steps)."""
        a = self.maps[d][0]
        return tuple(x @ a for x in designs)


def _at(k, t: np.ndarray, right: bool) -> np.ndarray:
    """A table's columns at times t (a held table's value at a row: the new one from the
    right, the old one from the left)."""
    if k.hold:
        i = np.searchsorted(k.times, t, side="right" if right else "left") - 1
        return k.values[np.clip(i, 0, len(k.times) - 1)]
    return np.column_stack([np.interp(t, k.times, c) for c in k.values.T])


def _cumulative(k) -> np.ndarray:
    """A table's integral from its first row to each row (trapezoids, or rectangles held)."""
    dt = np.diff(k.times)[:, None]
    step = dt * (k.values[:-1] if k.hold else 0.5 * (k.values[:-1] + k.values[1:]))
    return np.concatenate((np.zeros((1, k.values.shape[1])), np.cumsum(step, axis=0)))
