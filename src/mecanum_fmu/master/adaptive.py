"""The adaptive master: a cubic (or the quadratic) hold on a step chosen to meet a tolerance.

Per step, after the pass (docs/masters.md, "The adaptive master"):
- the hold (adaptive_holds.py) is the mean over the step of the cubic through u_k-2 ...
  u_k+1 on their own times where the third differences of this step and the last agree in
  sign (a smooth input), else
  the quadratic master's on unequal steps: the parabola through u_k-1, u_k, u_k+1, its second
  difference limited by the previous one (minmod: a kink or a jump in a table adds nothing);
  in a loop the step is predicted with the linear extrapolation, rolled back and corrected;
  after a breakpoint no value from before it enters a hold (two trapezoids first); an FMU
  whose output reads an input but is worked out in doStep alone (memory.lazy_at_start) has
  its inputs held at their end values ("end"), first order: the pair's difference then
  counts whole (AdaptiveHolds.richardson);
- the step's error, per recorded Real output, from an embedded pair: the step is taken once
  more (first) with each held input's mean corrected by the hold's signed next term (the
  cubic's 19/720 h^4 u4, the first two steps' trapezoids, a jump's own step), every FMU rolled
  back (fmi2SetFMUstate), then with the hold itself; the difference of the recorded outputs
  is the step's error, the FMUs' own dynamics included. Where a kink sits among a held
  input's values (KINK: a third-party FMU's, which no breakpoint announces) the step is
  taken once more whole without the hold's estimated error, and the outputs' difference is
  added to the step's; the whole-step trajectory holds that error times its divisor, so that
  its estimate carries it. On such graphs, where a step's halves moved no output of an FMU
  that holds the pair's inputs and one taken with the held inputs at their mean less or plus
  half their change left them to the bit (a flat response: a saturation), every later step
  is also taken with the held inputs so: what is left of the two beyond a linear response
  is a bend inside the step (bend_error), which the held means do not see where they sit
  on one side of it; its error is added to the step's and to the whole-step trajectory's
  estimate. An FMU whose held inputs an error model of Graph.error_models takes (the
  PoseIntegrator's, models/pose_error.py) is left to it: the model computes the same from
  the step's values, without the extra pass, and adds what the pair cannot see
  (the frame turning within the step). No pass is added when every held input has a model;
- the error is weighed per output as ODE solvers do: e_i / (atol + rtol |y_i|), the largest
  over the outputs (the max norm); atol is the tolerance, rtol the relative one;
- the signed sum of the accepted steps' errors must stay under the line
  FLOOR + SLOPE (t - start) / span, and a step's own error under LOCAL x its share h / span
  times the room that sum leaves under the line; a rejected step rolls every FMU back and is
  retried, shorter; a step the tolerance wants below the smallest one the times can carry
  ends the run (NoProgress);
- the next step comes from a PI controller (exponents 0.7/3 and 0.4/3, ratio clamped to
  [0.5, 2], [0.2, 0.9] after a rejection); the last step is kept unless the controller
  wants GROW x it or less than it; steps are free of the output grid: they land on the stop
  time and on the breakpoints of the graph (Stops: a jump gets a short step before it), and
  the rows between (every step_size seconds: results.csv's) are interpolated (dense.py),
  whose error estimate cuts a step too.
The controller holds the signed sum of the accepted steps' errors; the run's error estimate
is the error models' and, for the pair's outputs, the difference of the run and the run
stepped whole beside it over 3 (trajectory.py: the errors carried through the dynamics,
damped where the states relax), plus a row's interpolation error's.
"""
from __future__ import annotations

import time as _time
from typing import Callable

import numpy as np

from ..results import BELOW_ROUND_OFF, CANCELS, cancelled, round_off
from .instance import RunningInstance
from .dense import DenseRows
from .recorder import Recorder
from .trajectory import WholeSteps, slot_positions, values_at
from .stepping import (NonFinite, StepFailure, asked_to_end, free_states, one_pass,
                       programs, restore_states, save_states)
from .adaptive_holds import AdaptiveHolds
from .step_control import Bracket, Controller, NoProgress, Stops, first_step, smallest_step

# a step's held input moved by more than this share of its size: a response that does not
# move with it is flat (_Loop._bent; a step of 1e-8 s, where a quantized loop chatters,
# moves its inputs by 1e-8 of themselves, and an output by less than its round-off)
MOVED = 1e-6


