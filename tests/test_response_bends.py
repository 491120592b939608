"""A kink inside an FMU's own equations, under the adaptive master: a third-party lag whose
input saturates, x' = -k x + sat(cos w t) (tests/fmu_sources/with_state/xtest_lag.py, `lim`),
against its closed form between the kinks. Where the held mean sits on the saturation's flat
side while the input leaves it within the step, neither the whole step nor its halves see the
bend, nor where the mean sits on the live side and part of the step on the flat one: the
step is taken again with the held inputs at their mean less and plus half their change, and
what is left of the two beyond a linear response is the bend's (master/adaptive.py,
bend_error)."""
import math

import numpy as np
import pytest

from helpers import assert_estimated, state_fmus, with_experiment, write_scenario
from mecanum_fmu import master, runner
from mecanum_fmu.master.adaptive import bend_error

K, LIM, STOP = 2.0, 0.5, 6.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    return state_fmus(tmp_path_factory.mktemp("state_fmus"),
                      only=("xtest_wave", "xtest_lag", "xtest_gain"))


def _exact(times: np.ndarray, omega: float) -> np.ndarray:
    """x at `times` from x(0) = 0, piece by piece between the times cos(omega t) crosses
    +-LIM: x = x_p + (x(t0) - x_p(t0)) e^(-K (t - t0)), x_p = +-LIM / K where the input
    saturates, else (K cos(omega t) + omega sin(omega t)) / (K^2 + omega^2)."""
    a = math.acos(LIM)
    phases = [p + 2 * math.pi * n for p in (a, math.pi - a, math.pi + a, 2 * math.pi - a)
              for n in range(int(omega * STOP / (2 * math.pi)) + 1)]
    edges = [0.0] + sorted(p / omega for p in phases if 0 < p / omega < STOP) + [STOP]
    out, x0 = np.empty_like(times), 0.0
    for t0, t1 in zip(edges[:-1], edges[1:]):
        u = math.cos(omega * 0.5 * (t0 + t1))
        flat = abs(u) > LIM
        particular = (lambda t, s=math.copysign(LIM, u): s / K + 0.0 * t) if flat else (
            lambda t: (K * np.cos(omega * t) + omega * np.sin(omega * t)) / (K * K + omega ** 2))
        inside = (times >= t0) & (times <= t1)
        out[inside] = particular(times[inside]) + (x0 - particular(t0)) * np.exp(
            -K * (times[inside] - t0))
        x0 = float(particular(t1) + (x0 - particular(t0)) * math.exp(-K * (t1 - t0)))
    return out


def _run(folder, fmus, tolerance: float, parts: str, stop: float = STOP):
    """(graph, results) of the adaptive master at `tolerance` on the components,
    connections and outputs in `parts` (FMU names in braces: the test FMUs'), 0 to `stop`
    at 0.1 s rows."""
    path = write_scenario(folder, "bends", f"""\
name: bends
experiment: {{start_time: 0.0, stop_time: {stop}, step_size: 0.1, master: adaptive,
              tolerance: {tolerance}}}
components:
{parts.format(**{k: str(v) for k, v in fmus.items()}, K=K, LIM=LIM)}
""")
    graph = runner.prepare(path)
    return graph, master.simulate(graph, graph.scenario.experiment)


SATURATED = """\
  wave: {{fmu: {xtest_wave}, parameters: {{omega: %s}}}}
  it: {{fmu: {xtest_lag}, parameters: {{k: {K}%s}}}}
connections: [[wave.u, it.u]]
outputs: [it.x]"""


@pytest.mark.parametrize("omega, tolerance", [(1.0, 1e-4), (2.0, 1e-4), (2.0, 1e-6),
                                              (3.0, 1e-4), (3.0, 1e-6)])
def test_a_saturation_inside_an_fmu_holds_the_tolerance(tmp_path, fmus, omega, tolerance):
    # before: 1.93, 2.26, 51.6, 5.10 and 18.9 tolerances off, estimated at 0.22x, 0.18x,
    # 0.007x, 0.07x and 0.016x
    graph, results = _run(tmp_path, fmus, tolerance, SATURATED % (omega, ", lim: {LIM}"))
    error = np.abs(results["it.x"] - _exact(results.time, omega))
    assert tolerance / 10 < error.max() <= tolerance
    summary = master.estimate_error(graph, results)
    assert_estimated(summary, "it.x", error, 2.0)
    # the input saturates from t = 0 (cos 0 = 1): the method says the bends were counted
    assert "went flat" in summary["error_estimate_method"]
    assert results.extra["flat_at"] < 0.5


def test_a_lag_that_never_saturates_takes_no_end_pass(tmp_path, fmus):
    # the same lag without a limit: no flat response, no pass more than the pair's (the
    # whole step and its halves per step tried, the whole-step trajectory's per step
    # taken), and the method says nothing of bends
    graph, results = _run(tmp_path, fmus, 1e-4, SATURATED % (2.0, ""))
    summary = master.estimate_error(graph, results)
    assert "flat_at" not in results.extra
    assert "went flat" not in summary["error_estimate_method"]
    tried = results.steps_taken + results.steps_rejected
    assert results.extra["passes"] == 3 * tried + results.steps_taken


