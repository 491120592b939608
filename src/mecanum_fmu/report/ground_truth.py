"""The ground truth of each pose: what the commanded twist gives when integrated directly.

The original study's x_desired/y_desired, generalised: the twist that drives a pose
(report.commanded: expressions, tables, segments, field-oriented or car-like commands) is
integrated through the pose equations (docs/spec.md, Pose integration) with a tight-tolerance
ODE solver, independent of the FMUs, the coupling and the step size. A Center2Wheel with a
wheel speed limit (w_max > 0) between the command and the pose saturates the truth's wheel
speeds as the block does (docs/closed-loop.md, Wheel-speed limits), computed here from the
kinematics' matrix form (docs/spec.md). A closed loop's truth is the PathFollower's reference
(report.closed_loop).
"""
from __future__ import annotations

import numpy as np

from ..models.blocks.pose import pose_rate
from ..models.topology import Drive, topology, upstream
from .closed_loop import reference_truth
from .commanded import INPUTS, commanded_twist
from .truth import Truth, bounded_grid, integrate


def limited(twist, alpha: float, L: float, W: float, R: float, w_max: float):
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


def pose_truth(graph, drive: Drive, times: np.ndarray, rtol: float = 1e-10,
               atol: float = 1e-12) -> Truth | None:
    """The truth of one pose on `times` (thinned to a bounded grid for long runs); None when
    what drives it has no truth (another FMU, an unconnected pose)."""
    times = bounded_grid(np.asarray(times, dtype=float))
    if drive.model == "PathFollower":     # closed loop: the path it is asked to follow
        return reference_truth(graph.instance(drive.origin), times)
    found = commanded_twist(graph, drive) if drive.origin is not None else None
    if found is None or len(times) == 0:
        return None
    twist, breaks = found
    if drive.w_max > 0:
        c2w = graph.instance(drive.limiter)
        twist = limited(twist, *(float(c2w.value(k)) for k in ("alpha", "L", "W", "R")),
                        drive.w_max)
    pose = graph.instance(drive.pose)
    start = tuple(float(pose.value(k)) for k in ("x0", "y0", "theta0"))
    t0 = float(times[0])

    def rhs(tau, state):     # in time since the start: the solver's steps stay resolvable
        return pose_rate(state[2], *twist(t0 + float(tau), state[2]))   # (1e15 s: 0.125 s apart)

    path = integrate(rhs, start, times - t0, breaks - t0, rtol, atol)
    body = np.array([twist(t, th) for t, th in zip(times.tolist(), path[2])]).reshape(-1, 3)
    return Truth(times, path[0], path[1], path[2], body[:, 0], body[:, 1], body[:, 2])


def truth_inputs(graph, drive: Drive) -> tuple[str, ...]:
    """The instances whose values the pose's truth reads (a sweep solves one truth per
    distinct set of their start values)."""
    names = [drive.pose] + ([drive.origin] if drive.origin else [])
    if drive.limiter:
        names.append(drive.limiter)
    for var in INPUTS.get(drive.model, ()):
        if (found := upstream(graph, drive.origin, var)) is not None:
            names.append(found[0])
    return tuple(dict.fromkeys(names))


def ground_truth(graph, times: np.ndarray, rtol: float = 1e-10,
                 atol: float = 1e-12) -> Truth | None:
    """The truth of a graph's single pose (None without exactly one PoseIntegrator)."""
    drives = topology(graph).drives
    return pose_truth(graph, drives[0], times, rtol, atol) if len(drives) == 1 else None
