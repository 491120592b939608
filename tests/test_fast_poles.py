"""Third-party FMUs whose response has a part that decays within one step, below the probes'
round-off: a stiff lag (x' = -k x + u, k h of 20 and more), and a spring whose poles are -1
and -100 (its speed). That part's moment is measured over steps of 1 / SUBSTEPS of the step
(master/probe.py, Target._faster), and the estimate follows the error against the lag's
solution in closed form and the spring's by scipy; the moment of such a pole against its
integral worked out here."""
import math
import re

import numpy as np
import pytest

from scipy.integrate import solve_ivp

from helpers import (assert_estimated, rewrite_description, state_fmus, with_experiment,
                     write_scenario)
from mecanum_fmu import master, runner
from mecanum_fmu.master.probe_fit import fast_logs, moment_of_log


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    return state_fmus(tmp_path_factory.mktemp("state_fmus"), only=(
        "xtest_wave", "xtest_lag", "xtest_spring", "xtest_triple", "xtest_through"))


def _lag(folder, fmus, k: float, master_name: str, fmu: str = "xtest_lag",
         outputs: str = "[it.x]"):
    return write_scenario(folder, "stiff", f"""\
name: stiff
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.2, master: {master_name}}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}}}
  it: {{fmu: {fmus[fmu]}, parameters: {{k: {k}}}}}
connections:
  - [wave.u, it.u]
outputs: {outputs}
""")


def _truth(t: np.ndarray, k: float) -> np.ndarray:
    """x' = -k x + cos t from x = 0."""
    return (k * np.cos(t) + np.sin(t) - k * np.exp(-k * t)) / (k * k + 1)


@pytest.mark.parametrize("master_name, k", [
    ("quadratic", 100.0), ("gauss-seidel", 100.0), ("jacobi", 100.0), ("trapezoidal", 100.0),
    ("quadratic", 1e5)])
def test_a_stiff_lag_is_estimated_with_its_pole_measured_over_substeps(tmp_path, fmus,
                                                                       master_name, k):
    # k h = 20: g1 = e^-20 g0 is below round-off, and r read 0, its moment 0 where it is
    # 0.45: the estimate read 0.04x the error under the quadratic master, 10x under
    # Gauss-Seidel. At k = 1e5 the substeps see no decay either (moment 1/2). Under
    # Gauss-Seidel the error is what is left of two terms of the input's slope that nearly
    # cancel, and the end's read 0.21x before the moment's second term (probe_fit.bend)
    graph, exp = with_experiment(runner.prepare(_lag(tmp_path, fmus, k, master_name)))
    results = master.simulate(graph, exp, with_estimate=True)
    summary = master.estimate_error(graph, results)
    assert "measured by probes" in summary["error_estimate_method"]
    error = np.abs(results["it.x"] - _truth(results.time, k))
    assert error.max() > 1e-9
    assert_estimated(summary, "it.x", error, 1.5)


@pytest.mark.parametrize("master_name", ["quadratic", "gauss-seidel"])
def test_an_output_that_reads_its_input_and_a_fast_state_keeps_the_state_s_error(
        tmp_path, fmus, master_name):
    # y = x + u, x' = -100 x + u, at 0.2 s: g1 is below round-off, and y's whole response
    # within the step was taken as its direct part, which errs by the held value against the
    # end value (nothing where the master holds the newest): y's estimate read 1e-6 of its
    # error. The part that moves without a doStep (u) is direct, the rest a fast state's
    path = _lag(tmp_path, fmus, 100.0, master_name, "xtest_through", "[it.x, it.y]")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    summary = master.estimate_error(graph, results)
    x = _truth(results.time, 100.0)
    for output, truth in (("it.x", x), ("it.y", x + np.cos(results.time))):
        error = np.abs(results[output] - truth)
        assert error.max() > 1e-5
        assert_estimated(summary, output, error, 1.5)


