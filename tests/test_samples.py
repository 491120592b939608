"""A discrete output (a sample) read by an FMU with continuous outputs, under the masters that
hold samples (masters.Master.holds_samples: quadratic, trapezoidal): the reader steps on the
sample's value at the step's start, the value it holds over the step, and after a sample
changes the master reads the reader's outputs again (stepping.settle), so that an integrator
downstream integrates a sampled-and-held input exactly. Third-party style FMUs
(tests/fmu_sources/sampled), references from the closed forms."""
from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest

from mecanum_fmu import master, runner

from helpers import ROOT, cli_args, with_experiment, write_scenario
from helpers import declare_no_dependencies

SOURCES = ROOT / "tests" / "fmu_sources" / "sampled"
PERIOD, STOP = 0.1, 2.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """The sampler, the ramp y = s + t and the integrator (its x declared free of u)."""
    from pythonfmu import FmuBuilder
    dest = tmp_path_factory.mktemp("sampled_fmus")
    built = {script.stem: FmuBuilder.build_FMU(script, dest=dest, canGetAndSetFMUstate=True)
             for script in sorted(SOURCES.glob("stest_*.py"))}
    declare_no_dependencies(built["stest_integral"])
    return built


def _scenario(folder, fmus, master_name: str):
    return write_scenario(folder, "sampled", f"""\
name: sampled
experiment: {{start_time: 0.0, stop_time: {STOP}, step_size: {PERIOD}, master: {master_name}}}
components:
  sampler: {{fmu: {fmus["stest_sampler"]}, parameters: {{period: {PERIOD}}}}}
  ramp: {{fmu: {fmus["stest_ramp"]}}}
  integral: {{fmu: {fmus["stest_integral"]}}}
connections:
  - [sampler.s, ramp.s]
  - [ramp.y, integral.u]
""")


def _sample(t: float) -> float:
    """The held sample at t: sin(t_j), t_j the last sample time at or before t."""
    return math.sin(math.floor(t / PERIOD + 1e-9) * PERIOD)


def _integral(t: float) -> float:
    """x(t) = the integral of s + tau from 0 to t, s held between samples."""
    j = math.floor(t / PERIOD + 1e-9)
    held = sum(math.sin(i * PERIOD) * PERIOD for i in range(j))
    return held + _sample(t) * (t - j * PERIOD) + t * t / 2


@pytest.mark.parametrize("master_name", ["quadratic", "trapezoidal"])
@pytest.mark.parametrize("divide", [1, 2, 4])
def test_a_sampled_and_held_input_is_integrated_exactly(tmp_path, fmus, master_name, divide):
    graph = runner.prepare(_scenario(tmp_path, fmus, master_name))
    graph, exp = with_experiment(graph, step_size=PERIOD / divide, estimate="none")
    res = master.simulate(graph, exp)
    truth = np.array([_integral(t) for t in res.time])
    assert np.max(np.abs(res["integral.x"] - truth)) < 1e-12
    # every row shows the reader's output after the sample of its own time (the right value)
    ramp = np.array([_sample(t) + t for t in res.time])
    assert np.max(np.abs(res["ramp.y"] - ramp)) < 1e-12
    assert np.array_equal(res["sampler.s"], [_sample(t) for t in res.time])


def test_gauss_seidel_reads_the_newest_sample_a_step_early(tmp_path, fmus):
    """Gauss-Seidel holds every input at its newest value, a sample's too (docs/masters.md):
    over [t_k, t_k+1] the ramp sees the sample of t_k+1, and the integral is the right
    Riemann sum of s + t at the samples, an error of the first order."""
    graph = runner.prepare(_scenario(tmp_path, fmus, "gauss-seidel"))
    graph, exp = with_experiment(graph, estimate="none")
    res = master.simulate(graph, exp)
    t = res.time
    right = np.concatenate(([0.0], np.cumsum([(_sample(b) + b) * (b - a)
                                               for a, b in zip(t, t[1:])])))
    assert np.max(np.abs(res["integral.x"] - right)) < 1e-12
    truth = np.array([_integral(x) for x in t])
    assert abs(res["integral.x"][-1] - truth[-1]) > 0.05      # about h/2 per unit of time


