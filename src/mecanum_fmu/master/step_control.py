"""The adaptive master's step (adaptive.py steps with it): where a step must end (Stops: the
graph's breakpoints), how long the next one is (Controller: PI on the error ratio, under the
line FLOOR + SLOPE elapsed / span), the first step's length, the shortest the times can
carry (NoProgress below it), and a jump no breakpoint announces (Bracket: closed in on and
stepped over). docs/masters.md, "The adaptive master"."""
from __future__ import annotations

import bisect
import math
from typing import Callable

import numpy as np

from ..scenario.tables import distinct
from .breakpoints import graph_breaks

SAFETY, K_I, K_P = 0.9, 0.7 / 3, 0.4 / 3
# The signed sum of the accepted steps' errors must stay under the line
# TOL x (FLOOR + SLOPE x elapsed / span): an error that grows steadily (the frame turning) gets
# its share of the tolerance per unit time, one that cancels along the run (the hold's leading
# term telescopes: a smooth input's steps may each err far more than their share) is not held
# to a share it does not need. A step's own error may take at most LOCAL x its share
# TOL x h / span (a guard: one step cannot spend the budget that the others' errors cancel).
FLOOR, SLOPE, LOCAL = 0.15, 0.7, 32.0
MIN_ROOM = 0.5 * SLOPE / LOCAL
GROW = 1.3        # a longer step only when the controller wants GROW x it (step_to)
FIRST = 0.005     # the first step, at TOL = 1: of the span (first_step)


class Stops:
    """The times a step must end on besides the stop time: the graph's breakpoints
    (breakpoints.py). A kink (linear) is one stop; a jump (hold) two: JUMP x the output
    interval before it (at most a third of the way back to the stop before it, so that a
    short segment keeps its own steps), then on it, so that the step that sees the new value
    at its end is that short (the hold's mean blends the two values: the jump costs the step
    before it h |jump| / 2, under every hold, whatever the tolerance). A breakpoint that may
    be either (Breaks.others: the number an expression compares t with, another table's row,
    a path's) is taken as a jump. A stop is a breakpoint for the holds too
    (AdaptiveHolds.at_breakpoint), and the step after it may start shorter (restart_step)."""

    JUMP = 1e-6

    def __init__(self, graph, start: float, stop: float, interval: float):
        breaks = graph_breaks(graph)
        jumps = breaks.taken_as_jumps()
        marks = distinct(np.concatenate([[start], np.asarray(breaks.kinks, dtype=float),
                                          jumps]))
        gap = jumps - marks[np.maximum(np.searchsorted(marks, jumps) - 1, 0)]
        gap = np.where(gap > 0, gap, interval)
        before = jumps - np.minimum(self.JUMP * interval, gap / 3)
        # two stops nearer than this are one: a few round-offs of the times, at most 1e-9 h_out
        self.near = near = min(1e-9 * interval, 8 * np.finfo(float).eps * max(
            abs(start), abs(stop), interval) + 1e-3 * float(np.min(gap, initial=interval)))
        times = [float(x) for x in (*breaks.kinks, *jumps, *before)]
        self.times = sorted(x for x in set(times) if start + near < x < stop - near)
        self.before = sorted(float(x) for x in before)
        self.kinks = sorted(float(x) for x in breaks.kinks)
        self.others = sorted(float(x) for x in breaks.others)
        self.i = 0

    def on(self, t: float, times: list[float] | None = None) -> bool:
        """Whether t is one of the stops (or of `times`)."""
        times = self.times if times is None else times
        i = bisect.bisect_left(times, t - self.near)
        return i < len(times) and times[i] <= t + self.near

    def before_jump(self, t: float) -> bool:
        """Whether t is the stop just before a jump: the next step is the jump's own."""
        return self.on(t, self.before)

    def restart_step(self, t: float, stop: float, first: float, rows) -> float:
        """The longest first step after the stop at t.
        - After a breakpoint that may be either (an expression's, a path's row), `first`
          (first_step): what follows it is unknown, and the holds restart, so a first step's
          error has no estimate (on quiet_then_busy a 0.67 s step just after t = 8, where w
          starts to turn, left theta 92x TOL 1e-2 off).
        - After a table's corner, where a row falls inside the segment (`rows`:
          dense.DenseRows.row_inside), a third of the way to the next stop: the input goes on
          as a line, which the restarted hold takes exactly, but the rows of a segment of one
          step lie on the line through its two points, whose error two points cannot
          estimate (the joystick's theta: 2.3e-5 rad, said to be below round-off); four
          points give the rows their cubic and its estimate (with three, a bound: 9-11x over
          on the joystick's x).
        - Else (a jump of a hold table: constant after it; a corner with no row inside its
          segment) no limit."""
        if self.on(t, self.others):
            return first
        end = self.next(t, stop)
        if self.on(t, self.kinks) and rows(t, end):
            return (end - t) / 3
        return math.inf

    def next(self, t: float, target: float) -> float:
        """The first stop after t, or target when none comes before it."""
        while self.i < len(self.times) and self.times[self.i] <= t + self.near:
            self.i += 1
        if self.i < len(self.times) and self.times[self.i] < target - self.near:
            return self.times[self.i]
        return target


