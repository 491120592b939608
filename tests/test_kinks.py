"""A kink that no breakpoint announces, under the adaptive master: a third-party bouncing ball
(tests/fmu_sources/with_state/xtest_ball.py) whose height feeds a lag x' = -2 x + h, against
the ball's flights in closed form and the lag's ODE solved by scipy between the bounces. The
hold's polynomial through the values around a bounce is far from the height (a V between
two samples); the step is taken once more without the hold's estimated error there, and the
whole-step trajectory carries that error (master/adaptive.py, KINK)."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from helpers import assert_estimated, state_fmus, write_scenario
from mecanum_fmu import master, runner

G, E, K = 9.81, 0.7, 2.0        # xtest_ball's defaults, the lag's k


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    return state_fmus(tmp_path_factory.mktemp("state_fmus"))


def _flights(stop: float) -> list[tuple[float, float, float]]:
    """(start, height, speed) of each flight of the ball dropped from 1 m, until `stop` or
    it rests (a bounce under 1e-3 m/s)."""
    t, h, v, out = 0.0, 1.0, 0.0, []
    while t < stop:
        out.append((t, h, v))
        hit = (v + np.sqrt(v * v + 2 * G * h)) / G
        t, h, v = t + hit, 0.0, -E * (v - G * hit)
        if abs(v) < 1e-3:
            out.append((t, 0.0, 0.0))
            break
    return out


def _lag_truth(times: np.ndarray) -> np.ndarray:
    """The lag's x at `times`, solved flight by flight (no kink inside a solve)."""
    flights = _flights(times[-1])
    cuts = [f[0] for f in flights if f[0] < times[-1]] + [times[-1]]
    x, out = 0.0, np.empty(len(times))
    for (start, h, v), end in zip(flights, cuts[1:]):
        if end <= start:        # (bounces closer than round-off, as it comes to rest)
            continue
        height = (lambda t, h=h, v=v, s=start: h + v * (t - s) - 0.5 * G * (t - s) ** 2) \
            if (h, v) != (0.0, 0.0) else (lambda t: 0.0)
        at = (times >= start) & (times <= end)
        solved = solve_ivp(lambda t, y: [-K * y[0] + height(t)], (start, end), [x],
                           t_eval=times[at], rtol=1e-12, atol=1e-14, method="DOP853",
                           dense_output=True)
        if at.any():
            out[at] = solved.y[0]
        x = float(solved.sol(end)[0])
    return out


def _run(folder, fmus, stop: float, tolerance: float):
    path = write_scenario(folder, "ball", f"""\
name: ball
experiment: {{start_time: 0.0, stop_time: {stop}, step_size: 0.1, tolerance: {tolerance}}}
components:
  ball: {{fmu: {fmus["xtest_ball"]}}}
  lag: {{fmu: {fmus["xtest_lag"]}, parameters: {{k: {K}}}}}
connections:
  - [ball.h, lag.u]
outputs: [lag.x]
""")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    error = np.abs(results["lag.x"] - _lag_truth(results.time))
    assert tolerance / 10 < error.max() <= tolerance
    return master.estimate_error(graph, results), error


@pytest.mark.parametrize("tolerance", [1e-3, 1e-4])
def test_the_tolerance_holds_across_a_bouncing_balls_kinks(tmp_path, fmus, tolerance):
    # two bounces in 1.5 s. Before, the held means' errors at the bounces were in no step's
    # error: 1.63 and 3.13 tolerances off, estimated at 0.12x and 0.19x
    summary, error = _run(tmp_path, fmus, 1.5, tolerance)
    assert_estimated(summary, "lag.x", error, 1.5)


def test_a_ball_that_comes_to_rest_holds_the_tolerance_too(tmp_path, fmus):
    # bounces ever closer until 2.55 s, several in one step near the end: the largest
    # error within 3x, the end (a decayed error, 0.19x) not checked. Before: 1.65
    # tolerances off at 0.5 s, estimated at 0.15x
    summary, error = _run(tmp_path, fmus, 6.0, 1e-3)
    assert_estimated(summary, "lag.x", error, 3.0, end_factor=math.inf)