def test_by_name_richardson_repeats_a_sampled_run_at_half_the_step(tmp_path, fmus):
    """A coarser step would move the samples; `--estimate richardson` repeats the run at h/2,
    which keeps them. Gauss-Seidel's error here is first order (the right Riemann sum): the
    estimate's largest value is within 3x of the closed form's; the quadratic master's run is
    exact, and so is its estimate (below round-off). Under `auto` the pair leaves every
    output made from the samples unresolved, and says how to get a number."""
    path = _scenario(tmp_path, fmus, "gauss-seidel")
    graph, exp = with_experiment(runner.prepare(path), estimate="richardson")
    res = master.simulate(graph, exp)
    found = master.estimate_error(graph, res)
    assert "repeated at h/2" in found["error_estimate_method"]
    error = np.abs(res["integral.x"] - np.array([_integral(t) for t in res.time]))
    estimate = found["error_estimate"]["integral.x"]["max"]
    assert error.max() / 3 <= estimate <= 3 * error.max(), (estimate, error.max())
    graph, exp = with_experiment(runner.prepare(_scenario(tmp_path, fmus, "quadratic")),
                                 estimate="richardson")
    found = master.estimate_error(graph, master.simulate(graph, exp))
    assert found["error_estimate"]["integral.x"] == {"max": "below round-off",
                                                     "end": "below round-off"}
    graph = runner.prepare(path)
    found = master.estimate_error(graph, master.simulate(graph, graph.scenario.experiment))
    for name in ("ramp.y", "integral.x"):
        for which in ("max", "end"):
            words = found["error_estimate"][name][which]
            assert words.startswith("unresolved (StestSampler sample at their own period")
            assert "--estimate richardson repeats the run at h/2" in words


def test_the_adaptive_master_refuses_fmus_that_sample(tmp_path, fmus):
    """Each sample is a jump inside some step, which the adaptive master's step control
    would shrink the step to bracket until it stopped at the first sample: a tolerance on a
    graph with samples is refused before anything runs, naming the sampling FMUs, for a
    third-party sampler and for the bundled sensors, from the API (also when the experiment
    is changed after the graph is compiled) and from the command line (exit 2, one message)."""
    from mecanum_fmu.errors import ScenarioError
    with pytest.raises(ScenarioError, match="adaptive master cannot step StestSampler"):
        runner.prepare(_scenario(tmp_path, fmus, "quadratic"), tolerance=1e-4)
    graph = runner.prepare(_scenario(tmp_path, fmus, "quadratic"))
    graph, exp = with_experiment(graph, master="adaptive", tolerance=1e-4)
    with pytest.raises(ScenarioError, match="choose a fixed-step master"):
        master.simulate(graph, exp)
    belief = ROOT / "scenarios" / "robot" / "belief_track_circle.yaml"
    proc = subprocess.run(cli_args("run", str(belief), "--tolerance", "1e-3", "--no-plots",
                                   "--out", str(tmp_path / "out")),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "the adaptive master cannot step Encoder, Odometry" in proc.stderr
    # the place is the option that chose the adaptive master, not a key the file lacks
    assert f"{belief}: experiment.tolerance (or --tolerance): " in proc.stderr, proc.stderr
    assert proc.stderr.rstrip().endswith("and drop the tolerance")
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("master_name", ["quadratic", "trapezoidal"])
def test_a_sample_into_a_state_is_held_not_blended(tmp_path, fmus, master_name):
    """The sampler straight into the integrator (a state-only input, which these masters
    otherwise blend): x is the sum of the held samples, exactly; a trapezoid or a parabola
    through the samples would have taken the next sample half a step early."""
    text = _scenario(tmp_path, fmus, master_name).read_text()
    text = text.replace("  - [sampler.s, ramp.s]\n  - [ramp.y, integral.u]\n",
                        "  - [sampler.s, integral.u]\n  - [sampler.s, ramp.s]\n")
    graph = runner.prepare(write_scenario(tmp_path, "direct", text))
    graph, exp = with_experiment(graph, estimate="none")
    res = master.simulate(graph, exp)
    held = np.array([sum(math.sin(i * PERIOD) * PERIOD for i in range(round(t / PERIOD)))
                     for t in res.time])
    assert np.max(np.abs(res["integral.x"] - held)) < 1e-12


def test_validate_names_the_samples_it_holds(capsys):
    """`validate` says which links carry a sample held from the step's start and which FMUs
    are read again after each sample; nothing where no sample is held."""
    from mecanum_fmu import cli
    belief = ROOT / "scenarios" / "robot" / "belief_track_circle.yaml"
    assert cli.main(["validate", str(belief)]) == 0
    out = capsys.readouterr().out
    assert ("samples held from the step's start: odom -> follower; read again after each "
            "sample: follower, c2w, w2c") in out
    assert cli.main(["validate", str(ROOT / "scenarios" / "circle.yaml")]) == 0
    assert "samples held" not in capsys.readouterr().out


def test_a_sweep_that_asks_a_tolerance_of_a_graph_with_samples_is_refused(tmp_path, capsys):
    """The sweep's own `experiment:` chooses the adaptive master for every run: refused when
    the sweep is read (exit 2, naming the sweep file), not run by run."""
    from mecanum_fmu import cli
    belief = ROOT / "scenarios" / "robot" / "belief_track_circle.yaml"
    sweep = write_scenario(tmp_path, "sweep", f"name: belief_tol\nscenario: {belief}\n"
                           "experiment: {stop_time: 1.0, tolerance: 1.0e-3}\n"
                           "grid:\n  w2c.dR1: [0.0, 0.0003]\n")
    assert cli.main(["sweep", str(sweep), "--workers", "1", "--no-plots",
                     "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out" / "runs.csv").exists()
    assert (f"{sweep}: experiment: the adaptive master cannot step Encoder, Odometry"
            in capsys.readouterr().err)
