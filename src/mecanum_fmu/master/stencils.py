"""The weights of the polynomial through a few values one step apart (the embedded pair's
stencils, pair_rows.py): its mean over a step and its values at the step's ends, as dot
products with the values; exact for polynomials of the stencil's degree."""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.polynomial import polynomial as P


@lru_cache(maxsize=64)
def _basis(nodes: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The Lagrange basis polynomials through `nodes` (positions in steps, relative to a
    step's start), as coefficient columns (lowest power first), and their antiderivatives;
    expanded in plain floats (at most four nodes: microseconds)."""
    columns = []
    for i, x in enumerate(nodes):
        poly = [1.0]
        for j, y in enumerate(nodes):
            if j != i:      # poly * (t - y) / (x - y)
                poly = [(a - y * b) / (x - y) for a, b in zip([0.0] + poly, poly + [0.0])]
        columns.append(poly)
    values = np.array(columns).T
    whole = np.array([[0.0] + [c / (k + 1) for k, c in enumerate(poly)] for poly in columns]).T
    return values, whole


def means(nodes: tuple[float, ...], lo, hi) -> np.ndarray:
    """Per node, its basis polynomial's integral over [lo, hi] (arrays of bounds: shape
    (bounds, nodes))."""
    whole = _basis(nodes)[1]
    return (P.polyval(np.asarray(hi, dtype=float), whole)
            - P.polyval(np.asarray(lo, dtype=float), whole)).T


def values(nodes: tuple[float, ...], x) -> np.ndarray:
    """Per node, its basis polynomial's value at x (shape (x, nodes))."""
    return P.polyval(np.asarray(x, dtype=float), _basis(nodes)[0]).T


FOUR = np.arange(4)     # a stencil's nodes


@lru_cache(maxsize=None)
def weight_table(offsets: int) -> np.ndarray:
    """For the nodes 0 .. m-1 one step apart (m = 1 .. 4) and offsets o = 0 .. offsets - 1:
    the weights of the mean over [o, o + 1] and of the values at o and o + 1, at
    (m - 1) offsets + o as rows, padded with zeros to four nodes: one gather and one
    product a batch. The Lagrange weights at o, o + 1/2 and o + 1 for every m at once (a
    node's own value its unit vector exactly), the mean by Simpson's rule, exact for a
    cubic (a few NumPy calls: a Python loop over the rows took most of a millisecond)."""
    m = np.arange(1, 5)[:, None, None, None]
    i, j = np.arange(4)[:, None], np.arange(4)
    x = (np.arange(offsets)[:, None] + np.array([0.0, 0.5, 1.0])).reshape(1, -1, 1, 1)
    factor = np.where((j != i) & (j < m), (x - j) / np.where(i == j, 1, i - j), 1.0)
    w = (factor.prod(axis=3) * (i[:, 0] < m[..., 0])).reshape(4, offsets, 3, 4)
    mean = (w[:, :, 0] + 4 * w[:, :, 1] + w[:, :, 2]) / 6
    return np.stack((mean, w[:, :, 0], w[:, :, 2]), axis=2).reshape(4 * offsets, 3, 4)