class OutputErrors:
    """The recorded Real outputs that no error model covers: the pair's estimate per step of
    the two half steps' error, (whole - halves) / 3 (a local error ~ h^3: an FMU that sees
    the held mean where the input changes within the step), and its signed sum over the
    accepted steps."""

    def __init__(self, recorder: Recorder, clients: list, paired: bool, divisor: float = 3.0,
                 held: frozenset = frozenset()):
        real = [p for p in recorder.graph.recorded if p.type == "Real"]
        slot = {str(p.ref): recorder.buffers.slot(p) for p in real}
        covered = [[f"{c.name}.{o}" for o in c.outputs if f"{c.name}.{o}" in slot]
                   for c in clients]
        # not `paired` (every held input has a model, which sees only its own outputs): the
        # others are left unestimated
        self.names = [n for n in slot if paired and all(n not in c for c in covered)]
        self.slots = np.array([slot[n] for n in self.names], dtype=np.intp)
        self.real = recorder.buffers.real
        # per error model, the slots of its recorded outputs: their size for rtol
        self.model_slots = [np.array([slot[n] for n in c], dtype=np.intp) for c in covered]
        self.whole, self.step, self.sum, self.scaled, self.weighted, self.loose, self.bend = (
            np.zeros(len(self.slots)) for _ in range(7))
        # per output, the FMU it is of, where that FMU holds some of the pair's inputs
        # (`held`: their names), else ""
        owner = {str(p.ref): p.ref.instance for p in real}
        self.owner = np.array([owner[n] if owner[n] in held else "" for n in self.names],
                              dtype=object)
        self.positions = slot_positions(self.slots)
        self.carried = None     # a WholeSteps: the accumulated error the dynamics carried
        self.divisor = divisor  # (whole - halves) / it: AdaptiveHolds.richardson

    def upstream(self, slots) -> np.ndarray:
        """Per slot (an error model's inputs' sources), the signed accumulated error of that
        output at the middle of this step (the sum so far and half this step's), 0 where the
        pair does not cover it: the error the model's FMU is fed from upstream."""
        return values_at(self.positions, self.sum + 0.5 * self.step, slots)

    def size(self, i: int) -> float:
        """The largest |y| of the i-th error model's recorded outputs."""
        slots = self.model_slots[i]
        return float(np.max(np.abs(self.real[slots]))) if len(slots) else 0.0

    def keep_whole(self) -> None:
        np.take(self.real, self.slots, out=self.whole)

    def keep_loose(self) -> None:
        """The step taken whole without the held means' errors at a kink (_VarBlend.next):
        the outputs' difference from the whole step is what those errors make of them."""
        np.subtract(self.whole, self.real[self.slots], out=self.loose)

    def measure(self) -> None:
        np.subtract(self.whole, self.real[self.slots], out=self.step)
        self.step /= self.divisor
        self.step += self.loose
        self.loose[:] = 0.0
        self.bend[:] = 0.0

    def quiet(self, owners: set[str]) -> np.ndarray:
        """Per output: whether it is one of the `owners`' (FMUs whose held inputs moved) and
        the halves left it where the whole step did, to 64 round-offs."""
        whole, halves = self.whole, self.real[self.slots]
        return np.isin(self.owner, list(owners)) & (np.abs(whole - halves) <= 64 * np.finfo(
            float).eps * np.maximum(np.abs(whole), np.abs(halves)))

    @staticmethod
    def still(below: np.ndarray, above: np.ndarray) -> np.ndarray:
        """Per output: whether one of two passes (_Loop._ends) left it where the whole step
        did, to the bit."""
        return (below == 0.0) | (above == 0.0)

    def bent(self, error: np.ndarray) -> None:
        """Add a bend's error (_Loop._bent) to this step's."""
        self.bend[:] = error
        self.step += error

    def ratios(self, atol: float, rtol: float) -> tuple[float, float, float]:
        """(this step's own error, the accumulated error with it, without it), each in the
        max norm of e_i / (atol + rtol |y_i|). The accumulated error is the sum of the
        steps' errors, each weighed by |y_i| at its end (so that a fall of |y_i| later does
        not make an error made earlier count more); with `carried`, the whole-step
        trajectory's signed estimate at t_k instead, which the dynamics damped."""
        if not len(self.slots):
            return 0.0, 0.0, 0.0
        scale = atol + rtol * np.abs(self.real[self.slots])
        np.divide(self.step, scale, out=self.scaled)
        before = self.weighted if self.carried is None else self.carried.now() / scale
        return (float(np.max(np.abs(self.scaled))),
                float(np.max(np.abs(before + self.scaled))),
                float(np.max(np.abs(before))))

    def accept(self) -> None:
        self.sum += self.step
        self.weighted += self.scaled


