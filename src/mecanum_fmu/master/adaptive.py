"""The adaptive master: a cubic (or the quadratic) hold on a step chosen to meet a tolerance.

Per step, after the pass (docs/masters.md, "The adaptive master"):
- the hold is the mean over the step of the cubic through u_k-2 ... u_k+1 on their own times
  where the third differences of this step and the last agree in sign (a smooth input), else
  the quadratic master's on unequal steps: the parabola through u_k-1, u_k, u_k+1, its second
  difference limited by the previous one (minmod: a kink or a jump in a table adds nothing);
  in a loop the step is predicted with the linear extrapolation, rolled back and corrected;
  after a breakpoint no value from before it enters a hold (two trapezoids first);
- the step's error comes from the pose's twist before and after the step (no extra doStep):
  the cubic's next term, 19/720 h^4 u4 on the mean, u4 (the fourth derivative) from
  the change of the third difference (nothing where the parabola holds: no storm of
  rejections at a kink or a jump), as |u4| for the controller and signed for the estimate;
  the frame turning within the step, J (w dv - dw v) h^2 / 12; a heading error moves every
  later point by J (p - p_t);
- the sum of the accepted steps' errors (|u4|) must stay under the line
  TOL (FLOOR + SLOPE (t - start) / span), and a step's own error under LOCAL x its share
  TOL h / span times the room that sum leaves under the line; a rejected step rolls every FMU
  back (fmi2SetFMUstate) and is retried, shorter;
- the next step comes from a PI controller (exponents 0.7/3 and 0.4/3, ratio clamped to
  [0.5, 2], [0.2, 0.9] after a rejection), never longer than the output interval; the last
  step is kept unless the controller wants GROW x it or less than it; steps land on the
  output grid (every step_size seconds: results.csv's rows) and on the breakpoints of the
  VelocitySources' tables and segments (Stops: a jump gets a step of 1e-6 h_out before it).
The signed sum of the accepted steps' errors (u4 signed, plus the first two steps' trapezoids
and each jump's own step) is the run's error estimate.
"""
from __future__ import annotations

import bisect
import math
import time as _time
from typing import Callable

import numpy as np

from ..graph import Instance, Port
from ..models.catalog import bundled_model
from ..results import BELOW_ROUND_OFF, round_off
from .breakpoints import graph_breaks
from .instance import RunningInstance
from .plan import Holds
from .recorder import Recorder
from .stepping import NonFinite, _one_pass, _state_call

_TWIST = ("vx", "vy", "w")
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


