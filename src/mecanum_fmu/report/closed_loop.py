"""Closed-loop scenarios: the ground truth of a PathFollower run is the reference it follows.

The reference pose comes from the follower's expressions (the same safe evaluator) or from its
recorded path (its tables.Table, with NumPy's interp: linear between rows); its rates (the
twist the plots show as "reference") are central differences of the expressions, or the
table's slopes (zero outside the table), in the body frame of the reference heading. The
summary's error is then the tracking error at the end time.
"""
from __future__ import annotations

import numpy as np

from ..models.blocks.expression import compile_expression
from .truth import Truth

REFERENCE = ("x_ref_expr", "y_ref_expr", "theta_ref_expr")


def _table_rates(table, times: np.ndarray) -> np.ndarray:
    """The slopes of the row interval each time lies in (a row's time: the interval after
    it), zero before the first row and from the last row on; 3 x n."""
    rows, *columns = table.path()
    i = np.searchsorted(rows, times, side="right") - 1
    inside = (i >= 0) & (i < len(rows) - 1)
    j = np.clip(i, 0, max(len(rows) - 2, 0))
    rates = np.zeros((3, len(times)))
    if len(rows) > 1:
        span = rows[j + 1] - rows[j]
        for k, c in enumerate(columns):
            rates[k] = np.where(inside, (c[j + 1] - c[j]) / span, 0.0)
    return rates


def _reference(follower, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reference (x, y, theta) of a PathFollower instance at `times` and its rates
    (dx, dy, w) in the world frame, 3 x n each."""
    if follower.table is not None:
        rates = _table_rates(follower.table, times)
        rows, *columns = follower.table.path()
        return np.array([np.interp(times, rows, c) for c in columns]), rates
    funcs = [compile_expression(str(follower.value(k))) for k in REFERENCE]

    def at(ts: np.ndarray) -> np.ndarray:
        return np.array([[f(float(t)) for t in ts] for f in funcs]).reshape(3, len(ts))
    d = 1e-6 * np.maximum(1.0, np.abs(times))
    return at(times), (at(times + d) - at(times - d)) / (2 * d)


def reference_truth(follower, times: np.ndarray) -> Truth:
    """The follower's reference as a Truth: its pose and its rates in the body frame of the
    reference heading."""
    times = np.asarray(times, dtype=float)
    (x, y, th), (dx, dy, w) = _reference(follower, times)
    c, s = np.cos(th), np.sin(th)
    return Truth(times, x, y, th, c * dx + s * dy, -s * dx + c * dy, w)
