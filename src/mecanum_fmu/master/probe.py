"""The embedded pair's error model of an FMU with a state and no model of its own: its response
to a held input's error, measured on the FMU itself (docs/masters.md, "The measured response").

Before the master steps the FMU at a probed step k, its state is saved, and it is stepped
PROBE_STEPS times from there with the inputs of now (u_k: the sources' values at t_k), then,
per held input j, the same with u_j moved by a small eps over the first step only; its state
is set back. Per output o whose dependencies are declared and input j, the differences over
eps are the response to a unit held over one step, at the end of that step and of the next
three: g0, g1, g2, g3 (where j reaches o directly, g0's state part is g1 / r and the rest a
direct part: ProbedModel). The model is one pole and a direct part, which fits g0,
g1 and g2 exactly: g_n = g1 r^(n-1) for n >= 1, r = g2 / g1 (a first-order FMU, x' = a x + b u,
has g1 = r g0, r = e^(a h)). g3 checks it: a response of higher order (two integrators in a
row, a mass on a spring) does not decay geometrically. The model's first probe is then made
again over ORDER2_STEPS steps, and up to two poles per output and input fit g1 .. g5
(probe_fit.py; its later probes take as many steps); where neither fits (three integrators),
the pair hands over to Richardson rather than carry a wrong pole over the run. Per step the
pair's errors are carried (probed_model.py) as
    d_k = error_k - m change_k,    y_k = s_k + g0 d_k,    s_k+1 = r s_k + g1 d_k,
summed over the inputs: error, the held value against the true mean; change, the true input's
change over the step, whose weight within the step a mean does not see (m: moment(), about
-a h / 12, exact for the first-order part; less 6 b bend, the parabola's part: probe_fit.bend).
A part of g0 that no pole carries on (a mode gone within the step: a stiff lag, the fast pole
of a spring with poles -1 and -100) is measured over two steps of h / SUBSTEPS (_faster).

A probe costs (1 + m) PROBE_STEPS doStep calls of that FMU (ORDER2_STEPS for two poles, and
once the 4 that found one does not fit) and 1 + m state sets. The first is
made at the first step; the next PROBE_EVERY steps later, and each time a probe finds what the
one before it found (within AGREE), the gap grows GROWTH-fold: a linear FMU is probed about
log4(n / 32) + 2 times, a nonlinear one as often as its response changes. The Jacobian of an
FMU without a state that a loop's error goes through (ProbedResponse) is probed alike, one
step per input.
"""
from __future__ import annotations

import ctypes
import time as _time

import numpy as np

from .plan import has_state
from .probe_fit import (ORDER2_STEPS, PROBE_STEPS, SUBSTEPS, Higher, direct_fast, fast_moments,
                        fast_part, fitted, lazy, within_step)
from .probed_model import REAL, ProbedModel, probeable
from .stepping import StepFailure, restore_states

PROBE_EVERY = 32
RELATIVE_EPS = 1e-6
AGREE = 0.05            # relative: two probes that agree this well widen the gap
GROWTH = 4              # by this factor (a linear FMU: log4 of the run's length probes)
PROBED = ", its response measured by probes"
_EPS = float(np.finfo(float).eps)


def _slow(found: tuple) -> list[tuple[np.ndarray, np.ndarray]]:
    """A probe's poles with their parts of g0, (W, z) each: one pole, g1 / r (0 where r is
    0); two, each mode's c / z."""
    g1, r = found[3], found[4]
    if len(found) > 7:
        z, c = found[7][0], found[7][1]
        return [(within_step(z[i], c[i]), z[i]) for i in range(2)]
    return [(np.where(r != 0.0, g1 / np.where(r != 0.0, r, 1.0), 0.0), r)]


def _lost(before: np.ndarray, now: np.ndarray) -> tuple[int, int] | None:
    """(output, input) whose g1 an earlier probe measured and this one finds below round-off
    (fitted zeroes it), else None. Its ratio r is then unknown, not 0: an FMU whose output
    grows by itself (x' = 80 x + u) carries an earlier error on, while a perturbation of
    its input vanishes against the output's size."""
    gone = np.argwhere((before != 0.0) & (now == 0.0))
    return (int(gone[0][0]), int(gone[0][1])) if len(gone) else None