def _minmod(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.where(a * b > 0, np.sign(a) * np.minimum(np.abs(a), np.abs(b)), 0.0)


class AdaptiveHolds(Holds):
    """Holds over unequal steps: h (this step), g and f (the two before)."""

    def __init__(self):
        super().__init__("quadratic")
        self.h = self.g = self.f = 1.0
        self.poses: list["PoseError"] = []     # per PoseIntegrator: its vx, vy, w
        self.since = None       # committed steps since the last breakpoint (None: none yet)
        self.jump_next = False  # the next step ends on a jump (it started JUMP before it)

    @property
    def history(self) -> int:
        """The committed steps whose values the holds may use: none from before the last
        breakpoint (a table's corner or jump), where the input is another polynomial."""
        return self.steps if self.since is None else min(self.steps, self.since)

    def at_breakpoint(self, before_jump: bool) -> None:
        self.since, self.jump_next = 0, before_jump

    def add(self, buffer, src, roles, targets: list[Port], inst: Instance) -> "_VarBlend":
        blend = _VarBlend(self, buffer, src, roles)
        self.blends.append(blend)
        self.ahead = self.ahead or any(role != "state" for role in roles)
        model = bundled_model(inst.model)
        names = [t.ref.variable for t in targets]
        if model is not None and model.role == "pose" and all(n in names for n in _TWIST):
            self.poses.append(PoseError(blend, [names.index(n) for n in _TWIST], inst))
        return blend

    def prime(self) -> None:
        super().prime()
        for b in self.blends:
            b.third_before[:] = 0.0

    def commit(self) -> None:
        for b in self.blends:
            b.third_before[:] = b.third
        super().commit()
        self.f, self.g = self.g, self.h
        if self.since is not None:
            self.since += 1
        self.jump_next = False


class _VarBlend:
    """One group of blended inputs: history [now | u_k | u_k-1 | u_k-2] and its roles."""

    def __init__(self, holds: AdaptiveHolds, buffer: np.ndarray, src: np.ndarray, roles: list):
        m = len(src)
        self.holds, self.buffer, self.src = holds, buffer, src
        self.staging = np.zeros(m)
        self.history = np.zeros(4 * m)
        self.rows = self.history.reshape(4, m)          # views: now, u_k, u_k-1, u_k-2
        self.older, self.old = self.history[2 * m:], self.history[m:3 * m]
        roles = np.array(roles)
        self.ahead, self.fed = roles == "state_ahead", roles == "fed_back"
        self.third = np.zeros(m)          # u''' over this step (limited in error())
        self.third_before = np.zeros(m)

    def fill(self) -> None:
        np.take(self.buffer, self.src, out=self.rows[0])
        now, u, u1, _ = self.rows
        hs = self.holds
        h, g = hs.h, hs.g
        mean = 0.5 * (now + u)
        if hs.history >= 2:
            # the parabola's correction to the trapezoid, its second difference limited
            second = self._second()
            correction = _minmod(second, 2 * self._second_before()) * h * h / 12
            if hs.history >= 3:     # the cubic's where the third differences agree in sign
                third = self._third()
                cubic = second * h * h / 12 + third * h * h * (h + 2 * g) / 72
                correction = np.where(third * self.third_before > 0, cubic, correction)
            mean = mean - correction
        if hs.mode == hs.PREDICT:
            slope = (u - u1) / g
            self.staging[:] = np.where(self.ahead, u + slope * h / 2,
                                       np.where(self.fed, u + slope * h, mean))
        else:
            self.staging[:] = np.where(self.fed, now, mean)

    def _second(self) -> np.ndarray:
        """u'', 2x the second divided difference over u_k-1, u_k, u_k+1."""
        now, u, u1, _ = self.rows
        h, g = self.holds.h, self.holds.g
        return 2 * ((now - u) / h + (u1 - u) / g) / (h + g)

    def _second_before(self) -> np.ndarray:
        """The second divided difference over u_k-2, u_k-1, u_k."""
        _, u, u1, u2 = self.rows
        g, f = self.holds.g, self.holds.f
        return ((u - u1) / g - (u1 - u2) / f) / (g + f)

    def _third(self) -> np.ndarray:
        """u''', 6x the third divided difference over u_k-2 ... u_k+1."""
        h, g, f = self.holds.h, self.holds.g, self.holds.f
        return 6 * (0.5 * self._second() - self._second_before()) / (h + g + f)

    def error(self) -> tuple[np.ndarray, np.ndarray]:
        """The signed error of this step's held mean (held - true), per input, (for the
        controller, for the estimate): where the hold is the cubic (the third differences
        agree in sign), its next term 19/720 h^4 u4 (uniform steps' form: the cubic through
        four points, its mean over the last interval; u4 the change of the third difference)
        for both; on the first steps none for the controller (they are short) and the
        trapezoids' for the estimate; elsewhere (the limited parabola where a kink or a jump
        sits among the last four values, or u3 crosses zero) nothing."""
        hs = self.holds
        h, f = hs.h, hs.f
        self.third[:] = self._third()
        if hs.jump_next:       # held - true = (new - old) / 2 on the mean: the jump's own
            now, u, _, _ = self.rows
            return np.zeros_like(self.third), 0.5 * (now - u)
        if hs.history < 3:     # no history yet: the step is kept short instead (first_step)
            return np.zeros_like(self.third), self._start_up()
        smooth = self.third * self.third_before > 0
        fourth = 2 * (self.third - self.third_before) / (h + f)
        signed = np.where(smooth, 19 / 720 * h ** 4 * fourth, 0.0)
        return signed, signed

    def _start_up(self) -> np.ndarray:
        """The signed error of the first two steps' held means, told at the second step (the
        first with a second difference): each a trapezoid, held - true = h^2 u'' / 12, the
        first step's (g long) carried on this step's mean as g^3 / h u'' / 12."""
        if self.holds.steps != 1:
            return np.zeros_like(self.third)
        h, g = self.holds.h, self.holds.g
        return self._second() * (h * h + g ** 3 / h) / 12

    def commit(self) -> None:
        self.older[:] = self.old
        np.take(self.buffer, self.src, out=self.rows[1])


class PoseError:
    """The signed error of one pose, accumulated over the accepted steps: the body-frame
    errors of each step turned into the world frame (heading and position tracked from the
    held twist), and the heading's errors carried along the path travelled since."""

    def __init__(self, blend: "_VarBlend", index: list[int], inst: Instance):
        self.blend, self.index, self.name = blend, index, inst.name
        self.theta = float(inst.value("theta0"))
        self.p = np.zeros(2)
        # per sum: position errors made on the steps (world frame), the heading errors and
        # the sum of p_t * heading error_t; [0] with the cubic's term as a bound (|u4|: the
        # controller's), [1] signed (the run's estimate: errors that cancel do)
        self.e = np.zeros((2, 2))
        self.heading = np.zeros(2)
        self.moment = np.zeros((2, 2))

    def step(self, h: float, left: float) -> tuple[float, float, tuple]:
        """(position error bound, |heading error|) of this step for the controller, and the
        signed update to apply if the step is accepted."""
        e, signed = self.blend.error()
        ivx, ivy, iw = self.index
        now, u, mean = self.blend.rows[0], self.blend.rows[1], self.blend.staging
        vx, vy, w = mean[ivx], mean[ivy], mean[iw]
        dvx, dvy, dw = now[ivx] - u[ivx], now[ivy] - u[ivy], now[iw] - u[iw]
        # held minus true: the cubic's term (the third derivative's, h^4/24 over the step)
        # and the frame turning within the step, -J (w dv - dw v) h^2 / 12 (docs/masters.md)
        tx, ty = (w * dvx - dw * vx) * h * h / 12, (w * dvy - dw * vy) * h * h / 12
        body = np.array([(h * abs(e[ivx]) + ty, h * abs(e[ivy]) - tx),
                         (h * signed[ivx] + ty, h * signed[ivy] - tx)])
        e_theta = np.array([h * abs(e[iw]), h * signed[iw]])
        bound = math.hypot(*body[0]) + e_theta[0] * math.hypot(vx, vy) * left
        return bound, float(e_theta[0]), (body, e_theta, (vx, vy, w))

    def after(self, h: float, update: tuple) -> float:
        """The largest |error| of x, y, theta if the step were accepted."""
        saved = (self.theta, self.p.copy(), self.e.copy(), self.heading.copy(),
                 self.moment.copy())
        self.accept(h, update)
        worst = max(self.now())
        self.theta, self.p, self.e, self.heading, self.moment = saved
        return worst

    def accept(self, h: float, update: tuple) -> None:
        body, e_theta, (vx, vy, w) = update
        c, s = math.cos(self.theta), math.sin(self.theta)
        self.e += np.column_stack((c * body[:, 0] - s * body[:, 1],
                                   s * body[:, 0] + c * body[:, 1]))
        self.p += (h * (c * vx - s * vy), h * (s * vx + c * vy))
        self.theta += h * w
        self.heading += e_theta
        self.moment += np.outer(e_theta, self.p)

    def now(self, signed: bool = False) -> tuple[float, float, float]:
        """|error| of x, y, theta now (the bound, or `signed`: the estimate): the steps' own,
        plus J (p S - sum p_t e_t) of the heading errors (a heading error e_t at p_t moves
        every later point by J (p - p_t))."""
        k = int(signed)
        carried = self.p * self.heading[k] - self.moment[k]
        return (abs(self.e[k, 0] - carried[1]), abs(self.e[k, 1] + carried[0]),
                abs(self.heading[k]))


def step_error(holds: AdaptiveHolds, left: float) -> tuple[float, float, list]:
    """(position error bound in m, heading error in rad) of the step just taken, the worst
    over every pose, and the signed updates."""
    position = heading = 0.0
    updates = []
    for pose in holds.poses:
        bound, e_theta, update = pose.step(holds.h, left)
        position, heading = max(position, bound), max(heading, e_theta)
        updates.append(update)
    for blend in holds.blends:      # inputs of other FMUs: their third differences move on
        if all(blend is not pose.blend for pose in holds.poses):
            blend.error()
    return position, heading, updates


class Stops:
    """The times a step must end on besides the output grid: the breakpoints of the bundled
    VelocitySources' tables (segments are hold tables). A kink (linear) is one stop; a jump
    (hold) two: JUMP x the output interval before it, then on it, so that the step that sees
    the new value at its end is that short (the hold's mean blends the two values: the jump
    costs the step before it h |jump| / 2, under every hold, whatever the tolerance). A stop
    is a breakpoint for the holds too (AdaptiveHolds.at_breakpoint)."""

    JUMP = 1e-6

    def __init__(self, graph, start: float, stop: float, interval: float):
        breaks = graph_breaks(graph)
        before = breaks.jumps - self.JUMP * interval
        times = [float(x) for x in (*breaks.kinks, *breaks.jumps, *before)]
        near = 1e-9 * interval
        self.times = sorted(x for x in set(times) if start + near < x < stop - near)
        self.before = sorted(float(x) for x in before)
        self.near, self.i = near, 0

    def on(self, t: float, times: list[float] | None = None) -> bool:
        """Whether t is one of the stops (or of `times`)."""
        times = self.times if times is None else times
        i = bisect.bisect_left(times, t - self.near)
        return i < len(times) and times[i] <= t + self.near

    def before_jump(self, t: float) -> bool:
        """Whether t is the stop just before a jump: the next step is the jump's own."""
        return self.on(t, self.before)

    def next(self, t: float, target: float) -> float:
        """The first stop after t, or target when none comes before it."""
        while self.i < len(self.times) and self.times[self.i] <= t + self.near:
            self.i += 1
        if self.i < len(self.times) and self.times[self.i] < target - self.near:
            return self.times[self.i]
        return target


class Controller:
    """The step: PI on the error ratio, clamped, cut to land on the next stop."""

    def __init__(self, tolerance: float, span: float, first: float, longest: float):
        self.tolerance, self.span, self.longest = tolerance, span, longest
        self.wanted, self.ratio_before, self.last = first, 1.0, 0.0
        self.drift = 0.0      # the accumulated error so far (PoseError.now, the worst)

    def ratios(self, position: float, heading: float, h: float, drift: float,
               elapsed: float) -> tuple[float, float]:
        """(the step's own error against its allowance, for the PI; over 1: reject). The
        allowance is LOCAL x its share TOL h / span, times the room the accumulated error
        leaves under the line TOL (FLOOR + SLOPE elapsed / span) (at least MIN_ROOM: the line
        grows faster than the steps then add); the accumulated error after the step must
        stay under the line too."""
        line = self.tolerance * (FLOOR + SLOPE * (elapsed - h) / self.span)
        room = max(MIN_ROOM, 1.0 - self.drift / line)
        own = max(position, heading) / (LOCAL * room * self.tolerance * h / self.span)
        line += self.tolerance * SLOPE * h / self.span
        return own, max(own, drift / line)

    def accept(self, ratio: float, h: float, drift: float) -> None:
        r = max(ratio, 1e-10)
        factor = SAFETY * r ** -K_I * self.ratio_before ** K_P
        # never more than GROW x the output interval (a long quiet stretch must not leave a step
        # that takes many rejections to come down when the input turns), nor than the step
        # the error model (ratio ~ h^3) allows: no step that is sure to be rejected
        self.wanted = min(self.wanted * min(2.0, max(0.5, factor)), GROW * self.longest,
                          h * r ** (-1 / 3))
        self.ratio_before, self.drift, self.last = r, drift, h

    def reject(self, ratio: float, h: float) -> None:
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


def first_step(tolerance: float, interval: float) -> float:
    """The first steps have no history for the error estimate: short (the trapezoid's error
    then is h^3 |u''| / 12 per step, below the tolerance for any smooth input of size ~1)."""
    return interval * min(1.0, tolerance ** (1 / 3))


def step_adaptive(running: list[RunningInstance], recorder: Recorder, ctrl_c: list[int],
                  progress: Callable[[float], None] | None, holds: AdaptiveHolds,
                  tolerance: float, counts: dict) -> None:
    """The adaptive loop: rows recorded on the output grid only. counts gets steps_taken,
    steps_rejected and the accumulated error estimate. Raises StepFailure, NonFinite,
    KeyboardInterrupt."""
    exp = recorder.experiment
    start, stop, interval = exp.start_time, exp.stop_time, exp.step_size
    program = [(r, r.component, r.c_do_step, r.writes, r.reads) for r in running]
    control = Controller(tolerance, stop - start, first_step(tolerance, interval), interval)
    stops = Stops(recorder.graph, start, stop, interval)
    real, ints = recorder.buffers.real, recorder.buffers.int
    saved_real, saved_int = real.copy(), ints.copy()    # the values at t_k, for a retry
    t, j = start, 0
    next_report = _time.perf_counter() + 1.0
    while j < recorder.n_steps:
        target = stop if j == recorder.n_steps - 1 else start + (j + 1) * interval
        goal = stops.next(t, target)
        _save(running, t)
        saved_real[:], saved_int[:] = real, ints
        h, updates, (ratio, drift) = _take(running, program, holds, control,
                                           (start, t, goal, stop),
                                           ctrl_c, counts, (real, ints, saved_real, saved_int))
        _free(running, t)
        holds.commit()
        counts["steps_taken"] += 1
        for pose, update in zip(holds.poses, updates):
            pose.accept(h, update)
        if h >= 0.1 * min(control.wanted, interval):   # not cut short by a stop: a step
            control.accept(ratio, h, drift)             # of 1e-6 h_out says nothing of the next
        else:
            control.drift = drift
        if not np.isfinite(real).all():
            raise NonFinite(t + h)
        t = t + h
        if abs(t - target) <= 1e-9 * interval:
            t, j = target, j + 1
            recorder.record()
            counts["estimates"].append([pose.now(signed=True) for pose in holds.poses])
            if progress is not None and _time.perf_counter() >= next_report:
                progress((t - start) / (stop - start))
                next_report = _time.perf_counter() + 0.5
        elif abs(t - goal) <= 1e-9 * interval:
            t = goal
        if stops.on(t):
            holds.at_breakpoint(stops.before_jump(t))


def _take(running, program, holds: AdaptiveHolds, control: Controller, times: tuple,
          ctrl_c, counts: dict, values: tuple) -> tuple[float, list, float]:
    """One accepted step from t towards `goal` (times: start, t, goal, stop): tried, rejected
    and rolled back (the FMUs and the values) until its error ratio is at most 1.
    (h, the poses' updates, the ratio)."""
    start, t, goal, stop = times
    real, ints, saved_real, saved_int = values
    span = stop - start
    h = control.step_to(t, goal)
    while True:
        if ctrl_c[0]:
            raise KeyboardInterrupt
        _attempt(running, program, holds, t, h)
        position, heading, updates = step_error(holds, stop - t - h)
        drift = max([pose.after(h, u) for pose, u in zip(holds.poses, updates)])
        ratio, worst = control.ratios(position, heading, h, drift, t + h - start)
        if worst <= 1.0 or h <= 1e-12 * span:
            return h, updates, (ratio, drift)
        counts["steps_rejected"] += 1
        control.reject(worst, h)
        h = control.step_to(t, goal)
        _restore(running, t)
        real[:], ints[:] = saved_real, saved_int


def _attempt(running, program, holds: AdaptiveHolds, t: float, h: float) -> None:
    """One pass at step h (in a loop: predicted, rolled back, corrected)."""
    holds.h = h
    if holds.ahead:
        holds.mode = holds.PREDICT
        _one_pass(program, t, h)
        _restore(running, t)
        holds.mode = holds.CORRECT
    _one_pass(program, t, h)


def _save(running: list[RunningInstance], t: float) -> None:
    for r in running:
        _state_call(r, "fmi2GetFMUstate", r.c_get_state(r.component, r.state_ref), t)


def _restore(running: list[RunningInstance], t: float) -> None:
    for r in running:
        _state_call(r, "fmi2SetFMUstate", r.c_set_state(r.component, r.state), t)


def _free(running: list[RunningInstance], t: float) -> None:
    for r in running:
        _state_call(r, "fmi2FreeFMUstate", r.c_free_state(r.component, r.state_ref), t)


def estimate_of(graph, results, counts: dict, holds: AdaptiveHolds) -> dict:
    """summary.json's error estimate of an adaptive run: the accepted steps' signed errors
    accumulated (PoseError), per output row: its largest and its last."""
    rows = np.array(counts["estimates"])        # (row, pose, x/y/theta)
    estimate = {}
    for i, pose in enumerate(holds.poses):
        for column, k in enumerate(("x", "y", "theta")):
            name = f"{pose.name}.{k}"
            if name in results.names:
                values = rows[:, i, column]
                floor = round_off(np.asarray(results[name], dtype=float),
                                  counts["steps_taken"])
                estimate[name] = {w: float(v) if v > floor else BELOW_ROUND_OFF
                                  for w, v in (("max", values.max()), ("end", values[-1]))}
    return estimate
