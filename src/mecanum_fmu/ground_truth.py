"""The original study's x_desired/y_desired: the commanded twist integrated directly.

The commanded twist comes from the scenario's VelocitySource expressions (evaluated with the
same safe evaluator), integrated through SPEC section 4 with a tight-tolerance ODE solver, so
it is independent of the FMUs, the coupling and the step size.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .blocks.expression import compile_expression
from .blocks.pose import pose_rate

if TYPE_CHECKING:       # only for annotations: the plotting process needs Roles, not the graph
    from .graph import Graph

SOURCE_DEFAULTS = {"vx_expr": "sin(t)", "vy_expr": "cos(t)", "w_expr": "0"}


@dataclass(frozen=True)
class Roles:
    """Which instance plays which part of the original diagram (None: not in this graph)."""
    source: str | None
    inverse: str | None
    forward: str | None
    pose: str | None


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


def find_roles(graph: Graph) -> Roles:
    def one(model: str) -> str | None:
        inst = graph.find_model(model)
        return inst.name if inst is not None else None
    return Roles(one("VelocitySource"), one("Center2Wheel"), one("Wheel2Center"),
                 one("PoseIntegrator"))


def ground_truth(graph: Graph, times: np.ndarray, rtol: float = 1e-10,
                 atol: float = 1e-12) -> Truth | None:
    """Integrate the commanded twist; None when the graph has no single VelocitySource."""
    roles = find_roles(graph)
    if roles.source is None:
        return None
    from scipy.integrate import solve_ivp     # here: loading and validating need no scipy
    source = graph.instance(roles.source)
    funcs = [compile_expression(str(source.start_values.get(k, SOURCE_DEFAULTS[k])))
             for k in ("vx_expr", "vy_expr", "w_expr")]
    start = (0.0, 0.0, 0.0)
    if roles.pose is not None:
        pose = graph.instance(roles.pose).start_values
        start = tuple(float(pose.get(k, 0.0)) for k in ("x0", "y0", "theta0"))

    def rhs(t, state):
        return pose_rate(state[2], funcs[0](t), funcs[1](t), funcs[2](t))

    times = np.asarray(times, dtype=float)
    # max_step keeps the solver from stepping over short segments of piecewise profiles.
    span = float(times[-1] - times[0]) if len(times) > 1 else 1.0
    sol = solve_ivp(rhs, (times[0], times[-1]), start, t_eval=times, rtol=rtol, atol=atol,
                    method="DOP853", max_step=max(span / 2000, 1e-6))
    twist = np.array([[f(t) for f in funcs] for t in times]).reshape(len(times), 3)
    return Truth(times, sol.y[0], sol.y[1], sol.y[2], twist[:, 0], twist[:, 1], twist[:, 2])