_DEAF = ("{}'s outputs did not move with its input {} in the probe at t = {:g} s (an input "
         "that saturates there, or that it does not read): the pair cannot tell how they "
         "follow it where it moves")


def _deaf(g: np.ndarray, floor: np.ndarray) -> int | None:
    """The first input that moved no output above its round-off at any step of a probe (g:
    (steps, outputs, inputs), floor the same), else None. A lag whose input saturates at
    0.5, fed cos t, was probed at t0 and 3.2 s, saturated both times: its model said it does
    not respond, and the estimate read "below round-off" for an error of 9.4e-4."""
    moved = (np.abs(g) > floor).any(axis=(0, 1))
    return int(np.argmin(moved)) if not moved.all() else None


def _agree(a: tuple, b: tuple, horizon: int = 0) -> bool:
    """Whether two probes found the same (g0, g1 and r; with two poles, the responses g1 ..
    g5 their modes make, each within AGREE of its largest; a response's Jacobian) within
    AGREE. Two poles' z and c are not compared: a repeated pole split (probe_fit.SPLIT)
    has shares of 1 / SPLIT that cancel, and round-off moves them by more than 5%. One
    pole's r is compared as its rate, ln r, within AGREE or within AGREE / `horizon` (the
    steps the probe would then serve: its decay over them within AGREE): r near 1 hides a
    rate that changes. A lag whose rate is 1 + 4 sin^2 t at 0.01 s found r 0.990 at t0 and
    0.988 at 0.2 s, rates 18% apart, the gap grew to 256 steps, and the estimate read 2.2x
    its error."""
    first = len(a) == 7         # one pole: r as a rate; two: as a value, their responses
    x, y = (np.concatenate([np.ravel(v) for v in p[2:4 if first else 5]]) for p in (a, b))
    if not (np.abs(x - y) <= AGREE * np.abs(y) + 1e-300).all():
        return False
    if first and not _same_rate(np.ravel(a[4]), np.ravel(b[4]), horizon):
        return False
    if len(a) <= 7:
        return True
    made, other = (_responses(p[7]) for p in (a, b))
    return bool((np.abs(made - other) <= AGREE * np.abs(other).max(axis=0) + 1e-300).all())


def _same_rate(r: np.ndarray, other: np.ndarray, horizon: int) -> bool:
    """_agree's check of two probes' r: their rates ln r within AGREE of the other's, or
    within AGREE / horizon; r not positive (a rate unknown, a sign that flips) as values."""
    positive = (r > 0) & (other > 0)
    rate, rate_b = (np.log(np.where(positive, v, 1.0)) for v in (r, other))
    loose = AGREE / horizon if horizon else 0.0
    return bool(np.where(positive, np.abs(rate - rate_b) <= np.maximum(
        AGREE * np.abs(rate_b), loose) + 1e-300,
        np.abs(r - other) <= AGREE * np.abs(other) + 1e-300).all())


def _responses(modes: tuple) -> np.ndarray:
    """g1 .. g5 of two poles' modes (z, c, m: each (2, outputs, inputs)), sum c z^(n-1)."""
    z, c = modes[0], modes[1]
    powers = np.arange(ORDER2_STEPS - 1)[:, None, None, None]
    return (c[None] * z[None] ** powers).sum(axis=1).real


