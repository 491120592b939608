"""Closed-loop scenarios: the ground truth of a PathFollower run is the reference it follows.

The reference pose comes from the follower's expressions (the same safe evaluator); its rates
(the twist the plots show as "reference") are central differences in the body frame of the
reference heading. The summary's error is then the tracking error at the end time.
"""
from __future__ import annotations

import numpy as np

from ..models.blocks.expression import compile_expression
from .truth import Truth

REFERENCE = ("x_ref_expr", "y_ref_expr", "theta_ref_expr")


def reference_pose(follower, times: np.ndarray) -> np.ndarray:
    """The reference (x, y, theta) of a PathFollower instance at `times`, shape 3 x n."""
    funcs = [compile_expression(str(follower.value(k))) for k in REFERENCE]
    return np.array([[f(float(t)) for t in times] for f in funcs]).reshape(3, len(times))


def reference_truth(follower, times: np.ndarray):
    times = np.asarray(times, dtype=float)
    x, y, th = reference_pose(follower, times)
    d = 1e-6 * np.maximum(1.0, np.abs(times))
    up = reference_pose(follower, times + d)
    down = reference_pose(follower, times - d)
    dx, dy, w = (up - down) / (2 * d)
    c, s = np.cos(th), np.sin(th)
    return Truth(times, x, y, th, c * dx + s * dy, -s * dx + c * dy, w)
