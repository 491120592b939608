"""The measured response's arithmetic (probe.py measures it): the fit of a probe's responses,
one pole and a direct part from 4 steps, or, where one pole does not fit, up to two per
(output, input) from 6 steps; the moment of a pole; the running sum that carries a past
error on.

Two poles (`modes`): a second-order FMU (a mass on a spring, a motor with its inductance, two
lags in a row) answers a unit held over one step with g_n = c1 z1^(n-1) + c2 z2^(n-1) for
n >= 1: the recurrence g_n = a1 g_n-1 + a2 g_n-2 for n >= 3, a1 and a2 from g1 .. g4, checked
on g5 (FIT). z1 and z2, the roots of z^2 - a1 z - a2, are the poles of one step (a complex
pair where it oscillates), c1 and c2 their shares. Each mode is a first-order part of its own:
its within-step response w = c / z, its moment m(z) (complex for a complex pole), its past
share carried on by z each step; the outputs are their sums' real parts.
"""
from __future__ import annotations

import cmath
import math
from itertools import accumulate
from typing import NamedTuple

import numpy as np

PROBE_STEPS = 4         # a probe's steps: g0 .. g3
ORDER2_STEPS = 6        # where one pole does not fit: g0 .. g5
# a pole that decays below round-off within a step is measured over steps of 1 / this
SUBSTEPS = 64
FAST = 1e-3             # relative: g0's part its pole does not carry on, a faster mode's
FAST_NOISE = 1e-2       # and up to this, where the substeps do not see it decay: round-off
LOOP_MAX = 20_000       # steps x (output, input) pairs a call carries by a loop (carried)
FIT = 0.1               # relative: g3 against the model's g2 r (x'' = u is 16% off)
# relative: g5 against two poles' recurrence (x''' = u is 2.3% off; poles 0.99, 0.98 and 0.05
# 8.6e-4, and their fit, an oscillating pair, read a tenth of the error over 600 steps: its
# miss grows with the horizon, 6.4e-3 at g7, 0.19 at g20; a linear spring's is round-off)
FIT2 = 1e-4
ILL = 1e-4              # relative: g2^2 - g1 g3 below this, two poles are not posed
# two poles closer than this (relative) are split to it: a repeated pole z's response n z^n
# is then (z1^n - z2^n) / (z1 - z2), off by about (n SPLIT)^2 / 6 relative at step n, its
# shares c about 1 / SPLIT of the response (6 of 16 digits lost to their cancellation)
SPLIT = 1e-6


class Higher(str):
    """Why one pole does not fit 4 steps of a response: 6 steps may fit two (fitted)."""


class Moments(NamedTuple):
    """A probe's moments (outputs x inputs each): `carried`, its pole's (moment(); zeros
    with two poles, whose modes carry their own), and `bent`, its second (bend()); `fast`,
    g0's part that no pole carries on (fast_part: a faster mode's, gone within the step;
    zeros where there is none), and `quick` and `quick_bent`, that part's (fast_moments)."""
    carried: np.ndarray
    bent: np.ndarray
    fast: np.ndarray
    quick: np.ndarray
    quick_bent: np.ndarray


def _moments(carried: np.ndarray, bent: np.ndarray) -> Moments:
    zeros = np.zeros_like(carried)
    return Moments(carried, bent, zeros, zeros, zeros)


def carried(decay, s, x: np.ndarray, work: int) -> np.ndarray:
    """s_k+1 = decay s_k + x_k from s_0 = s: s_0 .. s_n, the same bits either way (complex
    where x is). Up to LOOP_MAX steps x pairs of a call (`work`) a loop (0.2 us a step: at
    most 4 ms a call); beyond, scipy.signal.lfilter (0.01 us a step), whose import costs a
    process 1.6 s, more than most runs."""
    if work <= LOOP_MAX:
        return np.fromiter(accumulate(x.tolist(), lambda a, b: decay * a + b, initial=s),
                           dtype=x.dtype, count=len(x) + 1)
    from scipy.signal import lfilter
    after, _ = lfilter([1.0], [1.0, -decay], x, zi=[decay * s])
    return np.concatenate(([s], after))


