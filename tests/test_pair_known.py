"""The tables' signals the embedded pair reads where a table's rows are closer than two steps
(master/pair_known.py): their means and one-sided values against quadrature of an independent
interpolation, and the map fitted from them to the run's columns, kept only where it holds."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import quad

from mecanum_fmu.master.pair_known import KnownInputs
from mecanum_fmu.scenario.tables import Known

TIMES = np.array([0.0, 0.05, 0.1, 0.15, 0.2, 0.27])
VALUES = np.array([[0.0, 1.0], [0.3, 1.0], [-0.2, 1.5], [0.4, 0.5], [0.1, 0.7], [0.6, -0.2]])
EXP = SimpleNamespace(start_time=-0.02, stop_time=0.36, step_size=0.04)     # 10 steps


def _inputs(hold: bool) -> KnownInputs:
    return KnownInputs((Known(TIMES, VALUES, hold),), EXP, 10, 0.5)    # 9.5 steps


def _truth(t: float, column: int, hold: bool) -> float:
    """The table's value at t as the FMU reads it: its first and last rows' before and after
    it, linear between its rows or each row's value until the next."""
    if hold:
        return float(VALUES[max(0, np.searchsorted(TIMES, t, side="right") - 1), column])
    return float(np.interp(t, TIMES, VALUES[:, column]))


@pytest.mark.parametrize("hold", [False, True])
def test_means_over_steps_across_rows_and_past_the_table(hold):
    known = _inputs(hold)
    t0 = np.array([-0.02, 0.02, 0.07, 0.14, 0.26, 0.3])
    t1 = t0 + np.array([0.04, 0.04, 0.04, 0.08, 0.04, 0.06])
    found = (known.integrals(t1) - known.integrals(t0)) / (t1 - t0)[:, None]
    for i, (a, b) in enumerate(zip(t0, t1)):
        for c in range(2):
            mean = quad(_truth, a, b, args=(c, hold), points=TIMES, limit=200)[0] / (b - a)
            assert found[i, c] == pytest.approx(mean, abs=1e-12)


def test_a_held_tables_value_at_a_row_from_either_side():
    known = _inputs(True)
    at = np.array([0.1])
    assert known.signals(at, right=True)[0].tolist() == VALUES[2].tolist()
    assert known.signals(at, right=False)[0].tolist() == VALUES[1].tolist()


def _window(known: KnownInputs, columns, d: int = 0) -> np.ndarray:
    """Rows 0 .. n of columns made from the signals at the nodes, late by d rows."""
    nodes = np.maximum(np.arange(11) - d, 0)
    s = known.signals(known.time(nodes), True)
    return np.column_stack([f(s) for f in columns])


def test_a_linear_map_of_the_signals_is_fitted_and_gives_its_means():
    known = _inputs(False)
    linear = lambda s: 2.0 * s[:, 0] - s[:, 1] + 0.5     # noqa: E731
    window = _window(known, [linear], d=2)
    fits = known.check(window, 0, 2, np.array([0]), np.array([True]))
    assert fits.tolist() == [True] and known.failed is None and known.told()
    ks = np.arange(10)
    mean, start, end = known.stencils(known.designs(ks), 2)
    t0, t1 = known.time(ks), known.time(ks + 1)
    want = [quad(lambda t: 2 * _truth(t, 0, False) - _truth(t, 1, False) + 0.5, a, b,
                 points=TIMES)[0] / (b - a) for a, b in zip(t0, t1)]
    assert mean[:, 0] == pytest.approx(want, abs=1e-12)
    assert start[:, 0] == pytest.approx(linear(known.signals(t0, True)), abs=1e-12)
    assert end[:, 0] == pytest.approx(linear(known.signals(t1, False)), abs=1e-12)


def test_a_column_that_is_no_linear_map_fails_only_where_it_is_held():
    known = _inputs(False)
    window = _window(known, [lambda s: s[:, 0], lambda s: s[:, 0] ** 2])
    fits = known.check(window, 0, 0, np.array([0, 1]), np.array([True, False]))
    assert fits.tolist() == [True, False]
    assert known.failed is None and not known.told()     # a late output: read at the nodes
    again = _inputs(False)
    again.check(window, 0, 0, np.array([0, 1]), np.array([True, True]))
    assert again.failed is not None and "not a fixed linear map" in again.failed


def test_too_few_rows_to_tell_the_map_fail_with_their_own_words():
    known = _inputs(False)
    window = _window(known, [lambda s: s[:, 0]])[:2]        # 2 rows, 3 unknowns
    known.check(window, 0, 0, np.array([0]), np.array([True]))
    assert known.failed is not None and "too few" in known.failed
