"""An FMU that asks to end the simulation (FMI 2.0: fmi2DoStep returns fmi2Discard and
fmi2GetBooleanStatus(fmi2Terminated) is true, as the Reference FMUs' Stair does at 9 s; FMI
3.0: fmi3DoStep sets terminateSimulation): the run ends there, complete, exit 0, as FMPy and
the standard take it; summary.json says who ended it and when, and the estimate covers the run
to its end. The reference each time is the same graph run to that time with no FMU asking
(the plain stepping loop)."""
from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from helpers import (ending_fmus, read_csv, run_child, run_main, with_experiment,
                     write_scenario)
from mecanum_fmu import master
from mecanum_fmu.runner import prepare

FIXED = ("quadratic", "trapezoidal", "gauss-seidel", "jacobi")


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    return ending_fmus(tmp_path_factory)


def _scenario(folder: Path, name: str, stop_fmu: str, stop_time: float, t_end: float,
              master_name: str = "quadratic", short: bool = False) -> Path:
    """The FMU that ends the run beside the source -> pose chain (a ground truth), or, for the
    FMI 3.0 one, a lag fed by the source."""
    if stop_fmu == "CStop":
        ender = f"stop: {{fmu: CStop.fmu, parameters: {{t_end: {t_end}, short: {int(short)}}}}}"
        rest = "  pose: {fmu: PoseIntegrator}\n"
        links = "  - [src.vx, pose.vx]\n  - [src.vy, pose.vy]\n  - [src.w, pose.w]\n"
    else:
        ender = f"stop: {{fmu: X3testStop.fmu, parameters: {{t_end: {t_end}}}}}"
        rest, links = "", "  - [src.vx, stop.u]\n"
    text = (f"name: {name}\n"
            f"experiment: {{start_time: 0, stop_time: {stop_time}, step_size: 0.1, "
            f"master: {master_name}}}\n"
            "components:\n"
            f"  {ender}\n"
            "  src: {fmu: VelocitySource, parameters: {vx_expr: 'sin(t)', vy_expr: '0', "
            "w_expr: '0'}}\n" + rest + "connections:\n" + links)
    return write_scenario(folder, name, text)


def _run(capsys, folder: Path, scenario: Path, *options) -> tuple[int, str, dict, np.ndarray]:
    out = folder / f"out_{scenario.stem}"
    code, stdout, _ = run_main(capsys, "run", scenario, "--out", out, "--no-plots", *options)
    summary = json.loads((out / "summary.json").read_text())
    return code, stdout, summary, read_csv(out / "results.csv")[1]


@pytest.mark.parametrize("name", FIXED)
def test_an_fmu_that_ends_the_simulation_ends_the_run_complete_at_that_step(
        capsys, fmus, name):
    ended = _scenario(fmus, f"ends_{name}", "CStop", 2.0, 1.0, name)
    plain = _scenario(fmus, f"plain_{name}", "CStop", 1.0, 5.0, name)
    code, stdout, summary, rows = _run(capsys, fmus, ended)
    _, _, reference, expected = _run(capsys, fmus, plain)
    assert code == 0
    assert "ended early: stop asked to end the simulation" in stdout
    assert summary["complete"] is True and summary["end_time"] == 1.0
    assert "fmi2Terminated" in summary["ended_by"] and "t = 1 s" in summary["ended_by"]
    assert "ended_by" not in reference
    assert rows.shape == expected.shape
    np.testing.assert_allclose(rows, expected, rtol=1e-12, atol=1e-15)
    # the estimate covers the run to its end: the one of the run that stops there
    assert "the run to t = 1 s, where stop asked to end it" in summary["error_estimate_method"]
    for output in ("pose.x", "pose.y"):
        _same_estimate(summary["error_estimate"][output], reference["error_estimate"][output])
    # and the ground truth is compared at the run's own end
    assert summary["reference_end_pose"] == pytest.approx(reference["reference_end_pose"],
                                                          rel=1e-9, abs=1e-12)
    assert summary["error"]["position"] == pytest.approx(reference["error"]["position"],
                                                         rel=1e-6)


def test_a_step_that_stops_short_when_it_asks_to_end_is_a_failed_step(capsys, fmus):
    """fmi2LastSuccessfulTime at the step's start: a failed step, as pythonfmu's do_step that
    returns False says (fmi2Terminated true there too): exit 1, the rows up to it kept."""
    ended = _scenario(fmus, "ends_short", "CStop", 2.0, 1.0, short=True)
    plain = _scenario(fmus, "plain_short", "CStop", 0.9, 5.0)
    out = fmus / "out_ends_short"
    code, _, err = run_main(capsys, "run", ended, "--out", out, "--no-plots")
    _, _, _, expected = _run(capsys, fmus, plain)
    assert code == 1
    assert "component 'stop', t = 0.9 s: fmi2DoStep (the FMU terminated early) returned " \
        "Discard" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and "ended_by" not in summary
    np.testing.assert_allclose(read_csv(out / "results.csv")[1], expected, rtol=1e-12,
                               atol=1e-15)


def test_an_fmu_that_ends_at_the_stop_time_ends_a_plain_run(capsys, fmus):
    ended = _scenario(fmus, "ends_at_stop", "CStop", 1.0, 1.0)
    code, stdout, summary, rows = _run(capsys, fmus, ended)
    assert code == 0 and "ended early" not in stdout and "ended_by" not in summary
    assert summary["complete"] is True and rows[-1, 0] == 1.0
    assert "the run to t =" not in summary["error_estimate_method"]


