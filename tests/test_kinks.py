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


def _solved(times: np.ndarray, flights: list, rates, start: list) -> np.ndarray:
    """An ODE whose `rates`(t, y, height) read the ball's height, solved flight by flight
    (no kink inside a solve) from `start`, at `times` (one row per state)."""
    cuts = [f[0] for f in flights if f[0] < times[-1]] + [times[-1]]
    y, out = np.array(start, dtype=float), np.empty((len(start), len(times)))
    for (begin, h, v), end in zip(flights, cuts[1:]):
        if end <= begin:        # (bounces closer than round-off, as it comes to rest)
            continue
        height = (lambda t, h=h, v=v, s=begin: h + v * (t - s) - 0.5 * G * (t - s) ** 2) \
            if (h, v) != (0.0, 0.0) else (lambda t: 0.0)
        at = (times >= begin) & (times <= end)
        solved = solve_ivp(lambda t, s, height=height: rates(t, s, height), (begin, end), y,
                           t_eval=times[at], rtol=1e-12, atol=1e-14, method="DOP853",
                           dense_output=True)
        if at.any():
            out[:, at] = solved.y
        y = solved.sol(end)
    return out


def _lag_truth(times: np.ndarray) -> np.ndarray:
    """The lag's x at `times`."""
    return _solved(times, _flights(times[-1]),
                   lambda t, y, height: [-K * y[0] + height(t)], [0.0])[0]


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


@pytest.mark.parametrize("tolerance", [1e-3, 1e-4])
def test_a_kink_held_into_an_error_model_is_in_its_error_too(tmp_path, fmus, fmu_dir,
                                                             tolerance):
    # the ball's height as a PoseIntegrator's turn rate (vx = 1): the pose's error model
    # takes the held mean's error from the hold (_VarBlend.error), which gave none at a kink.
    # Before, theta ended 2.31 and 1.26 tolerances off, estimated at 0.04x and 0.01x
    path = write_scenario(tmp_path, "turn", f"""\
name: turn
experiment: {{start_time: 0.0, stop_time: 1.5, step_size: 0.1, tolerance: {tolerance}}}
components:
  ball: {{fmu: {fmus["xtest_ball"]}}}
  source: {{fmu: VelocitySource, parameters: {{vx_expr: "1", vy_expr: "0", w_expr: "0"}}}}
  pose: {{fmu: PoseIntegrator}}
connections:
  - [source.vx, pose.vx]
  - [source.vy, pose.vy]
  - [ball.h, pose.w]
outputs: [pose.x, pose.y, pose.theta]
""")
    graph = runner.prepare(path, fmu_dir=fmu_dir)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    summary = master.estimate_error(graph, results)
    flights, t = _flights(1.5), results.time
    truth = _solved(t, flights, lambda s, y, height: [np.cos(y[2]), np.sin(y[2]), height(s)],
                    [0.0, 0.0, 0.0])
    for output, row in zip(("pose.x", "pose.y", "pose.theta"), truth):
        error = np.abs(results[output] - row)
        assert error.max() <= tolerance, (output, error.max())
        if error.max() > tolerance / 10:
            assert_estimated(summary, output, error, 3.0)
