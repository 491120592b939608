"""The original study's x_desired/y_desired: the commanded twist integrated directly.

The commanded twist comes from the scenario's VelocitySource expressions (evaluated with the
same safe evaluator), integrated through the pose equations (docs/spec.md, Pose integration)
with a tight-tolerance ODE solver, so it is independent of the FMUs, the coupling and the step
size.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .blocks.expression import compile_expression
from .blocks.pose import pose_rate
from .bundled import Roles, find_roles  # noqa: F401  (Roles: re-exported for the plots)
from .graph import Graph


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


def ground_truth(graph: Graph, times: np.ndarray, rtol: float = 1e-10,
                 atol: float = 1e-12) -> Truth | None:
    """Integrate the commanded twist; None when the graph has no single VelocitySource.
    Sampled at `times`, thinned to a bounded grid (bounded_grid) for long runs."""
    roles = find_roles(graph)
    if roles.source is None:
        return None
    source = graph.instance(roles.source)
    funcs = [compile_expression(str(source.value(k))) for k in ("vx_expr", "vy_expr", "w_expr")]
    start = (0.0, 0.0, 0.0)
    if roles.pose is not None:
        pose = graph.instance(roles.pose)
        start = tuple(float(pose.value(k)) for k in ("x0", "y0", "theta0"))

    times = bounded_grid(np.asarray(times, dtype=float))
    t0 = float(times[0])

    def rhs(tau, state):     # in time since the start: the solver's steps stay resolvable
        t = t0 + float(tau)  # (a start of 1e15 s has a float spacing of 0.125 s)
        return pose_rate(state[2], funcs[0](t), funcs[1](t), funcs[2](t))

    # max_step keeps the solver from stepping over short segments of piecewise profiles.
    taus = times - t0
    span = float(taus[-1]) if len(times) > 1 else 1.0
    sol = solve_ivp(rhs, (0.0, taus[-1]), start, t_eval=taus, rtol=rtol, atol=atol,
                    method="DOP853", max_step=max(span / 2000, 1e-6))
    if not sol.success:
        raise ArithmeticError(f"the ODE solver stopped: {sol.message}")
    twist = np.array([[f(t) for f in funcs] for t in times.tolist()]).reshape(len(times), 3)
    return Truth(times, sol.y[0], sol.y[1], sol.y[2], twist[:, 0], twist[:, 1], twist[:, 2])