def step_errors(holds: AdaptiveHolds, errors: OutputErrors, left: float, h: float,
                tol: tuple[float, float], signed: Callable = lambda slots: None
                ) -> tuple[float, tuple[float, float], list]:
    """(the step's own error, (the accumulated error with it, without it)), in units of the
    tolerance, the worst over the error models and the pair's outputs, and the models'
    updates. Each model is fed its inputs' sources' accumulated errors: the pair's sum (for
    its bound, the controller's) and `signed` of the slots (for its estimate: the whole-step
    trajectory's, or None: the same sum)."""
    atol, rtol = tol
    own, drift, before = errors.ratios(atol, rtol)
    updates = []
    for i, client in enumerate(holds.clients):
        scale = atol + rtol * errors.size(i)
        bound = errors.upstream(client.sources)
        carried = signed(client.sources)
        error, update = client.step(holds.h, left, (bound, bound if carried is None
                                                     else carried))
        own, drift = max(own, error / scale), max(drift, client.after(h, update) / scale)
        before = max(before, max(client.now()) / scale)
        updates.append(update)
    for blend in holds.paired:      # their third differences move on
        blend.error()
    return own, (drift, before), updates


def step_adaptive(running: list[RunningInstance], recorder: Recorder, ctrl_c: list[int],
                  progress: Callable[[float], None] | None, holds: AdaptiveHolds,
                  tol: tuple[float, float], counts: dict) -> None:
    """The adaptive loop: steps free of the output grid, ending on the stops and the stop
    time; the rows between from the values around them (dense.py). `tol`: (atol, rtol).
    counts gets steps_taken, steps_rejected, the passes and the accumulated error estimate
    per row. Raises StepFailure, NonFinite, NoProgress, KeyboardInterrupt; where an FMU asks
    to end the run (RunningInstance.ends_run), its StepFailure once the rows up to the last
    accepted step are recorded and counted (master._run_loop ends the run at the last)."""
    exp = recorder.experiment
    start, stop = exp.start_time, exp.stop_time
    stops = Stops(recorder.graph, start, stop, exp.step_size)
    loop = _Loop(running, recorder, holds, tol, counts, stops.near)
    counts["names"], counts["estimates"] = loop.names(), [loop.estimate()]
    loop.rows.restart(start, loop.estimate())
    t, ended = start, None
    next_report = _time.perf_counter() + 1.0
    while t != stop:
        try:
            t = loop.step(t, stops.next(t, stop), ctrl_c, stops.near)
        except StepFailure as err:      # an FMU asked to end the run: the rows up to t
            if not asked_to_end(err):
                raise
            counts["estimates"].extend(loop.rows.emit(final=True))
            ended = err
            break
        loop.rows.add(t, loop.estimate())
        crossed = loop.bracket.crossed      # an unannounced jump: what follows is unknown
        at_stop = stops.on(t) or crossed
        counts["estimates"].extend(loop.rows.emit(final=at_stop or t == stop))
        if at_stop:
            holds.at_breakpoint(stops.before_jump(t) and not crossed)
            loop.control.restart(loop.first if crossed else stops.restart_step(
                t, stop, loop.first, loop.rows.row_inside))
            loop.rows.restart(t, loop.estimate())
        if progress is not None and _time.perf_counter() >= next_report:
            progress((t - start) / (stop - start))
            next_report = _time.perf_counter() + 0.5
    counts["terms"], counts["jumps"] = loop.terms(), loop.bracket.found
    counts["flat_at"] = loop.flat_at
    counts["not_smooth"] = holds.not_smooth(counts["steps_taken"])
    counts["rough_rows"] = loop.rows.not_smooth(loop.names())
    if loop.whole is not None:
        loop.whole.close(t)
    if ended is not None:
        raise ended


