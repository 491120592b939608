"""Richardson extrapolation between step sizes: the fixed-step masters' estimate where the
embedded pair does not apply (pair.py), and by name (--estimate richardson).

The same graph is stepped again by the same master at r1 h and r2 h: 3/2 h and 3 h (1.0x the
run's doStep calls), or the first pair of CANDIDATES whose grids step on the same
breakpoints as the run's (table rows, segments, the times an expression compares t with, the
stop time): a coarser run that steps over a jump the run steps on makes an error of another
kind. On the times the three runs share, d1 = y_h - y_r1h and d2 = y_r1h - y_r2h; the
observed order p, from max|d2| / max|d1| and bounded to [1, the master's order] (to 2 where
the run steps across a table's corner), gives the error of the run, e_h ~ d1 / (r1^p - 1),
on the times the run shares with the r1 h run: their max (where no pair of coarser steps
steps on the run's breakpoints but one step does, that one run alone, p the master's order:
SINGLE). At the end, where the leading term may cancel (a path that closes, an error that
turns), two terms of the error, a h^p + b h^(p+1), are fitted to the end's d1 and d2 (p the
end's own order where the end's difference is a small share of the largest and falls
faster), and the end is at most the max (docs/masters.md, "The error estimate"). A
difference that is within the round-off of the outputs is reported as "below round-off",
never as a made-up number; coarser runs out of the h^p range give "unresolved" (the end
alone when the coarsest is off by most of the output's range); where the coarser runs cannot
be made (fewer than four steps, a coarser run that fails) the estimate says why and gives no
number.
"""
from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

import numpy as np

from ..errors import SimulationError
from ..masters import entry as master_entry
from ..results import BELOW_ROUND_OFF, CANCELS, Results, round_off
from ..scenario.graph import Graph
from .breakpoints import graph_breaks


METHOD = ("Richardson extrapolation: the run repeated at {r1} h and {r2} h, e ~ (y_h - y_r1h)/"
          "(r1^p - 1) with the observed order p bounded to [1, {order}]")
ONE = Fraction(1)
# the coarser steps (in run steps) the estimate compares with, in order of preference
# (doStep calls: 1/r1 + 1/r2 of the run's, 1.0 for 3/2 and 3, at most 1.2)
CANDIDATES = tuple((Fraction(a), Fraction(b)) for a, b in (
    ("3/2", "3"), ("5/4", "5/2"), ("5/3", "5"), ("2", "4"), ("2", "10"), ("5/2", "5"),
    ("5", "10"), ("5", "25")))
# where no pair of CANDIDATES steps on the run's breakpoints: one coarser run, at the first of
# these that does (doStep calls 1/r), with p the master's order: one difference cannot tell
# the order (a recorded path whose rows fall every second step: only 2 h steps on them all)
SINGLE = tuple(Fraction(r) for r in ("2", "3", "4", "5"))
SINGLE_METHOD = ("Richardson extrapolation: the run repeated at {r1} h, e ~ (y_h - y_r1h)/"
                 "(r1^p - 1) with p = {order}, the master's order (no second coarser step "
                 "steps on the run's breakpoints, and one difference does not tell the order)")
# the one run at h/2 (twice the run's doStep calls): where no coarser step steps on every
# breakpoint the run steps on (a path's rows at every step: coarse_factors), and, by name
# only, where FMUs sample at their own period (Graph.sampled, estimate.coarse_plan): a coarser
# step would move the samples. Half the step keeps both
FINER = Fraction(1, 2)
FINER_METHOD = ("Richardson extrapolation: the run repeated at h/2 ({why}), e ~ (y_h - y_h/2)/"
                "(1 - 2^-p) with p = {order}{whose}")
FINER_SAMPLED = "{sampled} sample at their own period: a coarser step would move the samples"
# where the pair found held inputs that jump at times the master does not know (a staircase on
# an FMU's own grid, a relay) or a response that a probe's move did not move (an input that
# saturates or is quantized: kinks and jumps inside the FMU): a coarser step would step across
# the jumps the run steps on (its error of another kind: a staircase on the run's nodes, which
# Jacobi holds exactly, read 1e12x its round-off error), and a jump held over part of a step
# errs to the first order, whatever the master's (a kink's higher order reads up to 2x over)
FINER_ROUGH = ("held inputs or an FMU's response jump or bend at times the master does not "
               "know, as a staircase on an FMU's own grid, a relay, or an input that saturates "
               "or is quantized does: a coarser step would step across those the run steps on, "
               "and a jump held over part of a step errs to the first order")
