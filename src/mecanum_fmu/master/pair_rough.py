"""Whether the held inputs move as smooth curves between the run's rows: the embedded pair's
stencils take an input's true mean over a step from the cubic through its nearest values in
the same smooth piece (pair_stencils.py), which holds only where the values are those of a
smooth curve at this step. An FMU may move its outputs on a grid of its own (a fixed-step
solver longer than the communication step, a sampled controller: a staircase of values that
the master's breakpoints do not know), or faster than the step; the cubic then follows
nothing, and the pair's estimate can miss the error by orders of magnitude (the Reference
FMUs' Dahlquist under the quadratic master: 0.017x to 0.035x of the error, docs/masters.md).

Per column, over every five rows in one smooth piece (Jacobi's columns a row late per lag),
the sum of |fourth differences| against the sum of |first differences|: a smooth curve at
h omega gives about (h omega)^3 (0.001 at 10 steps a radian, 0.9 at a radian a step), a
staircase 6 to 9 whatever its period, a single unknown jump under 1 (the cubic across it
says O(h) of the jump, as it should). Over ROUGH, with a variation above round-off, the
pair hands over; so it does where a value is held to the bit for one row between two moves
often enough (HELD: stairs 1 to 2 steps long, whose sums stay under ROUGH), and where the
ratio does not grow over every second row as a curve's or a kink's does (NOISY: a quantizer
finer than the step's change). The adaptive master applies the first rule on its unequal
steps (adaptive_holds._VarBlend.tally, ADAPTIVE_ROUGH), and leaves its estimate unresolved.
"""
from __future__ import annotations

import numpy as np

from ..results import round_off

ROUGH = 5.0     # sum |4th differences| / sum |1st differences| (cos at 3 steps a radian: 4.9)
SPAN = 5        # the rows one fourth difference reads
# a staircase whose stairs last 1 to 2 steps sums its fourth differences to 2.2 to 2.9 of its
# first (the wave on a 0.07 s grid at 0.05 s, on 0.13 s at 0.1 s), under ROUGH, where the
# bouncing ball's kinks sum to 2.1 to 3.2: no limit tells them apart. Its rows show it
# otherwise: a value held to the bit for one row between two moves (a share 1 - h / period
# of its steps), which a curve that moves never holds. Over HELD of the moves, at least
# HELD_LEAST times, the column is a staircase (its pair read 0.11x to 0.38x of the error)
HELD, HELD_LEAST = 0.1, 3
# the same sums over every second row (a step of 2h): a smooth curve's ratio grows about 8x
# (as h^3), a kink's about 2x (the bouncing ball, |sin 2t|, a saturation: 1.6 to 2.8), and
# many small jumps' (a quantizer finer than the step's change) not at all: 0.25 to 0.61 of the
# ratio at h on the test graphs. Between NOISY_LOW and NOISY of the ratio at h, which is over
# NOISY_FLOOR (a curve's own (h omega)^3 is not the whole of it), the column is rough: a lag
# fed cos t quantized to 0.005 read 0.02x to 0.09x of its largest error at 0.01 and 0.02 s.
# Left to the pair: a single unknown jump on a curve (1.0: its cubic says O(h) of it); under
# NOISY_LOW, a loop's odd-even ringing (0.14: a P loop at 0.2 s, trapezoidal, where the pair
# reads 1.08x) and a staircase finer than the step (0.19), which the subsample aliases
NOISY, NOISY_LOW, NOISY_FLOOR = 0.75, 0.2, 0.1
# the adaptive master's, per accepted step h^4 |u4| (the fourth derivative) against |the
# step's change|: its steps shrink around a staircase's jumps, which dilutes the sum (a
# staircase 4.3 to 8.1 at tolerances 1e-2 to 1e-6; the bundled and the test FMUs' curves
# 0.14 at most, at 1e-2)
ADAPTIVE_ROUGH = 1.0


def rough_columns(sums: np.ndarray, size: np.ndarray, n: int, limit) -> np.ndarray:
    """The columns whose `sums` (sum |4th differences|, sum |1st|) say they are not smooth
    curves: a variation above round-off (results.round_off: linear in the size, at least 1,
    over n steps) whose fourth differences sum to over `limit` times it (a float, or one
    per column)."""
    moved = sums[1] > np.maximum(size, 1.0) * round_off([1.0], n)
    return np.flatnonzero(moved & (sums[0] > limit * sums[1]))