def test_a_fast_state_whose_dependencies_are_not_declared_is_not_read_as_exact(tmp_path, fmus):
    # the lag without its model description's dependencies, as pythonfmu writes it: the
    # probe at t0 found no trace of the move a step later (e^-20 of it) and took it for an
    # FMU without a state, whose outputs are exact: "below round-off" for an error of 1e-4.
    # Over a substep of h/64 the trace shows
    bare = rewrite_description(fmus["xtest_lag"], lambda xml: re.sub(
        r' dependencies="[^"]*"', "", xml), tmp_path / "lag_bare.fmu")
    graph = runner.prepare(_lag(tmp_path, dict(fmus, bare=bare), 100.0, "quadratic", "bare"))
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    summary = master.estimate_error(graph, results)
    assert "measured by probes" in summary["error_estimate_method"]
    error = np.abs(results["it.x"] - _truth(results.time, 100.0))
    assert error.max() > 1e-5
    assert_estimated(summary, "it.x", error, 1.5)


def test_a_fast_state_in_an_fmu_that_cannot_step_shorter_hands_over(tmp_path, fmus):
    # canHandleVariableCommunicationStepSize false: no substep is asked of it (one refused
    # with Error would fail the run); Richardson estimates instead, and says why
    fixed = rewrite_description(fmus["xtest_lag"], lambda xml: xml.replace(
        'canHandleVariableCommunicationStepSize="true"',
        'canHandleVariableCommunicationStepSize="false"'), tmp_path / "lag_fixed.fmu")
    graph = runner.prepare(_lag(tmp_path, dict(fmus, fixed=fixed), 100.0, "quadratic",
                                "fixed"))
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    method = master.estimate_error(graph, results)["error_estimate_method"]
    assert method.startswith("Richardson") and "cannot step shorter" in method, method


def test_a_substep_the_fmu_refuses_hands_over_and_the_run_goes_on(tmp_path, fmus):
    # the lag refuses steps under 0.01 s (Discard): the substep of h/64 is the probe's, not
    # the run's, and the model hands over to Richardson, saying which call and why
    path = write_scenario(tmp_path, "picky", _lag(tmp_path, fmus, 100.0, "quadratic")
                          .read_text().replace("k: 100.0}", "k: 100.0, min_step: 0.01}"))
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    assert results.complete and results.time[-1] == pytest.approx(6.0)
    method = master.estimate_error(graph, results)["error_estimate_method"]
    assert method.startswith("Richardson") and "returned discard over a step of h/64" in \
        method, method


@pytest.mark.parametrize("master_name", ["quadratic", "gauss-seidel"])
def test_a_spring_with_a_fast_pole_is_estimated_with_that_part_measured_over_substeps(
        tmp_path, fmus, master_name):
    # x'' + 101 x' + 100 x = cos t: poles -1 and -100. At 0.2 s the fast mode is gone
    # after a step, and one pole (the slow one) fits the speed's response; g0 holds the
    # fast mode's part too, which the slow pole's moment (0.017) weighed: the speed's
    # estimate read 0.03x its error under the quadratic master
    path = write_scenario(tmp_path, "overdamped", f"""\
name: overdamped
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.2, master: {master_name}}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}}}
  it: {{fmu: {fmus["xtest_spring"]}, parameters: {{c: 101.0, k: 100.0}}}}
connections:
  - [wave.u, it.u]
outputs: [it.x, it.v]
""")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    summary = master.estimate_error(graph, results)
    assert "measured by probes" in summary["error_estimate_method"]
    truth = solve_ivp(lambda t, y: [y[1], np.cos(t) - 100 * y[0] - 101 * y[1]],
                      (0.0, 6.0), [0.0, 0.0], t_eval=results.time, rtol=1e-12, atol=1e-14,
                      method="DOP853").y
    for output, row in zip(("it.x", "it.v"), truth):
        error = np.abs(results[output] - row)
        assert error.max() > 1e-6
        assert_estimated(summary, output, error, 1.5)


