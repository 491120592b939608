"""A loop that closes through an FMU without a state into another FMU with a state than the
one whose error it carries (master/pair.py, _carried_on): two third-party lags in a row,
x1' = -x1 + u, x2' = -2 x2 + x1, the second's x2 into a P controller u = 3 (cos t - x2) that
feeds the first. The pair carried the second lag's error through the controller and dropped
it where the first lag, which steps before the controller, reads it: its end came out 3.7x
to 133x off the truth (solved here by scipy). It hands over to Richardson now, and says why."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from helpers import state_fmus, write_scenario
from mecanum_fmu import master, runner


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    return state_fmus(tmp_path_factory.mktemp("state_fmus"))


@pytest.mark.parametrize("master_name", ["quadratic", "gauss-seidel"])
def test_a_loop_back_into_an_earlier_lag_hands_over_and_says_why(tmp_path, fmus, master_name):
    path = write_scenario(tmp_path, "two_lags", f"""\
name: two_lags
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.1, master: {master_name}}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}}}
  ctrl: {{fmu: {fmus["xtest_gain"]}, parameters: {{kp: 3.0}}}}
  one: {{fmu: {fmus["xtest_lag"]}, parameters: {{k: 1.0}}}}
  two: {{fmu: {fmus["xtest_lag"]}, parameters: {{k: 2.0}}}}
connections: [[wave.u, ctrl.r], [two.x, ctrl.y], [ctrl.u, one.u], [one.x, two.u]]
outputs: [one.x, two.x]
""")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    summary = master.estimate_error(graph, results)
    method = summary["error_estimate_method"]
    assert method.startswith("Richardson") and "ctrl.u carries an error into one" in method, \
        method
    truth = solve_ivp(lambda t, y: [-y[0] + 3.0 * (np.cos(t) - y[1]), -2.0 * y[1] + y[0]],
                      (0.0, 6.0), [0.0, 0.0], t_eval=results.time, rtol=1e-12, atol=1e-14,
                      method="DOP853").y
    for output, want in zip(("one.x", "two.x"), truth):
        error = np.abs(results[output] - want)
        for which, value in (("max", error.max()), ("end", error[-1])):
            estimate = summary["error_estimate"][output][which]
            assert value / 3 <= estimate <= 3 * value, (output, which, estimate, value)
