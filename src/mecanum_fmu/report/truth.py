"""The ground truth of one pose: its path and commanded twist on the run's times, and the
ODE solve every kind of truth shares (docs/spec.md, Pose integration)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scenario.profiles import integrate_piecewise

MAX_POINTS = 20_001     # the ground truth is sampled on at most about this many times


@dataclass(frozen=True)
class Truth:
    time: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    w: np.ndarray

    @property
    def end(self) -> tuple[float, float, float]:
        return float(self.x[-1]), float(self.y[-1]), float(self.theta[-1])


def bounded_grid(times: np.ndarray, max_points: int = MAX_POINTS) -> np.ndarray:
    """`times`, or every k-th of them so that at most about max_points remain, the last kept."""
    if len(times) <= max_points:
        return times
    picked = times[::-(-len(times) // max_points)]
    return picked if picked[-1] == times[-1] else np.append(picked, times[-1])


def integrate(rhs, start, taus: np.ndarray, breaks: np.ndarray, rtol: float,
              atol: float) -> np.ndarray:
    """The pose at taus (3 x n, taus >= 0 from the start). A table is solved piece by piece
    between its rows (profiles.integrate_piecewise); anything else in one go, where max_step
    keeps the solver from stepping over a short feature of an expression: it reads the twist
    at least every span / 2000 and at least once per row interval of the run (the median: a
    short last step does not set it)."""
    if len(breaks):
        return integrate_piecewise(rhs, start, taus, breaks, rtol, atol)
    span = float(taus[-1]) if len(taus) > 1 else 1.0
    rows = float(np.median(np.diff(taus))) if len(taus) > 1 else span
    return solve_smooth(rhs, start, taus, rtol, atol, max(min(span / 2000, rows), 1e-6)).T


def solve_smooth(rhs, start, taus: np.ndarray, rtol: float, atol: float,
                 max_step: float) -> np.ndarray:
    """The state at taus (n x 3) of y' = rhs(tau, y) from y(0) = start: LSODA (scipy's
    odeint: Adams up to order 12 on a smooth span), which reads rhs about once a step where
    DOP853 reads it 12 times: at the same max_step a thirtieth of solve_ivp's time, within
    5e-12 of the pose that DOP853 gives at rtol 1e-13 on every bundled scenario; a feature of
    the twist narrower than max_step may fall between two readings (it could between
    DOP853's stages too, 12 times narrower). A table's pieces stay with DOP853
    (integrate_piecewise): LSODA starts each at first order, and over a 20 Hz table it ended
    1e-8 off. Raises ArithmeticError where the solver stops or a rate is not finite (an
    exception of rhs goes through)."""
    import warnings
    from scipy.integrate import odeint     # startup: loading and validating need no scipy
    taus, start = np.asarray(taus, dtype=float), np.asarray(start, dtype=float)
    out = np.empty((len(taus), len(start)))
    at_start = taus <= 4 * np.finfo(float).eps      # LSODA will not start on so short a span
    out[at_start] = start
    if at_start.all():
        return out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # its failure is the error below
        times = np.concatenate(([0.0], taus[~at_start]))
        y, info = odeint(_finite(rhs), start, times, tfirst=True, rtol=rtol, atol=atol,
                         hmax=max_step, mxstep=MAX_SOLVER_STEPS, full_output=True)
    if info["message"] != "Integration successful.":
        raise ArithmeticError(_stopped(info, times))
    out[~at_start] = y[1:]
    return out


def _finite(rhs):
    """rhs, raising where a rate is not finite: LSODA carries a NaN rate into the state and
    still says "Integration successful" (the end pose's check would only say that it is not
    finite, not where)."""
    def checked(tau, y):
        rates = rhs(tau, y)
        if not all(map(math.isfinite, rates)):
            raise ArithmeticError(f"the twist is not finite {tau:.6g} s after the start")
        return rates
    return checked


MAX_SOLVER_STEPS = 100_000      # between two of the run's rows: 2,000 at max_step span the run


def _stopped(info: dict, times: np.ndarray) -> str:
    """Why LSODA stopped, in our words, with where (from the start of the run): the t it
    reached on the first output time it did not reach. odeint leaves info's entries past
    that one unwritten (np.empty: any bits, 6e257 once), so none of them is read."""
    tcur = info["tcur"]
    short = np.flatnonzero(~(tcur >= times[1:]))    # a completed entry reached its time
    reached = float(tcur[short[0]]) if len(short) else float(times[-1])
    if len(short) and not times[short[0]] <= reached <= times[short[0] + 1]:
        reached = float(times[short[0]])            # not written either: its row's start
    why = (f"{MAX_SOLVER_STEPS:,} steps between two rows (is the twist singular there?)"
           if info["message"].startswith("Excess work") else info["message"])
    return f"the ODE solver stopped {reached:.6g} s after the start: {why}"