def _triple(folder, fmus, abc: tuple, h: float, master_name: str):
    """Three lags in a row fed cos t (xtest_triple, its a, b, c), and their solution by
    scipy."""
    a, b, c = abc
    path = write_scenario(folder, "triple", f"""\
name: triple
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: {h}, master: {master_name}}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}}}
  it: {{fmu: {fmus["xtest_triple"]}, parameters: {{a: {a}, b: {b}, c: {c}}}}}
connections:
  - [wave.u, it.u]
outputs: [it.x1, it.x2, it.x3]
""")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    truth = solve_ivp(lambda t, y: [np.cos(t) - a * y[0], y[0] - b * y[1], y[1] - c * y[2]],
                      (0.0, 6.0), [0.0] * 3, t_eval=results.time, rtol=1e-12, atol=1e-14,
                      method="DOP853").y
    return master.estimate_error(graph, results), {
        f"it.x{i + 1}": np.abs(results[f"it.x{i + 1}"] - row) for i, row in enumerate(truth)}


def test_a_fast_lag_inside_a_model_of_two_poles_keeps_its_part_of_the_error(tmp_path, fmus):
    # x1' = -300 x1 + u at 0.1 s: x1's response is gone after the step, and the model of
    # two poles (x2 and x3 need them) dropped g0's part that its poles do not carry on:
    # x1's estimate read "below round-off" for an error of 1.6e-4
    summary, errors = _triple(tmp_path, fmus, (300.0, 1.0, 2.0), 0.1, "quadratic")
    assert summary["error_estimate_method"].startswith("the embedded pair")
    for output, error in errors.items():
        assert error.max() > 1e-8
        assert_estimated(summary, output, error, 1.5)


def test_three_poles_that_two_poles_fit_to_1e_3_hand_over_to_richardson(tmp_path, fmus):
    # poles 0.99, 0.98 and 0.05 per step (c = 300 at 0.01 s): two poles fitted x3's response
    # to 8.6e-4 at g5, an oscillating pair whose miss grows to 0.19 at g20, and over 600
    # steps x3's estimate read 0.06x its error
    summary, errors = _triple(tmp_path, fmus, (1.0, 2.0, 300.0), 0.01, "gauss-seidel")
    assert summary["error_estimate_method"].startswith("Richardson"), \
        summary["error_estimate_method"]
    assert "is not of first or second order" in summary["error_estimate_method"]
    assert_estimated(summary, "it.x3", errors["it.x3"], 1.5)


def test_the_moment_of_a_fast_pole_is_its_integral():
    # m = int_0^1 e^(z t) (1/2 - t) dt / int_0^1 e^(z t) dt, by the trapezoid on 2e5 points
    t = np.linspace(0.0, 1.0, 200_001)
    for z in (-0.5, -20.0, -300.0):
        w = np.exp(z * t)
        f = w * (0.5 - t)
        expected = (f.sum() - (f[0] + f[-1]) / 2) / (w.sum() - (w[0] + w[-1]) / 2)
        assert moment_of_log(z) == pytest.approx(expected, rel=1e-6, abs=1e-9)
    assert moment_of_log(-math.inf) == 0.5


def test_substeps_give_the_pole_of_the_whole_step():
    # a lag's responses over two substeps of h / 64 to a unit held over the first:
    # g0 = (1 - r) / k, g1 = r g0, r = e^(-k h / 64); ln of the whole step's pole -k h
    k, h = 100.0, 0.2
    r = math.exp(-k * h / 64)
    g = np.array([[[(1 - r) / k]], [[r * (1 - r) / k]]])
    logs = fast_logs(g, np.full((1, 1), 1e-15))
    assert logs[0, 0] == pytest.approx(-k * h, rel=1e-12)
    assert fast_logs(g * np.array([[[1.0]], [[0.0]]]), np.full((1, 1), 1e-15))[0, 0] \
        == -math.inf
    assert np.isnan(fast_logs(np.array([[[1.0]], [[2.0]]]), np.full((1, 1), 1e-15))[0, 0])