@pytest.mark.parametrize("name", ("gauss-seidel", "jacobi"))
def test_an_fmi3_fmu_that_sets_terminate_simulation_ends_the_run(capsys, fmus, name):
    ended = _scenario(fmus, f"ends3_{name}", "X3testStop", 2.0, 1.0, name)
    plain = _scenario(fmus, f"plain3_{name}", "X3testStop", 1.0, 5.0, name)
    code, _, summary, rows = _run(capsys, fmus, ended)
    _, _, reference, expected = _run(capsys, fmus, plain)
    assert code == 0 and summary["complete"] is True and summary["end_time"] == 1.0
    assert "fmi3DoStep set terminateSimulation" in summary["ended_by"]
    np.testing.assert_allclose(rows, expected, rtol=1e-12, atol=1e-15)
    _same_estimate(summary["error_estimate"]["stop.x"], reference["error_estimate"]["stop.x"])


def test_the_adaptive_master_ends_at_the_last_row_before_the_step_that_asked(capsys, fmus):
    ended = _scenario(fmus, "ends3_adaptive", "X3testStop", 2.0, 1.0)
    code, _, summary, rows = _run(capsys, fmus, ended, "--tolerance", "1e-4")
    assert code == 0 and summary["complete"] is True
    assert summary["end_time"] < 1.0 and rows[-1, 0] == summary["end_time"]
    assert f"the run ends at t = {summary['end_time']:g} s" in summary["ended_by"]
    assert "which the run does not keep" in summary["ended_by"]
    # the rows are the lag's on the source's sin t, x' = -x + sin t, x(0) = 0, within the
    # tolerance's reach
    t = rows[:, 0]
    exact = 0.5 * (np.sin(t) - np.cos(t) + np.exp(-t))
    header = read_csv(fmus / "out_ends3_adaptive" / "results.csv")[0]
    true = np.abs(rows[:, header.index("stop.x")] - exact).max()
    assert true < 2e-4
    assert 1 / 3 < summary["error_estimate"]["stop.x"]["max"] / true < 3


def test_the_api_returns_a_complete_run_that_says_who_ended_it(fmus):
    graph = prepare(_scenario(fmus, "ends_api", "CStop", 2.0, 1.0, "gauss-seidel"))
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    assert results.complete and results.time[-1] == 1.0 and results.steps == 10
    assert results.ended_by.startswith("stop asked to end the simulation")
    found = master.estimate_error(graph, results)
    assert found["error_estimate"]["pose.x"]["max"] > 0
    rich = master.estimate_error(*_richardson(graph))
    assert rich["error_estimate"] is not None and "Richardson" in rich["error_estimate_method"]


def _same_estimate(found: dict, expected: dict) -> None:
    """The same "max" and "end": words alike, numbers to 1e-9."""
    for key in ("max", "end"):
        if isinstance(expected[key], str):
            assert found[key] == expected[key]
        else:
            assert found[key] == pytest.approx(expected[key], rel=1e-9)


def _richardson(graph):
    """The graph under --estimate richardson and its run."""
    graph, exp = with_experiment(graph, estimate="richardson")
    return graph, master.simulate(graph, exp)


def test_a_sweep_run_that_an_fmu_ends_is_ok_says_so_and_meets_the_truth_at_its_end(
        capsys, fmus):
    """runs.csv: the run's message says who ended it, and its end-point error is against the
    ground truth at its own end (the `run` of the same values gives the same)."""
    _scenario(fmus, "swept", "CStop", 2.0, 1.0)
    sweep = fmus / "ends_sweep.yaml"
    sweep.write_text("name: ends_sweep\nscenario: swept.yaml\n"
                     "grid:\n  stop.t_end: [1.0, 3.0]\n")
    done = run_child("sweep", sweep, "--out", fmus / "out_sweep", "--workers", "1",
                     "--no-plots")
    assert done.returncode == 0, done.stderr
    with open(fmus / "out_sweep" / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert rows[0]["message"].startswith("stop asked to end the simulation") and \
        "t = 1 s" in rows[0]["message"] and rows[1]["message"] == ""
    for row, stop_time, t_end in ((rows[0], 2.0, 1.0), (rows[1], 2.0, 3.0)):
        _, _, summary, _ = _run(capsys, fmus, _scenario(fmus, f"alone_{t_end:g}", "CStop",
                                                         stop_time, t_end))
        assert float(row["error.position"]) == pytest.approx(summary["error"]["position"],
                                                             rel=1e-9)
        assert float(row["pose.x"]) == summary["end_pose"]["x"]


def test_an_estimate_whose_run_made_again_ends_early_says_so(fmus):
    """Results that do not say the run ended early (an FMU whose end moved between runs; here
    the mark taken off): the run made again for the pair ends early, and the estimate says
    why it has none instead of failing."""
    graph = prepare(_scenario(fmus, "ends_again", "CStop", 2.0, 1.0, "gauss-seidel"))
    results = master.simulate(graph, graph.scenario.experiment)
    unmarked = dataclasses.replace(results, extra={})
    found = master.estimate_error(graph, unmarked)
    assert found["error_estimate"] is None
    # the pair's run made again ended (it fell to Richardson), and so did the coarser run
    assert "failed (stop asked to end it at t = 1 s)" in found["error_estimate_method"]
