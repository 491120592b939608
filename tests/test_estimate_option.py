"""How a run's error is estimated, as the user chooses it (masters.ESTIMATES): `--estimate`,
`experiment.estimate` in a scenario or a sweep, prepare(estimate=...). "none" turns the
estimate off and says so; a wrong value or Richardson beside a tolerance is bad input (exit 2,
the place named)."""
import json

import pytest

from helpers import ROOT, run_main, with_experiment
from mecanum_fmu import master, runner
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.master.richardson import coarse_factors

CIRCLE = ROOT / "scenarios" / "circle.yaml"


def _summary(folder):
    return json.loads((folder / "summary.json").read_text())


def test_none_turns_the_estimate_off_and_says_so(tmp_path, capsys):
    code, out, _ = run_main(capsys, "run", CIRCLE, "--estimate", "none", "--no-plots",
                            "--out", tmp_path / "off")
    assert code == 0
    summary = _summary(tmp_path / "off")
    assert summary["error_estimate"] is None
    assert "turned off" in summary["error_estimate_method"]
    assert "turned off" in out
    # the run itself is the same run: its end point does not depend on the estimate
    code, _, _ = run_main(capsys, "run", CIRCLE, "--no-plots", "--out", tmp_path / "on")
    assert code == 0
    on = _summary(tmp_path / "on")
    assert set(on["error_estimate"]) >= {"pose.x", "pose.y"}
    assert (tmp_path / "on" / "results.csv").read_bytes() == \
        (tmp_path / "off" / "results.csv").read_bytes()


def test_the_pair_is_the_default_and_richardson_is_there_by_name():
    """auto on a fixed step is the embedded pair (no extra doStep); richardson by name still
    steps the two coarser runs; on the seed circle the two agree within 1.5x."""
    graph = runner.prepare(CIRCLE)
    results = master.simulate(graph, graph.scenario.experiment)
    auto = master.estimate_error(graph, results)
    named, exp = with_experiment(graph, estimate="richardson")
    by_name = master.estimate_error(named, results)
    r1, r2 = coarse_factors(graph, exp)
    assert auto["error_estimate_method"].startswith("the embedded pair")
    assert f"{r1} h and {r2} h" in by_name["error_estimate_method"]
    for axis in ("pose.x", "pose.y"):
        for which in ("max", "end"):
            a, b = auto["error_estimate"][axis][which], by_name["error_estimate"][axis][which]
            assert 1 / 1.5 < a / b < 1.5, (axis, which, a, b)


def test_the_python_api_takes_the_estimate():
    graph = runner.prepare(CIRCLE, estimate="none")
    results = master.simulate(graph, graph.scenario.experiment)
    assert master.estimate_error(graph, results)["error_estimate"] is None
    with pytest.raises(ScenarioError, match="unknown estimate 'off'.*auto, richardson, none"):
        runner.prepare(CIRCLE, estimate="off")


# each replaces the seed's `master: quadratic` line of its experiment
@pytest.mark.parametrize("lines,expected", [
    ("estimate: nonee", "experiment.estimate: unknown estimate 'nonee'; did you mean 'none'?"),
    ("estimate: 1", "experiment.estimate: unknown estimate 1"),
    ("tolerance: 1.0e-3\n  estimate: richardson",
     "experiment.estimate: the adaptive master estimates its error itself"),
])
def test_a_bad_estimate_in_a_file_is_exit_2_naming_the_place(tmp_path, capsys, lines,
                                                              expected):
    text = CIRCLE.read_text()
    assert "\n  master: quadratic" in text
    path = tmp_path / "bad.yaml"
    path.write_text(text.replace("\n  master: quadratic", "\n  " + lines))
    code, _, err = run_main(capsys, "validate", path)
    assert code == 2
    assert str(path) in err and expected in err
    assert "Traceback" not in err


def test_richardson_beside_a_command_line_tolerance_is_refused(tmp_path, capsys):
    code, _, err = run_main(capsys, "run", CIRCLE, "--tolerance", "1e-3", "--estimate",
                            "richardson", "--no-plots", "--out", tmp_path / "o")
    assert code == 2
    assert "experiment.estimate" in err and "drop the estimate richardson" in err
    assert not (tmp_path / "o" / "results.csv").exists()


def test_a_sweep_file_turns_the_estimate_off(tmp_path, capsys):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"scenario: {CIRCLE}\nexperiment: {{estimate: none, stop_time: 2.0}}\n"
                     "grid:\n  w2c.dR1: [0.0, 0.0003]\n")
    code, _, err = run_main(capsys, "sweep", sweep, "--out", tmp_path / "out", "--workers", "1",
                            "--no-plots")
    assert code == 0, err
    header = (tmp_path / "out" / "runs.csv").read_text().splitlines()[0]
    assert "pose.x" in header and "estimate." not in header
