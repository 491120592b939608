"""The twist a pose is commanded, read from the blocks that drive it (docs/spec.md,
docs/chassis.md), independently of the FMUs; the ground truth (report.ground_truth) integrates
it:

- a VelocitySource: its expressions (the same safe evaluator) or its table (with NumPy:
  table_twist; `segments:` arrive as a hold table);
- FieldToBody (either holonomic chassis): the commanded WORLD velocity and yaw rate, turned into
  the body frame at the heading;
- Bicycle: the commanded (v, phi) turned into the body twist of its reference point.

Each input of FieldToBody and Bicycle is an expression or table source's channel or the constant
start value of an unconnected input; one fed by any other FMU gives no truth (None) rather than
a wrong one. A Center2Wheel with a wheel speed limit (w_max > 0) between the command and the
pose saturates the twist's wheel speeds as the block does (docs/closed-loop.md, Wheel-speed
limits), computed here from the kinematics' matrix form (docs/spec.md).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .blocks.bicycle import bicycle_twist
from .blocks.expression import compile_expression
from .blocks.pose import world_to_body
from .blocks.profile_table import INTERPOLATIONS, TABLE_COLUMNS, table_sampler
from .topology import Drive, upstream

Twist = Callable[[float, float], tuple[float, float, float]]   # (t, theta) -> body twist
Channel = Callable[[float], float]
INPUTS = {"FieldToBody": ("vX", "vY", "omega"), "Bicycle": ("v", "phi")}
TWIST = ("vx", "vy", "w")


def table_twist(table, interpolation: str = "linear"):
    """(twist function of t for arrays or scalars, breakpoints) of a twist table, with NumPy:
    an implementation independent of the FMU's (blocks/profile_table.py samples row by row).
    A scalar t costs one bisection (np.interp's formula, O(log n)); the last one is kept, as
    the ground truth asks for the three channels of one t in turn."""
    times, cols = table.times, [table.columns[c] for c in TABLE_COLUMNS[1:]]
    if interpolation not in INTERPOLATIONS:
        table_sampler(table.text, interpolation)      # raises the message
    hold = interpolation == "hold"
    rows, last = np.stack(cols, axis=1).tolist(), [None, None]

    def at(t: float) -> tuple:
        i = int(np.searchsorted(times, t, side="right")) - 1
        if i < 0 or hold:
            return tuple(rows[max(i, 0)])
        if i >= len(rows) - 1:
            return tuple(rows[-1])
        t0, t1 = float(times[i]), float(times[i + 1])
        return tuple((b - a) / (t1 - t0) * (t - t0) + a for a, b in zip(rows[i], rows[i + 1]))

    def twist(t):
        if isinstance(t, float) or np.ndim(t) == 0:
            if last[0] != t:
                last[:] = t, at(float(t))
            return last[1]
        if hold:
            i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
            return tuple(c[i] for c in cols)
        return tuple(np.interp(t, times, c) for c in cols)
    return twist, times


def limited(twist: Twist, alpha: float, L: float, W: float, R: float, w_max: float) -> Twist:
    """The twist the chassis makes when its wheel speeds (1/R) A (vx, vy, w) are scaled down
    together to max |wi| <= w_max, back through A's least-squares inverse (docs/spec.md)."""
    c = 1.0 / np.tan(alpha)
    k = L + W * c
    A = np.array([[-c, 1.0, k], [c, 1.0, -k], [-c, 1.0, -k], [c, 1.0, k]])
    back = R * np.linalg.pinv(A)

    def saturated(t, theta):
        wheels = A @ np.asarray(twist(t, theta), dtype=float) / R
        peak = float(np.max(np.abs(wheels)))
        if peak <= w_max:
            return twist(t, theta)
        return tuple(float(v) for v in back @ (wheels * (w_max / peak)))
    return saturated


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
    """(t, theta) -> the body twist commanded at the drive's origin, saturated as its
    Center2Wheel limits the wheel speeds (w_max > 0), and the times where a table jumps; None
    for an origin without a truth of this kind."""
    found = _origin_twist(graph, drive)
    if found is None or not drive.w_max > 0:
        return found
    c2w = graph.instance(drive.limiter)
    return limited(found[0], *(float(c2w.value(k)) for k in ("alpha", "L", "W", "R")),
                   drive.w_max), found[1]


def _origin_twist(graph, drive: Drive) -> tuple[Twist, np.ndarray] | None:
    """The twist at the drive's origin, before any wheel speed limit."""
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
