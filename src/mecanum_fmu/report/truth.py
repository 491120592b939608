"""The ground truth of one pose: its path and commanded twist on the run's times, and the
ODE solve every kind of truth shares (docs/spec.md, Pose integration)."""
from __future__ import annotations

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
    """The pose at taus (3 x n). max_step keeps the solver from stepping over short segments
    of piecewise profiles; a table is solved piece by piece between its rows."""
    from scipy.integrate import solve_ivp     # startup: loading and validating need no scipy
    if len(breaks):
        return integrate_piecewise(rhs, start, taus, breaks, rtol, atol)
    span = float(taus[-1]) if len(taus) > 1 else 1.0
    sol = solve_ivp(rhs, (0.0, taus[-1]), start, t_eval=taus, rtol=rtol, atol=atol,
                    method="DOP853", max_step=max(span / 2000, 1e-6))
    if not sol.success:
        raise ArithmeticError(f"the ODE solver stopped: {sol.message}")
    return sol.y