class NoProgress(Exception):
    """The tolerance wants a step shorter than the times can carry (`smallest`) at `time`."""

    def __init__(self, time: float, wanted: float, smallest: float):
        self.time, self.wanted, self.smallest = time, wanted, smallest


def smallest_step(t: float, span: float, interval: float) -> float:
    """The shortest step the controller may ask for at t: 1e-9 of the output interval, and
    at least 64 round-offs of t (a step below it would not move t, or by a quantised amount)."""
    return max(1e-9 * interval, 1e-12 * span, 64 * np.finfo(float).eps * abs(t))


class Controller:
    """The step: PI on the error ratio, clamped, cut to land on the next stop. The errors
    it gets are in units of the tolerance (e_i / (atol + rtol |y_i|), the max norm)."""

    def __init__(self, span: float, first: float, longest: float):
        self.span, self.longest = span, longest
        self.wanted, self.ratio_before, self.last = first, 1.0, 0.0
        self.drift = 0.0      # the accumulated error so far, in units of the tolerance

    def ratios(self, own: float, h: float, drift: tuple[float, float], elapsed: float,
               jump: bool = False) -> tuple[float, float]:
        """(the step's own error against its allowance, for the PI; over 1: reject). The
        allowance is LOCAL x its share h / span, times the room the accumulated error
        leaves under the line FLOOR + SLOPE elapsed / span (at least MIN_ROOM: the line
        grows faster than the steps then add); the accumulated error after the step must
        stay under the line too, unless it is over it without the step (`drift`: the
        accumulated error with the step and without it). A jump's own step (`jump`) errs
        h |jump| / 2 whatever its length: it may take half the room left under the line."""
        line = FLOOR + SLOPE * (elapsed - h) / self.span
        room = max(MIN_ROOM, 1.0 - self.drift / line)
        own = own / (LOCAL * room * h / self.span)
        line += SLOPE * h / self.span
        if jump:
            return 0.0, (drift[0] - drift[1]) / max(0.5 * (line - drift[1]), 1e-300)
        if drift[1] >= line:        # over the line already without this step (an output's
            return own, own         # |y| fell, under a relative tolerance): no shorter step
        return own, max(own, drift[0] / line)     # can undo that

    def accept(self, ratio: float, h: float, drift: float) -> None:
        r = min(max(ratio, 1e-10), 1e30)
        factor = SAFETY * r ** -K_I * self.ratio_before ** K_P
        # never more than GROW x `longest` (the run's span), nor than the step the error
        # model (ratio ~ h^3) allows: no step that is sure to be rejected
        self.wanted = min(self.wanted * min(2.0, max(0.5, factor)), GROW * self.longest,
                          h * r ** (-1 / 3))
        self.ratio_before, self.drift, self.last = r, drift, h

    def restart(self, longest: float) -> None:
        """After a stop: the next step at most `longest` (Stops.restart_step)."""
        self.wanted = min(self.wanted, longest)

    def reject(self, ratio: float, h: float) -> None:
        ratio = ratio if ratio == ratio else math.inf      # NaN: as far over as can be
        self.wanted = h * max(0.2, min(0.9, SAFETY * ratio ** (-1 / 3)))

    def step_to(self, t: float, target: float) -> float:
        """A step from t that lands on `target` (the next stop) in whole steps: the last
        step again while it lands there and the wanted step is neither shorter nor GROW x
        longer (a change of step costs the hold's leading error term its telescoping:
        |u''| |h_1^3 - h_2^3| / 24 per change)."""
        left = target - t
        n = max(1, math.ceil(left / min(self.wanted, self.longest) - 1e-9))
        keep = round(left / self.last) if self.last else 0
        if keep > n and abs(left / self.last - keep) < 1e-6 and \
                math.ceil(left * GROW / self.wanted - 1e-9) >= keep:
            n = keep
        return left if n == 1 else left / n