FINER_BREAKS = ("no coarser step steps on every breakpoint the run steps on: a path's or a "
                "table's rows")
# there, the run is repeated at h/2 and at h/3 and the larger estimate kept: a jump's error
# on a step hangs on where in the step it falls, and one finer grid may see it fall as the
# run does on average (a staircase every n + 1/2 steps at h/2, n + 1/3 at h/3: 11 of 120
# staircases' largest errors read 0.10x to 0.30x with h/2 alone, 1 with both; docs/masters.md)
ROUGH = (Fraction(1, 2), Fraction(1, 3))
ROUGH_METHOD = ("Richardson extrapolation: the run repeated at h/2 and at h/3 ({why}; a "
                "jump's error hangs on where in the step it falls, which one finer grid may "
                "see as the run does), e ~ the larger of (y_h - y_h/2)/(1 - 2^-1) and "
                "(y_h - y_h/3)/(1 - 3^-1)")
ROUGH_END = (f"unresolved (its differences from the runs at h/2 and h/3 are under {CANCELS:g} "
             "of the largest: one difference does not tell an end whose error cancels from "
             "two runs that meet there by chance)")
FINER_END = (f"unresolved (its difference from the run at h/2 is under {CANCELS:g} of the "
             "largest: one difference does not tell an end whose error cancels from two runs "
             "that meet there by chance, as a count's ticks make them)")
_END = np.iinfo(np.int64).max
# the coarser runs' differences growing more than this times as fast as the master's order
# allows: they are out of the range where the error goes as h^p, and no number is given
OUT_OF_RANGE = 1.3
UNRESOLVED = "unresolved (the coarser runs are out of the h^p range)"
# the coarser runs the same to round-off where the run differs from them: no order of the step
# explains it (an error C h^p, p > 0, has |y_r1h - y_r2h| at least 1.71x |y_h - y_r1h| at 3/2
# and 3). A pythonfmu FMU whose state keeps an attribute it does not register (set back to t0,
# the attribute stays as the run left it) read 1.0 where its error was 4e-7
NOT_THE_STEP = ("unresolved (the coarser runs agree to round-off where the run differs from "
                "them: what differs is not the step, as when an FMU's state, set back to t0 "
                "for them, misses some of what it holds)")
# the end's difference below this share of the run's largest: the leading term cancels there
# (a path that closes), and the end's own order may be higher than the run's
CANCELLED = 0.05
# the coarsest run off by this share of the output's range or more: the end point turns with
# the step (jacobi's lag at 0.5 s steps), and no number is given for it. Set between the
# largest share whose end was still within 3x (0.63) and the smallest that was not (0.76) on
# the bundled scenarios (bench/estimates.py)
FAR = 0.7
UNRESOLVED_END = (f"unresolved (the coarser runs are off by {FAR:.0%} of the output's range "
                  "or more)")
# the highest order the error can have where the run steps across a kink or jump of a table
# or segments (a breakpoint off its grid): the hold cannot follow a corner inside a step
ACROSS_ORDER = 2


def steps_across(marks: np.ndarray, exp) -> bool:
    """Whether the run's grid steps across a breakpoint (one off its grid, inside the run)."""
    k = (marks[(marks > exp.start_time) & (marks < exp.stop_time)] - exp.start_time) \
        / exp.step_size
    return not _on_grid(k, 1.0).all()


def _on_grid(k: np.ndarray, r: float) -> np.ndarray:
    """Which times, k in run steps from the start, a grid of steps of r run steps steps on
    (a recorded table's 0.049999872 s is on the 0.05 s grid: a jump 1e-7 s off a step
    costs nothing)."""
    return np.abs(k / r - np.round(k / r)) < 1e-3


def room_for_coarser(exp) -> bool:
    """Whether the run has 4 steps or more, the fewest coarse_factors compares."""
    return exp.stop_time - exp.start_time >= 4 * exp.step_size * (1 - 1e-9)