def _integrator(response, below: float, above: float):
    """What an integrator x' = f(u), stepped over h = 1 with u held at `below` and `above`,
    moves x from u held at their mean (D-, D+), and the held mean's true error (held -
    true) where u moves linearly from `below` to `above` over the step (the mean of f(u),
    by a fine midpoint sum)."""
    mean = 0.5 * (below + above)
    u = below + (above - below) * (np.arange(100000) + 0.5) / 100000
    ends = (np.array([response(below) - response(mean)]),
            np.array([response(above) - response(mean)]))
    return ends, response(mean) - float(np.mean(response(u)))


def test_the_bend_error_of_a_saturation_on_either_side_of_it():
    saturated = lambda u: np.minimum(u, 0.5)     # noqa: E731
    # the mean on the live side (a third of the step on the flat one): exact
    ends, true = _integrator(saturated, 0.3, 0.6)
    assert bend_error(*ends, flat=False)[0] == pytest.approx(true, rel=1e-6)
    # the mean on the flat side (a third of the step on the live one): the bound, -K/2,
    # 1/f = 3x the error
    ends, true = _integrator(saturated, 0.4, 0.7)
    assert bend_error(*ends, flat=True)[0] == pytest.approx(3 * true, rel=1e-6)
    # a linear response: no bend; a smooth curvature's: K^2 of it, a small share of K
    ends, _ = _integrator(lambda u: 2.0 * u, 0.3, 0.6)
    assert abs(bend_error(*ends, flat=False)[0]) < 1e-15
    ends, _ = _integrator(np.square, 0.3, 0.31)
    assert abs(bend_error(*ends, flat=False)[0]) < 0.02 * abs(ends[0][0] + ends[1][0])


def test_a_staircase_into_a_saturation_runs_and_says_the_estimate_is_unresolved(tmp_path,
                                                                                 fmus):
    # a stair holds the input still over whole steps, where no end pass is taken: it used
    # to end in a TypeError once a flat response was found
    _, results = _run(tmp_path, fmus, 1e-3, SATURATED.replace("%s}}", "%s, period: 0.3}}", 1)
                      % (2.0, ", lim: {LIM}"))
    assert results.time[-1] == STOP
    assert results.extra["error_estimate"]["it.x"]["max"].startswith("unresolved")


def test_a_saturation_inside_a_loop_holds_the_tolerance(tmp_path, fmus):
    # the lag under a P controller, u = 3 (cos t - x), saturating at 0.5; the truth: the
    # quadratic master at 1/256 of the output interval. Before: 8.71 tolerances off,
    # estimated at 0.02x
    graph, results = _run(tmp_path, fmus, 1e-4, """\
  wave: {{fmu: {xtest_wave}}}
  ctrl: {{fmu: {xtest_gain}, parameters: {{kp: 3.0}}}}
  it: {{fmu: {xtest_lag}, parameters: {{k: {K}, lim: {LIM}}}}}
connections: [[wave.u, ctrl.r], [it.x, ctrl.y], [ctrl.u, it.u]]
outputs: [it.x]""", stop=10.0)
    fine, exp = with_experiment(graph, step_size=0.1 / 256, master="quadratic", tolerance=None,
                                estimate="none")
    truth = master.simulate(fine, exp)
    on_rows = np.isin(np.round(truth.time, 9), np.round(results.time, 9))
    error = np.abs(results["it.x"] - truth["it.x"][on_rows])
    assert error.max() <= 1e-4
    estimate = results.extra["error_estimate"]["it.x"]["max"]
    assert error.max() / 3 <= estimate <= 3 * error.max()


def test_a_saturation_beside_a_live_fmu_is_seen(tmp_path, fmus):
    # a second lag on the same wave never saturates: the bends are looked for per output.
    # Before, with every output of the held FMUs to go flat at once: 1.85 tolerances off,
    # estimated at 0.15x (before this session too)
    graph, results = _run(tmp_path, fmus, 1e-4, """\
  wave: {{fmu: {xtest_wave}, parameters: {{omega: 3.0}}}}
  it: {{fmu: {xtest_lag}, parameters: {{k: {K}, lim: {LIM}}}}}
  free: {{fmu: {xtest_lag}, parameters: {{k: 1.0}}}}
connections: [[wave.u, it.u], [wave.u, free.u]]
outputs: [it.x, free.x]""")
    error = np.abs(results["it.x"] - _exact(results.time, 3.0))
    assert error.max() <= 1e-4
    assert_estimated(master.estimate_error(graph, results), "it.x", error, 3.0)


def test_an_output_the_halves_cannot_see_is_asked_once(tmp_path, fmus):
    # a PI controller's u: its halves integrate the same held means as the whole step, so
    # the halves never move it, while the end passes move it by as much either way (a
    # linear response): asked once (4 passes), not at every step. Before: 581 passes where
    # the pair takes 289
    graph, results = _run(tmp_path, fmus, 1e-3, """\
  wave: {{fmu: {xtest_wave}}}
  c: {{fmu: {xtest_gain}, parameters: {{kp: 2.0, ki: 1.0}}}}
  a: {{fmu: {xtest_lag}, parameters: {{k: {K}}}}}
connections: [[wave.u, c.r], [c.u, a.u]]
outputs: [a.x, c.u]""")
    tried = results.steps_taken + results.steps_rejected
    assert results.extra["passes"] == 3 * tried + results.steps_taken + 4
    assert "flat_at" not in results.extra
