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
    """step_weights's weights for m = 1 .. 4 nodes and offsets 0 .. offsets - 1, at
    (m - 1) offsets + o, padded with zeros to four nodes: one gather and one product a
    batch."""
    table = np.zeros((4 * offsets, 3, 4))
    for m in range(1, 5):
        for o in range(offsets):
            table[(m - 1) * offsets + o, :, :m] = step_weights(m, o)
    return table


@lru_cache(maxsize=None)
def step_weights(m: int, o: int) -> np.ndarray:
    """For the nodes 0 .. m-1 one step apart: the weights of the mean over [o, o + 1] and of
    the values at o and o + 1, as rows (Horner's rule on the basis: a few microseconds, where
    polyval's array set-up took a millisecond for the table)."""
    basis, whole = _basis(tuple(float(i) for i in range(m)))

    def at(x: int) -> list[float]:      # a node's own value exactly: its unit vector
        return [float(i == x) if x < m else _horner(basis[:, i], float(x)) for i in range(m)]
    return np.array([[_horner(whole[:, i], o + 1.0) - _horner(whole[:, i], float(o))
                      for i in range(m)], at(o), at(o + 1)])


def _horner(coefficients: np.ndarray, x: float) -> float:
    value = 0.0
    for c in coefficients[::-1].tolist():
        value = value * x + c
    return value