class _Loop:
    """What the adaptive loop steps with: the instances, the holds, the error models and the
    pair's outputs, the controller, and the values at t_k for a retry."""

    def __init__(self, running, recorder: Recorder, holds: AdaptiveHolds, tol: tuple,
                 counts: dict, near: float):
        exp = recorder.experiment
        self.running, self.program = running, programs(running)
        self.holds, self.tol, self.counts = holds, tol, counts
        self.span, self.interval, self.stop = (exp.stop_time - exp.start_time, exp.step_size,
                                               exp.stop_time)
        self.start = exp.start_time
        self.first = first_step(tol[0], self.span)
        self.control = Controller(self.span, self.first, self.span)
        self.errors = OutputErrors(recorder, holds.clients,
                                   bool(holds.paired) or not holds.clients, holds.richardson,
                                   frozenset(b.owner for b in holds.paired))
        self.real, self.ints = recorder.buffers.real, recorder.buffers.int
        self.saved = (self.real.copy(), self.ints.copy())      # the values at t_k
        # whether some step found a flat response (a saturation), whose bends every step
        # then looks for (_bent), and when the first did; per output, whether the halves do
        # not see it move where its response is linear (_bent: no step is taken for it again)
        self.bends, self.flat_at = False, None
        self.blind = np.zeros(len(self.errors.slots), dtype=bool)
        self.rows = DenseRows(recorder, tol, near, self.names(),
                              len(self.names()) - len(self.errors.names), holds.check)
        self.predicted = (self.real.copy(), self.ints.copy())  # after the predictor
        self.whole = WholeSteps(running, self.program, holds.blends, self.real, self.ints,
                                self.errors.slots, holds.richardson) \
            if len(self.errors.slots) else None
        if holds.check and not holds.ahead:     # third-party FMUs, no loop: see docs
            self.errors.carried = self.whole
        # where the graph holds FMUs the scenario layer knows nothing of: their jumps
        self.bracket = Bracket(Stops.JUMP * exp.step_size, holds.check, self.rows.row_after)

    def estimate(self) -> list[float]:
        """The accumulated error now, per covered output: the models' then the pair's."""
        return [*(e for c in self.holds.clients for e in c.now(signed=True)),
                *(np.abs(self.errors.sum) if self.whole is None else self.whole.error())]

    def terms(self) -> list[float]:
        """Per covered output, the size of the terms its signed estimate sums (estimate_of's
        test of cancellation): the error models' own (terms()); NaN for the pair's outputs
        (their estimate is the whole-step trajectory's, or a sum of the steps' errors, which
        are not tested)."""
        return [*(e for c in self.holds.clients for e in c.terms()),
                *np.full(len(self.errors.names), np.nan)]

    def _carried(self, slots) -> np.ndarray | None:
        """The whole-step trajectory's signed error estimate at `slots` (None without it)."""
        return None if self.whole is None else self.whole.signed(slots)

    def names(self) -> list[str]:
        return [*(f"{c.name}.{o}" for c in self.holds.clients for o in c.outputs),
                *self.errors.names]

    def step(self, t: float, goal: float, ctrl_c, near: float) -> float:
        """One accepted step from t towards goal; the time it ends at (goal itself when it
        lands within `near` of it)."""
        save_states(self.running, t)
        self.saved[0][:], self.saved[1][:] = self.real, self.ints
        h, updates, ratio, drift = self._take(t, goal, ctrl_c)
        if self.whole is not None:
            self.counts["passes"] += 1
            self.whole.step(t, h)
            self.whole.bends += self.errors.bend
        free_states(self.running, t)
        self.holds.commit()
        self.counts["steps_taken"] += 1
        for client, update in zip(self.holds.clients, updates):
            client.accept(h, update)
        self.errors.accept()
        control = self.control
        if h >= 0.1 * control.wanted:       # not cut short by a stop: a step of 1e-6 h_out
            control.accept(ratio, h, drift)  # says nothing of the next
        else:
            control.drift = drift
        if not np.isfinite(self.real).all():
            raise NonFinite(t + h)
        return goal if abs(t + h - goal) <= near else t + h

    def _take(self, t: float, goal: float, ctrl_c) -> tuple:
        """A step tried, rejected and rolled back (the FMUs and the values) until its error
        ratio is at most 1: (h, the models' updates, the ratio, the accumulated error); the
        step over an unannounced jump (Bracket) whatever its ratio."""
        control, bracket = self.control, self.bracket
        h = bracket.within(t, control.step_to(t, goal))
        while True:
            if ctrl_c[0]:
                raise KeyboardInterrupt
            self._attempt(t, h)
            own, drift, updates = step_errors(self.holds, self.errors, self.stop - t - h, h,
                                              self.tol,
                                              self._carried)
            ratio, worst = control.ratios(own, h, drift, t + h - self.start,
                                          self.holds.jump_next)
            rows = self.rows.ratio(t + h)     # the rows in the step: their interpolation
            ratio, worst = max(ratio, rows), max(worst, rows)
            if bracket.over(t, h) or worst <= 1.0:
                return h, updates, ratio, drift[0]
            self.counts["steps_rejected"] += 1
            bracket.rejected(t, h)
            control.reject(worst, h)
            smallest = smallest_step(t, self.span, self.interval)
            if control.wanted < smallest and not bracket.narrow(t):
                raise NoProgress(t, control.wanted, smallest)
            h = bracket.within(t, control.step_to(t, goal))
            self._restore(t, self.saved)

    def _restore(self, t: float, values: tuple) -> None:
        restore_states(self.running, t)
        self.real[:], self.ints[:] = values

    def _attempt(self, t: float, h: float) -> None:
        """One step of h: in a loop predicted, rolled back, corrected; with the pair, the
        step's recorded outputs kept, every FMU rolled back, and the step taken again as two
        halves on the same held polynomial (what is kept)."""
        holds = self.holds
        holds.h = h
        if holds.ahead:
            holds.mode = holds.PREDICT
            self._pass(t, h)
            restore_states(self.running, t)
            holds.mode = holds.CORRECT
        if holds.paired:
            self.predicted[0][:], self.predicted[1][:] = self.real, self.ints
        self._pass(t, h)
        if holds.paired:
            self.errors.keep_whole()
            if holds.kinked():
                kept = self._polynomials()
                self._restore(t, self.predicted)
                holds.kinks = -1.0
                self._pass(t, h)
                holds.kinks = 0.0
                self.errors.keep_loose()
                self._polynomials(kept)
            ends = self._ends(t, h) if self.bends and holds.moved() else None
            self._halves(t, h)
            self.errors.measure()
            self._bent(t, h, ends)

    def _halves(self, t: float, h: float) -> None:
        """The step taken again from t_k (the values after the predictor) as two halves on
        the whole step's held polynomial: what is kept."""
        self._restore(t, self.predicted)
        for half in (0, 1):
            self.holds.half = half
            self._pass(t + half * h / 2, h / 2)
        self.holds.half = None

    def _bent(self, t: float, h: float, ends: tuple | None) -> None:
        """A bend of an FMU's response inside the range a held input swept over the step (a
        saturation it leaves or enters), which neither the whole step nor the halves see
        where their held means sit on the same side of it: its error (bend_error), from
        the step taken with the held inputs at their mean less and plus half their change
        (`ends`: _ends). A flat response: the halves moved no output of an FMU that holds
        the pair's inputs from the whole step's (to 64 round-offs) while a held input moved
        by more than MOVED of itself, and one of the two ends leaves them where the whole
        step did, to the bit (the mean and that end saturated alike). The first such step
        takes the ends now (and its halves again: what is kept); every step after it whose
        held inputs move takes them before its halves. An output the halves left while
        the ends moved it on a linear response (a PI controller's, whose halves integrate
        the same held means) is one the halves do not see: it is not asked again."""
        quiet = self.errors.quiet(self.holds.moved(MOVED)) & ~self.blind \
            if self.holds.check else None
        if quiet is not None and quiet.any() and ends is None:
            ends = self._ends(t, h)
            self._halves(t, h)
        flat = quiet & self.errors.still(*ends) if ends is not None and quiet is not None \
            else np.zeros(len(self.errors.slots), dtype=bool)
        if quiet is not None and ends is not None:
            self.blind |= quiet & ~flat & _linear(*ends)
        if flat.any() and not self.bends:
            self.bends, self.flat_at = True, t
        if self.bends and ends is not None:
            self.errors.bent(bend_error(*ends, flat))

    def _ends(self, t: float, h: float) -> tuple[np.ndarray, np.ndarray]:
        """What the step taken with every held input at its mean less, then plus half its
        change over the step moves the recorded outputs from the whole step. The blends
        keep the whole step's polynomials for the halves (a held input read from an FMU
        upstream has another end value in these passes)."""
        kept = self._polynomials()
        ends = []
        for point in (0, 1):
            self._restore(t, self.predicted)
            self.holds.point = point
            self._pass(t, h)
            ends.append(self.real[self.errors.slots] - self.errors.whole)
        self.holds.point = None
        self._polynomials(kept)
        return ends[0], ends[1]

    def _polynomials(self, kept: list | None = None) -> list:
        """Every blend's held polynomial of this step (_VarBlend.polynomial), or `kept` set
        back: what the halves hold is the whole step's, whatever other passes held since."""
        return [b.polynomial(k) for b, k in zip(self.holds.blends,
                                                 kept or [None] * len(self.holds.blends))]

    def _pass(self, t: float, h: float) -> None:
        self.counts["passes"] += 1
        one_pass(self.program, t, h)


