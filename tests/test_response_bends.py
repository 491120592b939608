"""A kink inside an FMU's own equations, under the adaptive master: a third-party lag whose
input saturates, x' = -k x + sat(cos w t) (tests/fmu_sources/with_state/xtest_lag.py, `lim`),
against its closed form between the kinks. Where the held mean sits on the saturation's flat
side while the input leaves it within the step, neither the whole step nor its halves see the
bend: the step is taken again with the held inputs at their start and end values
(master/adaptive.py, _Loop._ends)."""
import math

import numpy as np
import pytest

from helpers import state_fmus, write_scenario
from mecanum_fmu import master, runner

K, LIM, STOP = 2.0, 0.5, 6.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    return state_fmus(tmp_path_factory.mktemp("state_fmus"), only=("xtest_wave", "xtest_lag"))


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


@pytest.mark.parametrize("omega, tolerance", [(2.0, 1e-4), (2.0, 1e-6), (3.0, 1e-6)])
def test_a_saturation_inside_an_fmu_holds_the_tolerance(tmp_path, fmus, omega, tolerance):
    # before: 2.26, 51.6 and 18.9 tolerances off, estimated at 0.18x, 0.007x and 0.016x
    path = write_scenario(tmp_path, "saturated", f"""\
name: saturated
experiment: {{start_time: 0.0, stop_time: {STOP}, step_size: 0.1, master: adaptive,
              tolerance: {tolerance}}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}, parameters: {{omega: {omega}}}}}
  it: {{fmu: {fmus["xtest_lag"]}, parameters: {{k: {K}, lim: {LIM}}}}}
connections: [[wave.u, it.u]]
outputs: [it.x]
""")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment)
    error = np.abs(results["it.x"] - _exact(results.time, omega))
    assert tolerance / 10 < error.max() <= tolerance
    estimate = results.extra["error_estimate"]["it.x"]
    assert error.max() / 3 <= estimate["max"] <= 3 * error.max()
    # the end on the safe side: the bends' errors are summed, not damped by the lag
    assert estimate["end"] >= error[-1] / 3