def coarse_factors(graph: Graph, exp, marks: np.ndarray | None = None
                   ) -> tuple[Fraction, ...] | None:
    """The coarser steps (r1 h, r2 h) of the estimate: the first pair of CANDIDATES whose
    grids step on the same breakpoints (of tables and segments) as the run's own grid, with
    room for 2 steps of r2 h; else the first one of SINGLE that does (r1 h alone); else the
    run at h/2 (FINER), whose grid holds the run's. A coarser run that steps over a
    breakpoint the run steps on (or the reverse) has an error of another kind there (a jump
    inside a step): comparing the two says nothing of the run's. None when the run has
    fewer than 4 steps. `marks`: graph_breaks(graph).times(), when known."""
    h, span = exp.step_size, exp.stop_time - exp.start_time
    if not room_for_coarser(exp):
        return None
    marks = graph_breaks(graph).times() if marks is None else marks
    k = (np.append(marks, exp.stop_time) - exp.start_time) / h
    k = k[k > 0.5]          # the stop time too: a short last step is an error of its own
    mine = _on_grid(k, 1.0)
    kept = lambda r: bool(np.array_equal(_on_grid(k, float(r)), mine))  # noqa: E731
    room = lambda r: 2 * r * h <= span * (1 + 1e-9)     # noqa: E731
    return next((pair for pair in CANDIDATES if all(map(kept, pair)) and room(pair[1])),
                next(((r,) for r in SINGLE if kept(r) and room(r)), (FINER,)))


def coarse_experiment(exp, factor: Fraction):
    """The experiment of the coarser run at factor x the step."""
    return dataclasses.replace(exp, step_size=float(factor) * exp.step_size)


def coarse_sink(exp, names: list[str], fine: np.ndarray) -> tuple:
    """(a sink for the coarser run at exp's step, what it kept: a list of row chunks): only
    the estimated columns, and only the rows at times the run kept (`fine`: the run's
    Results may hold a few evenly spaced rows of a long run): memory stays flat."""
    parts: list[np.ndarray] = []
    def quarters(t: np.ndarray) -> np.ndarray:      # the times in quarters of exp's step
        return np.round((t - exp.start_time) / exp.step_size * 4).astype(np.int64)

    wanted = quarters(fine)
    ends = np.array([fine[-1]]) if len(fine) else fine

    def keep(chunk: np.ndarray) -> None:
        t = chunk["time"]
        on = np.isin(quarters(t), wanted) | np.isin(t, ends)
        parts.append(chunk[["time"] + names][on])
    return keep, parts


def coarse_rows(wall: float, parts: list[np.ndarray], names: list[str]) -> tuple:
    """(stepping seconds, times, {name: values}) of a coarser run from its sink's chunks."""
    rows = np.concatenate(parts)
    return wall, rows["time"], {n: np.asarray(rows[n], dtype=float) for n in names}


def coarse_run(graph: Graph, exp, names: list[str], simulate, fine: np.ndarray
                ) -> tuple | str:
    """The coarser run at exp's step made afresh (coarse_rows), or why it failed."""
    keep, parts = coarse_sink(exp, names, fine)
    try:
        results = simulate(graph, exp, sink=keep, keep_rows=2)
    except SimulationError as err:
        return str(err)
    if ended := results.extra.get("ended"):     # master._ended: its rows stop short
        return f"{ended['by']} asked to end it at t = {ended['time']:g} s"
    return coarse_rows(results.wall_time, parts, names)


def _keys(exp, times: np.ndarray, every: float) -> np.ndarray:
    """A key per row: its index on the grid of step `every`, -1 off the grid; the end (stop
    time, common to every run) gets the largest key."""
    k = (times - exp.start_time) / every
    keys = np.where(np.abs(k - np.round(k)) < 1e-6, np.round(k), -1).astype(np.int64)
    keys[-1] = _END
    return keys


def _common(exp, every: float, *times: np.ndarray) -> list[np.ndarray]:
    """Per run (its times), the indices of the rows at the times they all share, in time
    order: one row per shared key (where the times quantise, at 1e15 s, several rows may
    round to one key: the first is taken). Found once per estimate, for every output."""
    keys = [_keys(exp, t, every) for t in times]
    shared = keys[0][keys[0] >= 0]
    for k in keys[1:]:
        shared = np.intersect1d(shared, k[k >= 0])
    picked = []
    for k in keys:
        unique, first = np.unique(k, return_index=True)
        picked.append(first[np.isin(unique, shared)])
    return picked


def _shared(*factors: Fraction) -> Fraction:
    """The step of the grid that steps of factors x h share (the least common multiple)."""
    num = math.lcm(*(f.numerator for f in factors))
    return Fraction(num, math.gcd(*(f.denominator for f in factors)))