def bend_error(below: np.ndarray, above: np.ndarray, flat) -> np.ndarray:
    """The step's error (kept - true) from a bend inside the range its held inputs swept,
    per output, from what holding them at their mean less and plus half their change moves
    it (`below`, `above`). On a response linear over that range the two cancel; what is
    left, K = below + above, is the bend's. Where the held mean sits on the flat side of a
    saturation (`flat`, per output), -K/2 (a bound: a bend at a share f of the step from its
    live end errs by f/2 of K, and f is not known); on its live side, f = |K| / (2 x the
    larger of |below| and |above|, the live end's: half the step's live response), and
    -f K / 2 (the flat share's error; a smooth curvature leaves K ~ h^3, and K^2 of it
    nothing)."""
    bend, live = below + above, np.maximum(np.abs(below), np.abs(above))
    share = np.ones(len(bend))
    np.divide(np.abs(bend), 2 * live, out=share, where=(live != 0) & ~np.asarray(flat, bool))
    return -0.5 * bend * np.minimum(share, 1.0)


def _linear(below: np.ndarray, above: np.ndarray) -> np.ndarray:
    """Per output: whether both end passes moved it, by as much either way (to 1e-6 of
    that): a response linear over the range the held inputs swept."""
    live = np.maximum(np.abs(below), np.abs(above))
    return (below != 0.0) & (above != 0.0) & (np.abs(below + above) <= 1e-6 * live)