def first_step(tolerance: float, span: float) -> float:
    """The first steps have no history for the error estimate: short (the trapezoid's error
    then is h^3 |u''| / 12 per step, below the tolerance for any smooth input of size ~1),
    FIRST of the run's span times TOL^(1/3), whatever the output interval."""
    return span * FIRST * min(1.0, tolerance ** (1 / 3))


class Bracket:
    """A jump that no breakpoint announces: an FMU's output on a grid of its own (the
    Reference FMUs' Dahlquist, Euler at 0.1 s: its x jumps at each of its steps). A step
    over it errs (its rows' interpolation, a held input's blend) as much however short it
    is, so the controller's rejections would close in on it for ever (NoProgress). Where a
    step SHRINK x shorter than the first rejected before its end is rejected too (a smooth
    error falls as h^2 to h^3 in these units: a million-fold), a jump lies before its end,
    `end` (the rejections between may come from later times: each step that does not reach
    the jump is taken): the steps then halve what is left before it, each rejection
    moves `end` in, and the step that ends on it, once within `width` (Stops.JUMP x the
    output interval, as short as a jump's own step before a breakpoint of the graph's), is
    taken whatever its error (a row before `end` is landed on first: within); the holds
    and the rows restart after it (adaptive.step_adaptive), as after a breakpoint that may be a
    jump, and the estimate says the tolerance is not controlled there (adaptive._not_controlled).
    Only where the graph holds FMUs the scenario layer knows nothing of (`active`): the
    bundled ones announce every jump."""

    SHRINK = 1e3

    def __init__(self, width: float, active: bool, row_after: Callable[[float], float]):
        self.width, self.active, self.row_after = width, active, row_after
        self.end: float | None = None
        self.first: tuple | None = None     # the first rejected step (its end, h)
        self.crossed = False        # the last step taken was the one over the jump
        self.found: list[float] = []

    def within(self, t: float, h: float) -> float:
        """The step to try from t: h, at most half of what is left before the jump (all
        of it once within `width`), or one that lands on an output row before `end` (the
        row then holds the FMUs' own values; a staircase's jump often falls on one: the
        step over it then ends on it)."""
        if self.end is None:
            return h
        left, row = self.end - t, self.row_after(t)
        if row < self.end:
            return min(h, row - t)
        return left if left <= self.width else min(h, 0.5 * left)

    def rejected(self, t: float, h: float) -> None:
        """A step of h from t rejected."""
        if not self.active:
            return
        if self.end is not None:
            self.end = min(self.end, t + h)
            return
        if self.first is None or t >= self.first[0]:     # none, or passed: this one first
            self.first = (t + h, h)
        elif h * self.SHRINK <= self.first[1]:
            self.end, self.first = t + h, None

    def narrow(self, t: float) -> bool:
        """Whether the next step from t is the one over the jump."""
        return self.end is not None and self.end - t <= self.width

    def over(self, t: float, h: float) -> bool:
        """Whether the step of h from t is the one over the jump (taken whatever its
        error); the jump is then found."""
        self.crossed = self.narrow(t)   # (then `within` gave h = end - t, to round-off)
        if self.crossed:
            self.found.append(self.end)
            self.end = None
        return self.crossed