def _pairs(exp, factors: tuple, fine: np.ndarray, mid: np.ndarray, coarse: np.ndarray
           ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The rows of (fine, mid) on the times the run and the r1 h run share, and of (fine,
    mid, coarse) on the times all three share (`fine` ... : each run's times)."""
    r1, r2 = factors
    h = exp.step_size
    return (_common(exp, float(_shared(ONE, r1)) * h, fine, mid),
            _common(exp, float(_shared(ONE, r1, r2)) * h, fine, mid, coarse))


def _richardson(exp, steps: int, factors: tuple, values: tuple, rows: tuple,
                orders: tuple[int, int]) -> dict:
    """{"max", "end"} of one output from its values in the three runs (fine, mid, coarse)
    and the rows they share (_pairs); `orders`: the master's order (the h^p range) and the
    highest the error can have here (2 where the run steps across a breakpoint)."""
    order, top = orders
    fine, mid, coarse = values
    (i_f2, i_m2), (i_f4, i_m4, i_c4) = rows
    f2, m2, f4, m4, c4 = fine[i_f2], mid[i_m2], fine[i_f4], mid[i_m4], coarse[i_c4]
    d1, d1_4, d2 = f2 - m2, f4 - m4, m4 - c4
    big1, big1_4, big2 = (float(np.max(np.abs(d))) for d in (d1, d1_4, d2))
    floor = round_off(f2, steps)
    if big1 <= floor:
        return {"max": BELOW_ROUND_OFF, "end": BELOW_ROUND_OFF}
    r1, r2 = (float(r) for r in factors)
    if big2 > OUT_OF_RANGE * _grows(r1, r2, order) * big1_4:
        return {"max": UNRESOLVED, "end": UNRESOLVED}
    if big2 <= floor:
        return dict.fromkeys(("max", "end"), NOT_THE_STEP)
    p = _order(big2, big1_4, floor, (r1, r2), top)
    largest = big1 / (r1 ** p - 1.0)
    if big2 >= FAR * np.ptp(f2):
        return {"max": largest, "end": UNRESOLVED_END}
    end = min(_end(float(-d1_4[-1]), float(-d2[-1]), big1_4, floor, (r1, r2), p, order),
              largest)       # an end above the run's largest: no
    return {"max": largest, "end": end if end > floor else BELOW_ROUND_OFF}


def _end(e1: float, e2: float, largest: float, floor: float, factors: tuple, p: float,
         order: int) -> float:
    """|e_h| at the end from its two differences: two error terms at the run's order p, or
    at the end's own order where its differences agree in sign and fall faster and the
    end's difference is a small share of the run's largest (a figure eight that closes
    cancels two terms; an end error that merely crosses zero keeps the run's order)."""
    if e1 * e2 > 0 and abs(e1) < CANCELLED * largest:
        p = max(p, _order(abs(e2), abs(e1), floor, factors, order + 2))
    return _two_terms(e1, e2, *factors, p)


def _two_terms(d1: float, d2: float, r1: float, r2: float, p: float) -> float:
    """|e_h| at one time from y_r1h - y_h = d1 and y_r2h - y_r1h = d2, with two terms of the
    error, e(r h) = a r^p + b r^(p+1): the end point, where the leading term may cancel (a
    path that closes, an error that turns) and the next one decides."""
    q = p + 1.0
    m11, m12, m21, m22 = r1 ** p - 1.0, r1 ** q - 1.0, r2 ** p - r1 ** p, r2 ** q - r1 ** q
    det = m11 * m22 - m12 * m21     # Cramer's rule: the same bits on every CPU (no LAPACK)
    a, b = (d1 * m22 - m12 * d2) / det, (m11 * d2 - m21 * d1) / det
    return abs(float(a + b))


def _order(coarse: float, fine: float, floor: float, factors: tuple, highest: int) -> float:
    """The observed order p, bounded to [1, highest]: with e = C h^p, the ratio
    |y_r1h - y_r2h| / |y_h - y_r1h| is (r2^p - r1^p) / (r1^p - 1), increasing in p (r1^p
    when r2 = r1^2), solved by bisection."""
    ratio = coarse / max(fine, floor)
    grows = lambda p: _grows(*factors, p)       # noqa: E731
    low, high = 1.0, float(highest)
    if not ratio > grows(low):
        return low
    if ratio >= grows(high):
        return high
    for _ in range(50):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if grows(mid) < ratio else (low, mid)
    return 0.5 * (low + high)


def _grows(r1: float, r2: float, p: float) -> float:
    """|y_r1h - y_r2h| / |y_h - y_r1h| for an error C h^p."""
    return (r2 ** p - r1 ** p) / (r1 ** p - 1.0)


def _single(steps: int, r: float, values: tuple, rows: list, p: int) -> dict:
    """{"max", "end"} of one output from the run and one coarser run (SINGLE), at order p,
    or the run at h/2 (FINER: an end under CANCELS of the largest is unresolved)."""
    fine, mid = values
    d1 = fine[rows[0]] - mid[rows[1]]
    if float(np.max(np.abs(d1))) <= (floor := round_off(fine[rows[0]], steps)):
        return {"max": BELOW_ROUND_OFF, "end": BELOW_ROUND_OFF}
    e = np.abs(d1) / abs(r ** p - 1.0)
    end, largest = float(e[-1]), float(e.max())
    if r == FINER and end < CANCELS * largest:
        return {"max": largest, "end": FINER_END}
    return {"max": largest, "end": end if end > floor else BELOW_ROUND_OFF}


def _on_run(exp, results: Results, r: Fraction, run: tuple) -> list[np.ndarray]:
    """The rows of the run and of its repetition at r h (coarse_rows') at their common
    times (of the run's grid and r h's)."""
    return _common(exp, float(_shared(ONE, r)) * exp.step_size, results.time, run[1])


def _finer(results: Results, factors: tuple, coarse: list, rows: list, name: str) -> dict:
    """{"max", "end"} of one output from the runs at h/2 and h/3 (ROUGH; `rows`: _on_run's
    per run), at order 1: the larger of the two estimates' largest values, and of their
    ends; an end under CANCELS of the largest is unresolved (ROUGH_END)."""
    fine = np.asarray(results[name], dtype=float)
    floor = round_off(fine, results.steps)
    largest, end, differs = 0.0, 0.0, 0.0
    for r, run, at in zip(factors, coarse, rows):
        d = np.abs(fine[at[0]] - run[2][name][at[1]])
        e = d / abs(float(r) - 1.0)
        largest, end = max(largest, float(e.max())), max(end, float(e[-1]))
        differs = max(differs, float(d.max()))
    if differs <= floor:
        return {"max": BELOW_ROUND_OFF, "end": BELOW_ROUND_OFF}
    if end < CANCELS * largest:
        return {"max": largest, "end": ROUGH_END}
    return {"max": largest, "end": end if end > floor else BELOW_ROUND_OFF}


def richardson(graph: Graph, results: Results, names: list[str], factors: tuple,
               coarse: list, marks: np.ndarray, rough: bool = False) -> dict:
    """summary.json's estimate from the coarser runs (coarse_rows' per factor), `marks` the
    graph's breakpoints (graph_breaks(graph).times()); `rough`: the pair found held inputs
    or a measured response that jump or bend at times the master does not know (FINER_ROUGH:
    order 1)."""
    exp = graph.scenario.experiment
    order = 1 if rough else master_entry(exp.master).order
    orders = (order, min(order, ACROSS_ORDER) if steps_across(marks, exp) else order)
    if tuple(factors) == ROUGH:
        rows = [_on_run(exp, results, r, run) for r, run in zip(factors, coarse)]
        estimate = {n: _finer(results, factors, coarse, rows, n) for n in names}
        method = ROUGH_METHOD.format(why=FINER_ROUGH)
    elif len(factors) == 1:
        rows = _on_run(exp, results, factors[0], coarse[0])
        estimate = {n: _single(results.steps, float(factors[0]), (np.asarray(
            results[n], dtype=float), coarse[0][2][n]), rows, orders[1]) for n in names}
        method = SINGLE_METHOD.format(r1=str(factors[0]), order=orders[1])
        if factors[0] == FINER:
            why = FINER_ROUGH if rough else FINER_SAMPLED.format(
                sampled=", ".join(graph.sampled)) if graph.sampled else FINER_BREAKS
            method = FINER_METHOD.format(why=why, order=orders[1],
                                         whose="" if rough else ", the master's order")
    else:
        rows = _pairs(exp, factors, results.time, coarse[0][1], coarse[1][1])
        estimate = {n: _richardson(exp, results.steps, factors, (np.asarray(
            results[n], dtype=float), coarse[0][2][n], coarse[1][2][n]), rows, orders)
            for n in names}
        method = METHOD.format(r1=str(factors[0]), r2=str(factors[1]), order=orders[1])
    cost = sum(c[0] for c in coarse) / max(results.wall_time, 1e-12)
    return {"error_estimate": estimate, "error_estimate_method": method,
            "error_estimate_cost": round(cost, 3)}