def _not_controlled(counts: dict) -> str | None:
    """Why the run's estimate is unresolved (every recorded output's), or None: held inputs
    that do not move as smooth curves, or steps taken over jumps no breakpoint announces."""
    if counts.get("not_smooth"):
        return (f"unresolved (the held inputs of {', '.join(counts['not_smooth'])} do not move "
                "as smooth curves between the steps: a staircase on an FMU's own grid, or a "
                "curve faster than the steps, which the steps' error estimates do not see; the "
                "tolerance is not controlled)")
    if counts.get("jumps"):
        found = counts["jumps"]
        return (f"unresolved ({len(found)} steps, the first ending at t = {found[0]:.9g} s, "
                "were taken over a jump that no breakpoint announces, whatever their error: "
                "an FMU's output on a grid of its own, a staircase; the rows near such jumps "
                "may blend the values on either side; the tolerance is not controlled there; "
                "a fixed-step master on a step that divides the FMU's grid holds it exactly)")
    if counts.get("rough_rows"):
        return (f"unresolved ({', '.join(counts['rough_rows'])} did not move as smooth curves "
                "between the steps: a staircase on an FMU's own grid, whose jumps the steps "
                "crossed and the rows between them blend; the tolerance is not controlled; a "
                "fixed-step master on a step that divides the FMU's grid holds it exactly)")
    return None


def estimate_of(names: list[str], results, counts: dict) -> dict:
    """summary.json's error estimate of an adaptive run: the accepted steps' signed errors
    accumulated, per covered output and row: its largest and its last. An end under CANCELS
    of the size of the terms it sums is unresolved (results.cancelled), as the embedded
    pair's: what is left of estimates that cancel (the circle's y end: 0.02 to 0.08 of its
    terms, its number 5x to 9x under the true error at TOL 1e-4 and 1e-2)."""
    why = _not_controlled(counts)
    if why:
        return {name: {"max": why, "end": why} for name in names if name in results.names}
    rows = np.array(counts["estimates"], dtype=float).reshape(len(counts["estimates"]), -1)
    estimate = {}
    for i, name in enumerate(names):
        if name in results.names:
            values = rows[:, i]
            floor = round_off(np.asarray(results[name], dtype=float), counts["steps_taken"])
            estimate[name] = {w: float(v) if v > floor else BELOW_ROUND_OFF
                              for w, v in (("max", values.max()), ("end", values[-1]))}
            if floor < values[-1] < CANCELS * counts["terms"][i]:
                estimate[name]["end"] = cancelled()
    return estimate
