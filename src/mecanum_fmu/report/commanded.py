"""The twist a pose is commanded, read from the blocks that drive it (docs/spec.md,
docs/chassis.md), independently of the FMUs:

- a VelocitySource: its expressions (the same safe evaluator) or its table (with NumPy:
  profiles.table_twist; `segments:` arrive as a hold table);
- FieldToBody (either holonomic chassis): the commanded WORLD velocity and yaw rate, turned into
  the body frame at the heading;
- Bicycle: the commanded (v, phi) turned into the body twist of its reference point.

Each input of FieldToBody and Bicycle is an expression or table source's channel or the constant
start value of an unconnected input; one fed by any other FMU gives no truth (None) rather than
a wrong one.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..models.blocks.bicycle import bicycle_twist
from ..models.blocks.expression import compile_expression
from ..models.blocks.pose import world_to_body
from ..models.topology import Drive, upstream
from ..scenario.profiles import table_twist

Twist = Callable[[float, float], tuple[float, float, float]]   # (t, theta) -> body twist
Channel = Callable[[float], float]
INPUTS = {"FieldToBody": ("vX", "vY", "omega"), "Bicycle": ("v", "phi")}
TWIST = ("vx", "vy", "w")


def source_channels(source) -> tuple[list[Channel], np.ndarray]:
    """A VelocitySource's vx, vy, w as functions of t, and the times where its table jumps."""
    if source.table is None:
        return [compile_expression(str(source.value(f"{k}_expr"))) for k in TWIST], np.array([])
    twist_of, breaks = table_twist(source.table, str(source.value("interpolation")))
    return [lambda t, i=i: float(twist_of(t)[i]) for i in range(3)], np.asarray(breaks, float)


def _channel(graph, inst, var: str) -> tuple[Channel | None, np.ndarray]:
    """inst.var as a function of t (and its table's breaks); None when another FMU drives it."""
    found = upstream(graph, inst.name, var)
    if found is None:
        value = float(inst.value(var) or 0.0)   # no start value declared: 0
        return (lambda t: value), np.array([])
    source = graph.instance(found[0])
    if source.model_name == "VelocitySource" and found[1] in TWIST:
        funcs, breaks = source_channels(source)
        return funcs[TWIST.index(found[1])], breaks
    if source.model_name == "SteeringSource":
        return compile_expression(str(source.value(f"{found[1]}_expr"))), np.array([])
    return None, np.array([])


def commanded_twist(graph, drive: Drive) -> tuple[Twist, np.ndarray] | None:
    """(t, theta) -> the body twist commanded at the drive's origin, and the times where a
    table jumps; None for an origin without a truth of this kind."""
    if drive.model == "VelocitySource":
        funcs, breaks = source_channels(graph.instance(drive.origin))
        return (lambda t, theta: tuple(f(t) for f in funcs)), breaks
    if drive.model not in INPUTS:
        return None
    origin = graph.instance(drive.origin)
    found = [_channel(graph, origin, name) for name in INPUTS[drive.model]]
    if any(f is None for f, _ in found):
        return None
    funcs = [f for f, _ in found]
    breaks = np.unique(np.concatenate([b for _, b in found]))
    if drive.model == "FieldToBody":
        def twist(t, theta):
            vX, vY, omega = (f(t) for f in funcs)
            return (*world_to_body(vX, vY, theta), omega)
        return twist, breaks
    l, reference = float(origin.value("l")), int(origin.value("reference"))
    return (lambda t, theta: bicycle_twist(funcs[0](t), funcs[1](t), l, reference)), breaks
