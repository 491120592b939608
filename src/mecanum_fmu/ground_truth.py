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

from .blocks.expression import compile_expression
from .blocks.pose import pose_rate
from .bundled import Roles, find_roles  # noqa: F401  (Roles: re-exported for the plots)

if TYPE_CHECKING:       # only for annotations: the plotting process needs Roles, not the graph
    from .graph import Graph


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


def ground_truth(graph: Graph, times: np.ndarray, rtol: float = 1e-10,
                 atol: float = 1e-12) -> Truth | None:
    """Integrate the commanded twist; None when the graph has no single VelocitySource."""
    from .chassis_truth import NOT_MINE, chassis_truth   # field-oriented or car-like chassis
    if (truth := chassis_truth(graph, times, rtol, atol)) is not NOT_MINE:
        return truth
    roles = find_roles(graph)
    if roles.follower is not None:        # closed loop: the path it is asked to follow
        from .closed_loop import reference_truth
        return reference_truth(graph.instance(roles.follower), times)
    if roles.source is None:
        return None
    from scipy.integrate import solve_ivp     # here: loading and validating need no scipy
    source = graph.instance(roles.source)
    funcs = [compile_expression(str(source.value(k))) for k in ("vx_expr", "vy_expr", "w_expr")]
    breaks = ()
    if source.value("table"):  # a table replaces the expressions (profiles.py)
        from .profiles import table_twist
        twist_of, breaks = table_twist(str(source.value("table")),
                                       str(source.value("interpolation")))
        funcs = [lambda t, i=i: float(twist_of(t)[i]) for i in range(3)]
    start = (0.0, 0.0, 0.0)
    if roles.pose is not None:
        pose = graph.instance(roles.pose)
        start = tuple(float(pose.value(k)) for k in ("x0", "y0", "theta0"))

    def rhs(t, state):
        return pose_rate(state[2], funcs[0](t), funcs[1](t), funcs[2](t))

    times = np.asarray(times, dtype=float)
    # max_step keeps the solver from stepping over short segments of piecewise profiles.
    span = float(times[-1] - times[0]) if len(times) > 1 else 1.0
    if len(breaks):
        from .profiles import integrate_piecewise
        path = integrate_piecewise(rhs, start, times, breaks, rtol, atol)
    else:
        sol = solve_ivp(rhs, (times[0], times[-1]), start, t_eval=times, rtol=rtol, atol=atol,
                        method="DOP853", max_step=max(span / 2000, 1e-6))
        path = sol.y
    twist = np.array([[f(t) for f in funcs] for t in times]).reshape(len(times), 3)
    return Truth(times, path[0], path[1], path[2], twist[:, 0], twist[:, 1], twist[:, 2])
