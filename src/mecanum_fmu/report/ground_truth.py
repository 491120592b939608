"""The original study's x_desired/y_desired: the commanded twist integrated directly.

The commanded twist comes from the scenario's VelocitySource expressions (evaluated with the
same safe evaluator), integrated through the pose equations (docs/spec.md, Pose integration)
with a tight-tolerance ODE solver, so it is independent of the FMUs, the coupling and the step
size.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..models.blocks.expression import compile_expression
from ..models.blocks.pose import pose_rate
from ..models.catalog import Roles, find_roles  # noqa: F401  (Roles: re-exported for the plots)

if TYPE_CHECKING:       # only for annotations: the plotting process needs Roles, not the graph
    from ..graph import Graph


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
    times = bounded_grid(np.asarray(times, dtype=float))
    from .chassis_truth import NOT_MINE, chassis_truth   # field-oriented or car-like chassis
    if (truth := chassis_truth(graph, times, rtol, atol)) is not NOT_MINE:
        return truth
    roles = find_roles(graph)
    if roles.follower is not None:        # closed loop: the path it is asked to follow
        from .closed_loop import reference_truth
        return reference_truth(graph.instance(roles.follower), times)
    if roles.source is None:
        return None
    funcs, breaks = _commanded(graph.instance(roles.source))
    start = (0.0, 0.0, 0.0)
    if roles.pose is not None:
        pose = graph.instance(roles.pose)
        start = tuple(float(pose.value(k)) for k in ("x0", "y0", "theta0"))
    t0 = float(times[0])

    def rhs(tau, state):     # in time since the start: the solver's steps stay resolvable
        t = t0 + float(tau)  # (a start of 1e15 s has a float spacing of 0.125 s)
        return pose_rate(state[2], funcs[0](t), funcs[1](t), funcs[2](t))

    path = integrate(rhs, start, times - t0, np.asarray(breaks, dtype=float) - t0, rtol, atol)
    twist = np.array([[f(t) for f in funcs] for t in times.tolist()]).reshape(len(times), 3)
    return Truth(times, path[0], path[1], path[2], twist[:, 0], twist[:, 1], twist[:, 2])


def _commanded(source) -> tuple[list, tuple]:
    """The source's twist as three functions of t, and the times where a table jumps."""
    funcs = [compile_expression(str(source.value(k))) for k in ("vx_expr", "vy_expr", "w_expr")]
    if not source.value("table"):
        return funcs, ()
    from ..profiles import table_twist     # a table replaces the expressions
    twist_of, breaks = table_twist(str(source.value("table")), str(source.value("interpolation")))
    return [lambda t, i=i: float(twist_of(t)[i]) for i in range(3)], breaks


def integrate(rhs, start, taus: np.ndarray, breaks: np.ndarray, rtol: float,
               atol: float) -> np.ndarray:
    """The pose at taus (3 x n). max_step keeps the solver from stepping over short segments
    of piecewise profiles; a table is solved piece by piece between its rows."""
    from scipy.integrate import solve_ivp     # here: loading and validating need no scipy
    if len(breaks):
        from ..profiles import integrate_piecewise
        return integrate_piecewise(rhs, start, taus, breaks, rtol, atol)
    span = float(taus[-1]) if len(taus) > 1 else 1.0
    sol = solve_ivp(rhs, (0.0, taus[-1]), start, t_eval=taus, rtol=rtol, atol=atol,
                    method="DOP853", max_step=max(span / 2000, 1e-6))
    if not sol.success:
        raise ArithmeticError(f"the ODE solver stopped: {sol.message}")
    return sol.y