def first_order(g0: np.ndarray, g1: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """Per output its one decay ratio, where g1 = r g0 for every input (within FIT, or
    where the input does not reach it), else None."""
    reached = g0 != 0.0
    if (np.abs(g1 - r * g0) > FIT * np.abs(g1) + 1e-300)[reached].any():
        return None
    rate = np.zeros(len(g0))
    for o in range(len(g0)):
        seen = r[o][reached[o]]
        if len(seen) and np.ptp(seen) > FIT * np.abs(seen).max():
            return None
        rate[o] = seen.mean() if len(seen) else 0.0
    return rate


def moment(r: np.ndarray) -> np.ndarray:
    """m(z), z = ln r = a h: x' = a x + b u's weight of the input's (s/h - 1/2) over a step,
    over its weight of the input's mean: int_0^1 e^(z t) (1/2 - t) dt / int_0^1 e^(z t) dt
    (about -z/12); 0 where r is not positive (no first-order response decays so). A complex
    r (a mode of an oscillating pair) takes the same integrals in complex numbers."""
    if np.iscomplexobj(r):
        return np.array([_moment_complex(complex(x)) for x in r.flat]).reshape(r.shape)
    return np.array([_moment(x) for x in r.flat]).reshape(r.shape)


def _moment(r: float) -> float:
    return moment_of_log(math.log(r)) if r > 0.0 else 0.0


def moment_of_log(z):
    """moment() of the pole e^z (real or complex); 1/2 at z = -inf (a decay within the step
    that the probes do not resolve: SUBSTEPS): the input's weight all at the step's end."""
    if z == -math.inf:
        return 0.5
    if abs(z) < 1e-4:
        return -z / 12
    if isinstance(z, complex):
        grown = cmath.exp(z)
        mean = (grown - 1.0) / z
        return (0.5 * mean - grown / z + (grown - 1.0) / (z * z)) / mean
    mean = math.expm1(z) / z
    return (0.5 * mean - math.exp(z) / z + math.expm1(z) / (z * z)) / mean


def bend(r: np.ndarray) -> np.ndarray:
    """b(z), z = ln r: x' = a x + b u's weight of the input's (s/h - 1/2)^2 - 1/12 over a
    step, over its weight of the input's mean (about z^2 / 360; 1/6 at z = -inf: all at the
    step's end): what 6 b times the input's (start + end) / 2 - mean adds to the weighted
    mean of a parabola, past the moment's share of its change. 0 where r is not positive; a
    complex r takes the same integrals in complex numbers."""
    if np.iscomplexobj(r):
        return np.array([bend_of_log(cmath.log(complex(x))) if x != 0 else 0.0
                         for x in r.flat]).reshape(r.shape)
    return np.array([bend_of_log(math.log(x)) if x > 0.0 else 0.0 for x in r.flat]
                    ).reshape(r.shape)


def bend_of_log(z):
    """bend() of the pole e^z (real or complex; 1/6 at z = -inf)."""
    if z == -math.inf:
        return 1.0 / 6.0
    if abs(z) < 1e-2:
        return z * z / 360
    grown = cmath.exp(z) if isinstance(z, complex) else math.exp(z)
    mean = (grown - 1.0) / z
    first = (grown * (z - 1.0) + 1.0) / (z * z)
    second = (grown * (z * z - 2.0 * z + 2.0) - 2.0) / (z * z * z)
    return 1.0 / 6.0 + (second - first) / mean


def _moment_complex(r: complex) -> complex:
    return complex(_moment(r.real)) if r.imag == 0.0 else moment_of_log(cmath.log(r))


def fitted(g: np.ndarray, floor: np.ndarray, direct: np.ndarray | None = None
           ) -> tuple | str:
    """(g0, g1, r, m, D) from the responses g (PROBE_STEPS, outputs, inputs) and the
    round-off floor of each (outputs, inputs), or why the model does not fit (g3 off its
    prediction: Higher); where `direct` (the input reaches the output directly), g0 is the
    state's part, g1 / r, and D the rest (ProbedModel); m its Moments, without a fast part
    (Target._faster measures one). From ORDER2_STEPS responses, the same with up to two
    poles each (_two_poles): (g0, g1, r, m, D, modes)."""
    if len(g) >= ORDER2_STEPS:
        return _modes(g, floor, direct)
    g = g * (np.abs(g) > floor)
    g0, g1, g2, g3 = g
    seen = g1 != 0.0
    r = g2 / (g1 + ~seen) * seen
    if direct is not None and direct.any():
        state = np.where(r != 0.0, g1 / np.where(r != 0.0, r, 1.0), 0.0)
        d_part = np.where(direct, g0 - state, 0.0)
        g0 = np.where(direct, state, g0)
    else:
        d_part = np.zeros_like(g0)
    off = np.abs(g3 - g2 * r) > FIT * np.abs(g3) + 2 * floor
    if off.any():
        o, j = np.argwhere(off)[0]
        return Higher(f"(output {o}, input {j}) is not of first order: one step on, the "
                      f"response {g1[o, j]:.3g}, {g2[o, j]:.3g}, {g3[o, j]:.3g} does not decay "
                      "by one ratio")
    return g0, g1, r, _moments(moment(r), bend(r)), d_part


def _modes(g: np.ndarray, floor: np.ndarray, direct: np.ndarray | None) -> tuple | str:
    """fitted's from ORDER2_STEPS responses: per (output, input) up to two poles z and their
    shares c, g_n = sum c z^(n-1) for n >= 1 (the module doc); modes (z, c, m(z), bend(z)),
    each (2, outputs, inputs). g0's state part is sum c / z; r the larger |z| (what two
    probes compare: probe._agree); m's carried moments 0 (the modes carry their own)."""
    g = g * (np.abs(g) > floor)
    z = np.zeros((2, *g.shape[1:]), dtype=complex)
    c = np.zeros_like(z)
    for o, j in np.ndindex(g.shape[1:]):
        fit = _two_poles(g[1:, o, j], 2 * floor[o, j])
        if isinstance(fit, str):
            return f"(output {o}, input {j}) {fit}"
        z[:, o, j], c[:, o, j] = fit
    state = within_step(z, c).sum(axis=0).real
    g0 = g[0]
    if direct is not None and direct.any():
        d_part = np.where(direct, g0 - state, 0.0)
        g0 = np.where(direct, state, g0)
    else:
        d_part = np.zeros_like(g0)
    zeros = np.zeros_like(g0)
    return g0, g[1], np.abs(z).max(axis=0), _moments(zeros, zeros), d_part, (
        z, c, moment(z), bend(z))


def fast_part(g0: np.ndarray, state: np.ndarray, direct: np.ndarray) -> np.ndarray:
    """(outputs, inputs): g0's part that the poles do not carry on, g0 less their `state`
    part (g1 / r; two poles: sum c / z; 0 where r is 0, a decay below round-off within the
    step), where it is above FAST of g0 and the input is not declared to reach the output
    directly (its direct part says that); 0 elsewhere. A faster mode's: a lag x' = -100 x +
    u at 0.2 s, a spring's speed whose poles are -1 and -100."""
    part = np.where(direct, 0.0, g0 - state)
    return np.where(np.abs(part) > FAST * np.abs(g0), part, 0.0)


def direct_fast(found: tuple, seen: np.ndarray, where: np.ndarray) -> tuple:
    """A probe's `found` with the direct part D (`where`: declared direct) cut to `seen`,
    what the output moved by for the input moved after the step (no doStep: the part that
    is truly direct), and the rest, over FAST of D, a fast part (Moments.fast): a state
    gone within the step, g1 below round-off, which D took for its own (y = x + u, x' =
    -100 x + u at 0.1 s: y's estimate read 1e-6 of its error, D erring by the held value
    against the end value, nothing where the master holds the newest), or an output worked
    out in doStep alone (lazy: seen 0), whose substeps show no decay: moment 1/2 and bend
    1/6, the held value against the end value, as its lazy part had it."""
    d_part, m = found[6], found[5]
    rest = np.where(where, d_part - seen, 0.0)
    rest = np.where(np.abs(rest) > FAST * np.abs(d_part), rest, 0.0)
    if not rest.any():
        return found
    return (*found[:5], m._replace(fast=rest), d_part - rest, *found[7:])   # (a fresh fit's)


def fast_moments(sub: np.ndarray, floor: np.ndarray, slow: list, fast: np.ndarray,
                 g0: np.ndarray) -> tuple | str:
    """(the fast parts kept, their moments, their bends): those of each `fast` part of `g0`
    (fast_part; 0 where there is none) from `sub` (2, outputs, inputs), the responses at the
    ends of two substeps of h / SUBSTEPS to a unit held over the first, and their round-off
    `floor`. The slow poles' share of those is
    taken out (`slow`: their parts of g0 and poles, (W, z) each: W answers W (z^(1/S) - 1)
    / (z - 1), then z^(1/S) of that); the rest decays by the fast part's ratio (fast_logs).
    A part under FAST_NOISE of g0 that the substeps do not see decay is taken for a slow
    pole's round-off (a lag with r 5e-5 measured 2% off: g1 / r 0.2% off g0) and left out.
    Or why it does not fit."""
    first, second = sub[0].astype(complex), sub[1].astype(complex)
    for w, z in slow:
        ln = np.log(np.where(z != 0.0, z, 1.0).astype(complex))
        share = np.where(ln != 0.0, np.expm1(ln / SUBSTEPS) / np.where(
            ln != 0.0, np.expm1(ln), 1.0), 1.0 / SUBSTEPS)
        part = np.where(z != 0.0, w * share, 0.0)
        first, second = first - part, second - part * np.exp(ln / SUBSTEPS)
    logs = fast_logs(np.stack((first.real, second.real)), floor)
    unfit = np.isnan(logs) & (fast != 0.0)
    if (np.abs(fast[unfit]) > FAST_NOISE * np.abs(g0[unfit])).any():
        return f"decays within one step, and over 1/{SUBSTEPS} of it not by one ratio"
    fast = np.where(unfit, 0.0, fast)
    quick, bent = np.zeros_like(fast), np.zeros_like(fast)
    quick[fast != 0.0] = [moment_of_log(z) for z in logs[fast != 0.0]]
    bent[fast != 0.0] = [bend_of_log(z) for z in logs[fast != 0.0]]
    return fast, quick, bent


def fast_logs(g: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """ln r per (output, input) of one step, from the responses g (2, outputs, inputs) to a
    unit held over the first of two steps of 1 / SUBSTEPS of it: SUBSTEPS ln(g1 / g0); -inf
    where g1 is not above its round-off `floor` (a pole e^(a h), a h below -20 SUBSTEPS: its
    moment 1/2 - 1 / (a h) is 1/2 to 1e-3); nan where g0 is not, or g1 / g0 is not a decay
    (not in (0, 1): no first-order response)."""
    g0, g1 = g
    gone = np.abs(g1) <= floor
    ratio = np.where(np.abs(g0) > floor, g1 / np.where(g0 != 0.0, g0, 1.0), np.nan)
    decays = (ratio > 0.0) & (ratio < 1.0)
    return np.where(gone, -np.inf, np.where(decays, SUBSTEPS * np.log(np.where(
        decays, ratio, 1.0)), np.nan))


def within_step(z: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Each mode's response within the step its input moved on, c / z (0 for a mode at 0)."""
    return np.where(z != 0, c / np.where(z != 0, z, 1.0), 0.0)


def _two_poles(g: np.ndarray, tol: float) -> tuple | str:
    """((z1, z2), (c1, c2)) of the responses g1 .. g5 of one (output, input): one pole where
    it misses g3 .. g5 within FIT and by no more than 10x what the recurrence of two through
    g1 .. g4 misses g5 by (or by round-off, or where that recurrence is ill-conditioned: a
    geometric response's), c2 = 0; else those two poles, where they miss g5 within FIT2; or
    why neither fits. (A second-order response looks geometric within FIT over a few short
    steps: the mass's speed at 0.05 s, 4% off, whose pole the first-order check alone took
    for 0.96, and its estimate read half its error. Three integrators' response misses two
    poles' recurrence by 2.3% and would take growing poles, |z| 1.43.)"""
    g1, g2, g3, g4, g5 = (float(v) for v in g)
    if not g.any():
        return (0.0, 0.0), (0.0, 0.0)
    r = g2 / g1 if g1 != 0.0 else math.nan
    misses = [abs(b - r * a) for a, b in zip(g[1:], g[2:])]     # g3 .. g5
    det = g2 * g2 - g1 * g3
    posed = abs(det) > ILL * max(g2 * g2, abs(g1 * g3))
    a1 = (g3 * g2 - g1 * g4) / det if posed else math.nan
    a2 = (g2 * g4 - g3 * g3) / det if posed else math.nan
    two = abs(g5 - a1 * g4 - a2 * g3)
    if all(m <= FIT * abs(b) + tol for m, b in zip(misses, g[2:])) and (
            max(misses) <= 10 * two or max(misses) <= tol or not posed):
        return (r, 0.0), (g1, 0.0)
    if not two <= FIT2 * abs(g5) + tol:
        return (f"is not of first or second order: the response {g1:.3g}, {g2:.3g}, "
                f"{g3:.3g}, {g4:.3g}, {g5:.3g} does not follow one recurrence of two steps")
    root = cmath.sqrt(a1 * a1 + 4 * a2)
    if abs(root) < SPLIT * abs(a1):     # a repeated pole (two integrators, two equal lags)
        root = SPLIT * a1
    z1, z2 = (a1 + root) / 2, (a1 - root) / 2
    if z1 == z2:
        return "has a repeated pole at 0"
    c1 = (g2 - z2 * g1) / (z1 - z2)
    return (z1, z2), (c1, g1 - c1)


def lazy(d_part: np.ndarray, after: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Per (output, input): a direct part (fitted's D, within the step) that the output does
    not show for the input moved after the step (`after`: its change over the move), not
    even half of it: the output is worked out in doStep alone (pythonfmu's way, where a
    getter does not work it out when read). Such an output reads what the input was held
    at during the step, not the value set after it. `floor`: the round-off of each."""
    return (np.abs(d_part) > floor) & (np.abs(after) < 0.5 * np.abs(d_part))


def modal_linear(modes: tuple, scale: float, error: np.ndarray, change: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One run of steps of a probe with two poles (`modes`: z, c, m, each (2, outputs,
    inputs)) in the form a loop carries (pair_loop.py): X_k+1 = A X_k + made_k + B (the held
    inputs' further error), X the modes' shares after each step, c / z d summed on (their
    real parts, then their imaginary parts, each mode in z's flat order; modal_outputs sums
    them into the outputs): A turns each by z^scale, B its within-step response c / z, made
    that times d = error - m change. Returns (A, B, made) per step."""
    z, c, m = (v.ravel() for v in modes[:3])
    inputs = np.broadcast_to(np.arange(modes[0].shape[2]), modes[0].shape).ravel()
    turn = z if scale == 1.0 else z ** scale
    within = within_step(z, c) * scale
    k, steps = len(z), len(error)
    a = np.zeros((2 * k, 2 * k))
    a[:k, :k] = a[k:, k:] = np.diag(turn.real)
    a[:k, k:], a[k:, :k] = -np.diag(turn.imag), np.diag(turn.imag)
    b = np.zeros((2 * k, error.shape[1]))
    b[np.arange(k), inputs], b[k + np.arange(k), inputs] = within.real, within.imag
    made = within[None] * (error[:, inputs] - m[None] * change[:, inputs])
    return (np.broadcast_to(a, (steps, *a.shape)), np.broadcast_to(b, (steps, *b.shape)),
            np.concatenate((made.real, made.imag), axis=1))


def modal_outputs(shape: tuple) -> np.ndarray:
    """The outputs' errors from modal_linear's X (outputs x X): each output the sum of its
    modes' real parts."""
    outputs = np.broadcast_to(np.arange(shape[1])[:, None], shape[1:])
    out = np.zeros((shape[1], 2 * int(np.prod(shape))))
    out[np.broadcast_to(outputs, shape).ravel(), np.arange(int(np.prod(shape)))] = 1.0
    return out
