"""Ground truth for the other chassis (docs/chassis.md), when the pose is driven through them.

- Field-oriented (FieldToBody, either holonomic chassis): the commanded WORLD velocity and yaw
  rate, integrated directly (x' = vX, y' = vY, theta' = omega).
- Car-like (Bicycle): the commanded (v, phi) turned into the body twist of the reference point
  (docs/spec.md, Kinematic bicycle) and integrated like any body twist.

The commands are read from the expression sources (VelocitySource, SteeringSource) that feed
those blocks, with the same safe evaluator; an input fed by any other FMU gives no ground truth
(None) rather than a wrong one. Graphs whose pose is driven otherwise are NOT_MINE: the
original study's ground truth (ground_truth.py) handles them.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..models.blocks.bicycle import bicycle_twist
from ..models.blocks.expression import compile_expression
from ..models.blocks.pose import pose_rate, world_to_body
from ..graph import Graph, Instance

NOT_MINE = object()
# blocks a body twist passes through unchanged (inverse then forward kinematics): model -> the
# input to follow upstream
PASS_THROUGH = {"Wheel2Center": "w1", "OmniWheel2Center": "w1",
                "Center2Wheel": "vx", "OmniCenter2Wheel": "vx"}
EXPRESSION_SOURCES = ("VelocitySource", "SteeringSource")


def _upstream(graph: Graph, inst: Instance, var: str) -> tuple[Instance, str] | None:
    """The instance and output that drive inst.var, or None when it is not connected."""
    for link in graph.links:
        if link.target.ref.instance == inst.name and link.target.ref.variable == var:
            return graph.instance(link.source.ref.instance), link.source.ref.variable
    return None


def twist_origin(graph: Graph, pose: Instance) -> Instance | None:
    """The block whose body twist the pose integrates, past any kinematics pair."""
    found = _upstream(graph, pose, "vx")
    seen = set()
    while found is not None and found[0].model_name in PASS_THROUGH and found[0].name not in seen:
        seen.add(found[0].name)
        found = _upstream(graph, found[0], PASS_THROUGH[found[0].model_name])
    return found[0] if found is not None else None


def command(graph: Graph, inst: Instance, var: str) -> Callable[[float], float] | None:
    """inst.var as a function of t: an expression source's channel, or the constant start
    value of an unconnected input; None when another FMU drives it."""
    found = _upstream(graph, inst, var)
    if found is None:
        value = float(inst.value(var) or 0.0)   # no start value declared: 0
        return lambda t: value
    source, output = found
    if source.model_name not in EXPRESSION_SOURCES:
        return None
    return compile_expression(str(source.value(f"{output}_expr")))


def chassis_truth(graph: Graph, times: np.ndarray, rtol: float = 1e-10, atol: float = 1e-12):
    """Truth for the single pose when FieldToBody or Bicycle drives it (None when its commands
    are not all expressions); NOT_MINE otherwise."""
    pose = graph.find_model("PoseIntegrator")
    origin = twist_origin(graph, pose) if pose is not None else None
    if origin is None or origin.model_name not in ("FieldToBody", "Bicycle"):
        return NOT_MINE
    return pose_truth(graph, pose, times, rtol, atol)


def _twist_function(graph: Graph, origin: Instance):
    """(t, theta) -> commanded body twist at origin's output; None without a ground truth."""
    names = {"VelocitySource": (), "FieldToBody": ("vX", "vY", "omega"), "Bicycle": ("v", "phi")}
    if origin.model_name not in names:
        return None
    if origin.model_name == "VelocitySource":
        funcs = [compile_expression(str(origin.value(f"{v}_expr"))) for v in ("vx", "vy", "w")]
    else:
        funcs = [command(graph, origin, n) for n in names[origin.model_name]]
    if any(f is None for f in funcs):
        return None
    if origin.model_name == "VelocitySource":
        return lambda t, theta: tuple(f(t) for f in funcs)
    if origin.model_name == "FieldToBody":
        def twist(t, theta):
            vX, vY, omega = (f(t) for f in funcs)
            return (*world_to_body(vX, vY, theta), omega)
        return twist
    l, reference = float(origin.value("l")), int(origin.value("reference"))
    return lambda t, theta: bicycle_twist(funcs[0](t), funcs[1](t), l, reference)


def pose_truth(graph: Graph, pose: Instance, times: np.ndarray, rtol: float = 1e-10,
               atol: float = 1e-12):
    """The commanded twist that drives `pose` (from VelocitySource, FieldToBody or Bicycle,
    past any kinematics pair) integrated from the pose's start; None when there is none."""
    from .ground_truth import Truth, integrate
    origin = twist_origin(graph, pose)
    twist = _twist_function(graph, origin) if origin is not None else None
    if twist is None or len(times) == 0:
        return None
    start = tuple(float(pose.value(k)) for k in ("x0", "y0", "theta0"))
    times = np.asarray(times, dtype=float)
    t0 = float(times[0])       # solved in time since the start, as ground_truth does
    path = integrate(lambda tau, s: pose_rate(s[2], *twist(t0 + float(tau), s[2])), start,
                      times - t0, np.array([]), rtol, atol)
    body = np.array([twist(t, th) for t, th in zip(times, path[2])]).reshape(len(times), 3)
    return Truth(times, path[0], path[1], path[2], body[:, 0], body[:, 1], body[:, 2])
