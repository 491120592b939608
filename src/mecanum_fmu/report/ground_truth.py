"""The ground truth of each pose: what the commanded twist gives when integrated directly.

The original study's x_desired/y_desired, generalised: the twist that drives a pose
(models.commanded: expressions, tables, segments, field-oriented or car-like commands, saturated
where a Center2Wheel limits the wheel speeds) is integrated through the pose equations
(docs/spec.md, Pose integration) with a tight-tolerance ODE solver, independent of the FMUs,
the coupling and the step size. A closed loop's truth is the PathFollower's reference
(report.closed_loop).
"""
from __future__ import annotations

import numpy as np

from ..models.blocks.pose import pose_rate
from ..models.commanded import INPUTS, commanded_twist
from ..models.topology import Drive, topology, upstream
from .closed_loop import reference_truth
from .truth import Truth, bounded_grid, integrate


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