def whole_windows(starts: np.ndarray, ends: np.ndarray, n: int, span: int = SPAN
                  ) -> np.ndarray:
    """Per node j = 0 .. n: whether nodes j .. j + span - 1 lie in one smooth piece
    (breakpoints.Pieces' starts and ends)."""
    nodes = np.arange(n + 1)
    piece = np.searchsorted(starts, nodes, side="right") - 1
    return nodes + span - 1 <= ends[np.maximum(piece, 0)]


class Roughness:
    """The tally of one run's held columns (PairRows' window columns by lag), chunk by
    chunk as the rows come in."""

    def __init__(self, cols: dict, starts: np.ndarray, ends: np.ndarray, n: int, width: int):
        """`starts`, `ends`: the run's smooth pieces (breakpoints.Pieces), of n steps."""
        # per node, whether the rows of a fourth difference from it lie in one smooth piece:
        # at the step, and over every second row
        self.whole = (whole_windows(starts, ends, n),
                      whole_windows(starts, ends, n, 2 * SPAN - 1))
        # per column its lag (-1: not tallied; a column read at two lags: the last)
        self.lag = np.full(width, -1)
        for d, these in cols.items():
            self.lag[these] = d
        # per column: sum |4th differences|, |1st|; the moves, the one-row holds between;
        # sum |4th differences|, |1st| over every second row
        self.sums = np.zeros((6, width))

    def tally(self, window: np.ndarray, lo: int, first: int, count: int) -> None:
        """Add the fourth differences that end in the chunk of rows first .. first + count
        - 1 (the window holds rows lo .. , at least eight before the chunk)."""
        span = SPAN
        r0, r1 = max(first - span + 1, lo), first + count - span
        if r1 >= r0:
            rows, m, ok = self._rows(window, lo, r0, r1, span, 0)
            self.sums[0] += (np.abs(np.diff(rows, 4, axis=0)) * ok).sum(axis=0)
            moves = np.diff(rows[:m + 3], axis=0) != 0      # the steps from rows r0 .. r1 + 2
            self.sums[1] += (np.abs(rows[1:m + 1] - rows[:m]) * ok).sum(axis=0)
            self.sums[2] += (moves[:m] & ok).sum(axis=0)
            self.sums[3] += (moves[:m] & ~moves[1:m + 1] & moves[2:m + 2] & ok).sum(axis=0)
        span = 2 * SPAN - 1         # every second row: rows r, r + 2, .. r + 8
        r0, r1 = max(first - span + 1, lo), first + count - span
        if r1 >= r0:
            rows, m, ok = self._rows(window, lo, r0, r1, span, 1)
            fourth = rows[8:] - 4 * rows[6:-2] + 6 * rows[4:-4] - 4 * rows[2:-6] + rows[:-8]
            self.sums[4] += (np.abs(fourth) * ok).sum(axis=0)
            self.sums[5] += (np.abs(rows[2:m + 2] - rows[:m]) * ok).sum(axis=0)

    def _rows(self, window: np.ndarray, lo: int, r0: int, r1: int, span: int, which: int
              ) -> tuple:
        """Rows r0 .. r1 + span - 1, how many differences start in r0 .. r1, and per such row
        and column whether its rows lie in one smooth piece (self.whole[which])."""
        node = np.arange(r0, r1 + 1)[:, None] - self.lag      # row r of lag d: node r - d
        ok = (node >= 0) & (self.lag >= 0) & self.whole[which][np.maximum(node, 0)]
        return window[r0 - lo:r1 + span - lo], r1 - r0 + 1, ok

    def rough(self, size: np.ndarray, n: int) -> np.ndarray:
        """The columns whose values are not a smooth curve at this step: their fourth
        differences over ROUGH of their first, or one-row holds between moves (HELD), or
        a ratio that does not grow over every second row (NOISY)."""
        s = self.sums
        held = (s[3] >= HELD_LEAST) & (s[3] > HELD * s[2])
        with np.errstate(divide="ignore", invalid="ignore"):
            at_h = np.where(s[1] > 0, s[0] / s[1], 0.0)
            at_2h = np.where(s[5] > 0, s[4] / s[5], np.inf)
            noisy = (at_h > NOISY_FLOOR) & (at_2h < NOISY * at_h) & (at_2h > NOISY_LOW * at_h)
        return rough_columns(s[:2], size, n, np.where(held | noisy, 0.0, ROUGH))
