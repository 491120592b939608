"""Closed-loop scenarios: the ground truth of a PathFollower run is the reference it follows.

The reference pose comes from the follower's expressions (the same safe evaluator); its rates
(the twist the plots show as "reference") are central differences in the body frame of the
reference heading. The summary's error is then the tracking error at the end time.
"""
from __future__ import annotations

import numpy as np

from .blocks.expression import compile_expression

REFERENCE_DEFAULTS = {"x_ref_expr": "0", "y_ref_expr": "0", "theta_ref_expr": "0"}


def reference_pose(start_values: dict, times: np.ndarray) -> np.ndarray:
    """The reference (x, y, theta) at `times`, shape 3 x n."""
    funcs = [compile_expression(str(start_values.get(k, d))) for k, d in REFERENCE_DEFAULTS.items()]
    return np.array([[f(float(t)) for t in times] for f in funcs]).reshape(3, len(times))


def reference_truth(start_values: dict, times: np.ndarray):
    from .ground_truth import Truth
    times = np.asarray(times, dtype=float)
    x, y, th = reference_pose(start_values, times)
    d = 1e-6 * np.maximum(1.0, np.abs(times))
    up = reference_pose(start_values, times + d)
    down = reference_pose(start_values, times - d)
    dx, dy, w = (up - down) / (2 * d)
    c, s = np.cos(th), np.sin(th)
    return Truth(times, x, y, th, c * dx + s * dy, -s * dx + c * dy, w)


def check_bundled_closed_loop(comp, model: str, value, own, bad, start: float) -> None:
    """Up-front checks (exit 2) of the values the closed-loop additions bring: Center2Wheel's
    w_max and PathFollower's gains and reference expressions."""
    from .blocks.expression import ExpressionError

    def place(name: str) -> str:
        return (f"{comp.place}.parameters.{name}" if name in comp.parameters
                else f"parameters.{name}")
    if model == "Center2Wheel" and "w_max" in own:
        w_max = value("w_max")
        if isinstance(w_max, (int, float)) and not (np.isfinite(w_max) and w_max >= 0):
            bad(place("w_max"), f"parameter w_max = {w_max!r} rad/s must be >= 0 "
                                "(0: no wheel speed limit)")
    if model != "PathFollower":
        return
    for name in ("k_pos", "k_theta"):
        gain = value(name) if name in own else None
        if isinstance(gain, (int, float)) and not (np.isfinite(gain) and gain > 0):
            bad(place(name), f"gain {name} = {gain!r} 1/s must be > 0 (the rate at which "
                             "the error decays; try 2)")
    for name in REFERENCE_DEFAULTS:
        text = value(name) if name in own else None
        if isinstance(text, str):
            try:
                compile_expression(text)(start)
            except ExpressionError as err:
                bad(place(name), str(err))