class Prober:
    """Measures the ProbedModels' responses in the run's own instances: step_all calls it
    before each step in `at`, which it extends as it goes."""

    def __init__(self, targets: list["Target"], real: np.ndarray, n_steps: int):
        self.targets, self.real = targets, real
        self.last = n_steps - 1 - PROBE_STEPS        # the last step a probe starts at
        self.at = {0} if self.last >= 0 else set()
        self.gap = PROBE_EVERY
        self.seconds = 0.0      # inside the run's stepping time: the estimate's, not the run's
        self.calls = 0          # the probes' doStep calls

    def __call__(self, k: int, t: float, h: float) -> None:
        tick = _time.perf_counter()
        same, changed = True, False
        for target in self.targets:
            if target.model.failed is None:
                before = target.model.found[-1] if target.model.found else None
                room = self.last + PROBE_STEPS - k     # the steps after t_k
                if target.steps > room:
                    continue        # (a probe of two poles' steps would run past the end)
                calls = target.calls
                target.probe(k, t, h, self.real, room)
                self.calls += target.calls - calls
                now = target.model.found[-1] if target.model.found else None
                agree = before is not None and now is not before and _agree(
                    now, before, GROWTH * self.gap)
                same = same and agree
                changed = changed or (before is not None and now is not before and not agree)
        self.gap = GROWTH * self.gap if same else PROBE_EVERY
        self.at.discard(k)
        if k + self.gap <= self.last:
            self.at.add(k + self.gap)
        elif (end := max(self._last_two_pole(), self.last if changed else -1)) > k:
            self.at.add(end)    # a response that changes: probed again at the end
        self.seconds += _time.perf_counter() - tick

    def _last_two_pole(self) -> int:
        """The last step a probe of two poles may start at, where some model has them, has
        not failed and has been probed once; else -1. The gap past the run's end, the
        probes check there that the poles stay (two poles change along a nonlinear FMU's
        run, and the pair hands over: Target._fit): a run too short for a second probe took
        one alone, and a Van der Pol oscillator's estimate read 0.07x to 0.47x of its error
        at 30 steps."""
        if not any(t.steps == ORDER2_STEPS and t.model.failed is None and
                   len(t.model.found) == 1 for t in self.targets):
            return -1
        return self.last + PROBE_STEPS - ORDER2_STEPS


def prober(plan, running: list, real: np.ndarray, n_steps: int) -> Prober | None:
    """The Prober of the pair's measured models (its groups whose model is a ProbedModel)
    and measured responses (the Throughs of its loop or network whose response is a
    ProbedResponse); None where there are none. `real`: the run's buffers (plan.slots: the
    buffer slot of each of the pair's columns)."""
    by_name = {r.name: r for r in running}
    targets = []
    for g in plan.groups:
        if isinstance(g.model, ProbedModel) and g.model.outputs:
            targets.append(Target(by_name[g.name], g.model, g.model.inputs, g.model.outputs,
                                  plan.slots[g.cols]))
    for t in plan.throughs():
        if isinstance(t.response, ProbedResponse):
            targets.append(Target(by_name[t.name], t.response, t.response.inputs,
                                  t.response.outputs, plan.slots[t.ins], t.response.steps))
    return Prober(targets, real, n_steps) if targets else None


def probed_response(inputs: list[str], inst) -> "ProbedResponse | None":
    """The response (models/responses.Response's interface: outputs, divides, jacobian) of a
    third-party FMU without a state, measured by probes, its linked inputs `inputs`; None
    where it cannot be probed (probeable). Each probe checks it for a state (steps 2): one
    that may hold one (its dependencies not declared, and the probes before the run found
    none: memory.py), and one whose every output declares inputs only, which FMI 2.0 does
    not make free of a state (a PI controller, u = kp e + i, declares u: [r, y])."""
    if not probeable(inst):
        return None
    outputs = [u.variable.name for u in inst.model.outputs if u.variable.type in REAL]
    response = ProbedResponse(inst.name, inputs, outputs, 2)
    response.declared = not has_state(inst)
    return response


class ProbedResponse:
    """The Jacobian of an FMU without a state's Real outputs in its linked inputs, as its
    last probe measured it (a Target of one step: the outputs after one step from a saved
    state with each input moved, over the move). Per probe, in `found`: (its step, its step
    size, J (outputs x inputs)). `steps` 2: one that may hold a state (its dependencies not
    declared) is stepped once more, and an output that keeps a trace of the move marks it
    failed."""

    def __init__(self, name: str, inputs: list[str], outputs: list[str], steps: int = 1):
        self.name, self.inputs, self.outputs, self.steps = name, inputs, outputs, steps
        self.moved = self.trace = np.zeros(len(outputs), dtype=bool)    # steps 2: per output
        self.declared = False   # every output declares its dependencies (probed_response)
        self.divides: dict = {}
        self.found: list[tuple] = []
        self.failed: str | None = None
        self.deaf = False   # failed as an input moved no output in a probe (_DEAF)

    def jacobian(self, ins: np.ndarray, outs: np.ndarray) -> np.ndarray:
        j = self.found[-1][2] if self.found else np.zeros((len(self.outputs),
                                                            len(self.inputs)))
        return np.broadcast_to(j, (len(ins), *j.shape))


class Target:
    """One probed FMU: its running instance, its model, and the value references of its held
    inputs and covered outputs, with the buffer slots of the inputs' sources."""

    def __init__(self, running, model, inputs: list[str], outputs: list[str],
                 slots: np.ndarray, steps: int = PROBE_STEPS):
        self.r, self.model, self.slots, self.steps = running, model, slots, steps
        vrs = {v.name: v.valueReference for v in running.inst.model.modelVariables}
        self.in_vrs = (ctypes.c_uint * len(inputs))(*(vrs[n] for n in inputs))
        self.out_vrs = (ctypes.c_uint * len(outputs))(*(vrs[n] for n in outputs))
        self.u = (ctypes.c_double * len(inputs))()
        self.y = (ctypes.c_double * len(outputs))()
        self.calls = 0      # the doStep calls of its probes

    def probe(self, k: int, t: float, h: float, real: np.ndarray, room: int = 0) -> None:
        """One probe from the FMU's state now (t_k), the state set back after it. A call
        that returns Discard, or a response the model does not fit, marks the model failed
        (the pair hands over to Richardson); Error or worse, or a state that cannot be set
        back, fails the run (StepFailure: FMI allows nothing more of such an instance).
        A model's first probe whose response one pole does not fit is made again with
        ORDER2_STEPS steps, where `room` (the steps after t_k the run still takes) has
        them: two poles may fit it (probe_fit), and its later probes take as many."""
        r, comp = self.r, self.r.component
        u = real[self.slots].astype(float)
        eps = RELATIVE_EPS * np.maximum(1.0, np.abs(u))
        state = ctypes.c_void_p()
        status = r.c_get_state(comp, ctypes.byref(state))
        if status > 1:
            if status > 2:
                raise StepFailure(r, "fmi2GetFMUstate", status, t, t)
            self.model.failed = f"{r.name}'s fmi2GetFMUstate returned discard while probing it"
            return
        # a model's outputs' change over each input's move set after the first step (_after)
        after = np.zeros((len(self.y), len(u))) if isinstance(self.model, ProbedModel) \
            else None
        try:
            runs = self._moves(u, t, h, eps, state, (after, eps) if after is not None else None)
        except _Refused as why:
            self._refused(why, t, h)
        restore_states([r], t, [state])
        try:
            higher = self.model.failed is None and self._fit(k, h, np.array(runs), eps, after)
            if self.model.failed is None and (fast := self._fast(k)).any():
                self._faster(fast, t, h, u, eps, state)
        finally:
            r.c_free_state(comp, ctypes.byref(state))
        if higher and room >= ORDER2_STEPS:
            self.model.failed, self.steps = None, ORDER2_STEPS
            self.probe(k, t, h, real)

    def _fast(self, k: int) -> np.ndarray:
        """(outputs, inputs): the part of this step's probe's g0 that its poles do not carry
        on (probe_fit.fast_part: a faster mode's, whose moment theirs is not); zeros where
        there is none. A lag x' = -100 x + u at 0.2 s, g1 e^-20 g0, below round-off: r read
        0 and its moment 0 where it is 0.45, and the estimate read 0.04x its error under the
        quadratic master, 10x under Gauss-Seidel; two poles dropped that part."""
        found = self.model.found[-1] if isinstance(self.model, ProbedModel) and \
            self.model.found else None
        if found is None or found[0] != k:
            return np.zeros(0)
        return found[5].fast + fast_part(found[2], sum(w for w, _ in _slow(found)).real,
                                         self.model.direct)     # (direct_fast's, the rest)

    def _faster(self, fast: np.ndarray, t: float, h: float, u: np.ndarray, eps: np.ndarray,
                state) -> None:
        """The probe's `fast` parts and their moments, from two steps of h / SUBSTEPS from
        the saved `state` (probe_fit.fast_moments), where the FMU takes them (_substeps);
        the probe before's where it found the same parts (within AGREE): no substeps."""
        found = self.model.found[-1]
        if len(self.model.found) > 1 and (last := self.model.found[-2][5]).fast.any() and \
                (np.abs(fast - last.fast) <= AGREE * np.abs(last.fast)).all():
            m = found[5]._replace(fast=last.fast, quick=last.quick, quick_bent=last.quick_bent)
            self.model.found[-1] = (*found[:5], m, *found[6:])
            return
        runs = self._substeps(t, h, u, eps, state)
        if runs is None:
            return
        sub, floor = _gains(runs, eps)
        floor = floor.max(axis=0)
        # (a direct part moved the first substep's end)
        fit = fast_moments(sub - np.stack((found[6], 0 * found[6])), floor, _slow(found), fast,
                           found[2] + found[6])
        if isinstance(fit, str):
            self.model.failed = (f"{self.r.name}'s response {fit} (probed at t = "
                                 f"{found[0] * h:g} s)")
        else:
            m = found[5]._replace(fast=fit[0], quick=fit[1], quick_bent=fit[2])
            self.model.found[-1] = (*found[:5], m, *found[6:])

    def _substeps(self, t: float, h: float, u: np.ndarray, eps: np.ndarray, state
                  ) -> np.ndarray | None:
        """The outputs after two steps of h / SUBSTEPS from the saved `state`, unmoved and
        each input moved over the first, (1 + inputs, 2, outputs); the state set back after.
        None, the model marked failed, where the FMU says it cannot step shorter
        (canHandleVariableCommunicationStepSize false) or a substep returns Discard
        (_refused: Error or worse fails the run, naming the substep)."""
        if not self.r.inst.can_vary_step:
            self.model.failed = (f"{self.r.name}'s response has a part faster than the step, "
                                 "and it cannot step shorter for the probes to measure it "
                                 "(canHandleVariableCommunicationStepSize false)")
            return None
        steps, self.steps = self.steps, 2
        try:
            runs = self._moves(u, t, h / SUBSTEPS, eps, state)
        except _Refused as why:
            self._refused(why, t, h, f" over a step of h/{SUBSTEPS}")
            return None
        finally:
            self.steps = steps
            restore_states([self.r], t, [state])
        return np.array(runs)

    def _moves(self, u: np.ndarray, t: float, h: float, eps: np.ndarray, state,
               after: tuple | None = None) -> list:
        """The covered outputs after each of self.steps steps of h from the saved `state`,
        unmoved (with `after`: _steps'), then per input with it moved by eps over the first,
        the state set back before each. Raises _Refused."""
        runs = [self._steps(u, t, h, after=after)]
        for j in range(len(u)):
            restore_states([self.r], t, [state])
            runs.append(self._steps(u, t, h, _moved(u, j, eps)))
        return runs

    def _refused(self, why: "_Refused", t: float, h: float, steps: str = "") -> None:
        """A probe's call that returned Discard marks the model failed (the caller sets the
        saved state back); Error or Fatal fails the run (StepFailure: FMI allows nothing
        more of that instance, and pythonfmu's crashed the process on the next call),
        naming the probe's `steps` where they are not the run's."""
        if why.status > 2:
            asked = f" (over a step of h/{SUBSTEPS} that the estimate's probe asked for; " \
                "--estimate richardson asks none)" if steps else ""
            raise StepFailure(self.r, self.r.function_name(why.function) + asked, why.status, t,
                              t + h) from None
        self.model.failed = f"{self.r.name}'s {why.function} returned discard{steps} while " \
            "probing it"

    def _fit(self, k: int, h: float, runs: np.ndarray, eps: np.ndarray,
             after: np.ndarray | None = None) -> bool:
        """runs: (1 + inputs, steps, outputs), the first unmoved: a model's fit (fitted),
        or a response's Jacobian (one step: its outputs' change over each input's move);
        `after` (outputs, inputs): a model's outputs' change over each input's move set
        after the first step (_after; None: not measured). True where the model's first
        probe does not fit one pole (probe_fit.Higher): probe() may make it again with more
        steps, and clears the failure it marked."""
        if not np.isfinite(runs).all():
            self.model.failed = (f"{self.r.name}'s outputs were not finite numbers in the "
                                 f"probe at t = {k * h:g} s")
            return
        g, floor = _gains(runs, eps)
        if isinstance(self.model, ProbedResponse):
            self._fit_response(k, h, g, floor)
            return
        fit = fitted(g, floor.max(axis=0), self.model.direct)
        if isinstance(fit, str):
            self.model.failed = f"{self.r.name}'s response {fit} (probed at t = {k * h:g} s)"
            return isinstance(fit, Higher) and not self.model.found and \
                self.steps < ORDER2_STEPS
        deaf = _deaf(g, floor)
        if self.model.found and (lost := _lost(self.model.found[-1][3], fit[1])):
            self.model.failed = (
                f"{self.r.name}'s response of output {lost[0]} to input {lost[1]}, measured "
                f"at t = {self.model.found[-1][0] * h:g} s, fell below the output's round-off "
                f"by t = {k * h:g} s (an output that grows by itself, an input that "
                "saturates): the probes no longer measure how it carries an error")
        elif deaf is not None:
            self._deaf(deaf, k * h)
        elif self.model.found and len(fit) > 5 and not _agree((k, h, *fit),
                                                              self.model.found[-1]):
            self.model.failed = (
                f"{self.r.name}'s response of second order changed along the run (probed at "
                f"t = {self.model.found[-1][0] * h:g} s and {k * h:g} s): the pair carries "
                "two poles only where they stay, as a linear FMU's do")
        else:
            self._keep((k, h, *fit), after, eps, floor.max(axis=0))

    def _fit_response(self, k: int, h: float, g: np.ndarray, floor: np.ndarray) -> None:
        """A response's probe (_fit): its Jacobian, the outputs' change over each input's move
        (g[0]); it fails where an output kept a trace of the move a step later (a state), an
        input moved no output (_deaf: a quantizer, a saturation), or the Jacobian changed."""
        g0 = np.where(np.abs(g[0]) <= floor[0], 0.0, g[0])
        if self.steps > 1:      # per output: moved within the step, kept a trace after
            self.model.moved = g0.any(axis=1)
            self.model.trace = (np.abs(g[1]) > floor[1]).any(axis=1)
        if self.steps > 1 and self.model.trace.any():
            self.model.failed = (
                f"{self.r.name}'s outputs kept a trace of an input's move one step later "
                f"(probed at t = {k * h:g} s): it holds a state, " + (
                    "which its outputs' dependencies, on inputs only, do not say (FMI 2.0 "
                    "does not ask a co-simulation FMU to)" if self.model.declared else
                    "and its outputs declare no dependencies"))
            return
        found, deaf = (k, h, g0), _deaf(g0[None], 0.0)
        if deaf is not None:        # (a quantizer: a small move moves nothing)
            self._deaf(deaf, k * h)
        elif self.model.found and not _agree(found, self.model.found[-1]):
            self.model.failed = (
                f"{self.r.name}'s measured Jacobian changed along the run (probed at t = "
                f"{self.model.found[-1][0] * h:g} s and {k * h:g} s), and the pair "
                "carries an error only through an FMU without a state whose response it "
                "knows or that responds linearly")
        self.model.found = [found]        # only the last is used

    def _deaf(self, i: int, t: float) -> None:
        """The model failed: its input i moved no output in the probe at t (_DEAF)."""
        self.model.failed = _DEAF.format(self.r.name, self.model.inputs[i], t)
        self.model.deaf = True

    def _keep(self, found: tuple, after: np.ndarray | None, eps: np.ndarray,
              floor: np.ndarray) -> None:
        """A model's probe kept, with its outputs' change over each input's move set after
        the first step (`after`; None: not measured): the outputs worked out in doStep alone
        (lazy), and its direct part cut to what moves without a doStep (direct_fast)."""
        if after is not None:
            self.model.lazy |= lazy(found[6], after / eps, floor)
            found = direct_fast(found, after / eps, self.model.direct)
        self.model.found.append(found)

    def _steps(self, u: np.ndarray, t: float, h: float, first: np.ndarray | None = None,
               after: tuple | None = None) -> np.ndarray:
        """The covered outputs after each of its steps (self.steps: PROBE_STEPS, or
        ORDER2_STEPS; a response's: 1 or 2), inputs `first` (default u) over the first and
        u over the others; with `after` (a
        model's (outputs x inputs array, eps)), each input's move set after the first step
        and its outputs' change read into it (_after)."""
        out = np.empty((self.steps, len(self.y)))
        for i in range(self.steps):
            values = first if i == 0 and first is not None else u
            if i < 2:
                self._call("fmi2SetReal", self.r.c_set["Real"], self.in_vrs, len(values),
                           _fill(self.u, values))
            self.calls += 1
            self._call("fmi2DoStep", self.r.c_do_step, t + i * h, h, 0)
            self._call("fmi2GetReal", self.r.c_get["Real"], self.out_vrs, len(self.y), self.y)
            out[i] = self.y[:]
            if i == 0 and after is not None:
                self._after(u, out[0], *after)
        return out

    def _after(self, u: np.ndarray, y: np.ndarray, into: np.ndarray, eps: np.ndarray
               ) -> None:
        """Per input j, set u_j + eps_j after the step (no doStep) and the outputs' change
        read into `into`[:, j]: an output that reads u_j directly follows it (FMI 2.0), one
        worked out in doStep alone does not (`lazy`). The inputs are u again after it (the
        next step sets them too)."""
        for j in range(len(u)):
            self._call("fmi2SetReal", self.r.c_set["Real"], self.in_vrs, len(u),
                       _fill(self.u, _moved(u, j, eps)))
            self._call("fmi2GetReal", self.r.c_get["Real"], self.out_vrs, len(self.y), self.y)
            into[:, j] = np.array(self.y[:]) - y
        if len(u):
            self._call("fmi2SetReal", self.r.c_set["Real"], self.in_vrs, len(u),
                       _fill(self.u, u))

    def _call(self, name: str, function, *args) -> None:
        st = function(self.r.component, *args)
        if st > 1:
            raise _Refused(name, st)


class _Refused(Exception):
    """An FMI call that returned Discard or worse while probing."""

    def __init__(self, function: str, status: int):
        super().__init__(function, status)
        self.function, self.status = function, status


def _gains(runs: np.ndarray, eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """From a probe's runs (1 + inputs, steps, outputs; the first unmoved, then each input
    moved by eps): the responses g, each output's change over each input's move, and their
    round-off floor, each (steps, outputs, inputs)."""
    g = ((runs[1:] - runs[0]) / eps[:, None, None]).transpose(1, 2, 0)
    return g, (64 * _EPS) * np.abs(runs).max(axis=0)[:, :, None] / eps


def _moved(u: np.ndarray, j: int, eps: np.ndarray) -> np.ndarray:
    """u with input j moved by eps_j (a copy)."""
    nudged = u.copy()
    nudged[j] += eps[j]
    return nudged


def _fill(array, values: np.ndarray):
    array[:] = values.tolist()
    return array
