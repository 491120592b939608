"""The one evaluation stage (report.evaluation): every pose is held against the truth of what
drives it, a failing truth costs only itself, and saturated wheels are named as the cause.

Reference values are computed here, independently of the code under test: closed-form arcs of a
constant twist (docs/spec.md, Pose integration), the wheel matrix of docs/spec.md with the
w_max rule of docs/closed-loop.md, and the reference path's own derivative.
"""
from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT, SPEC_END, child_env, run_child
from mecanum_fmu import cli, runner

COMPARE = ROOT / "scenarios" / "chassis" / "compare.yaml"
FIGURE_EIGHT = ROOT / "scenarios" / "closed_loop" / "track_figure_eight.yaml"
CIRCLE = ROOT / "scenarios" / "circle.yaml"
COMMAND = 'command:      {fmu: VelocitySource, parameters: {vx_expr: "0.3*sin(t)", vy_expr: "0.5", w_expr: "0.3"}}'
# defined at every communication point (0.01 s apart) but not within 1e-4 s of t = 0.005:
# the FMUs never see the gap, the ground-truth solver does
BETWEEN = "sqrt(abs(t-0.005)-0.0001)"


def with_command(tmp_path: Path, command: str, name: str = "compare") -> Path:
    text = COMPARE.read_text()
    assert COMMAND in text
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.replace(COMMAND, command))
    return path


def arcs(segments, start=(0.0, 0.0, 0.0)):
    """The end pose after constant body twists (vx, vy, w, duration), in closed form:
    body +Y forward, world velocity R(theta) (vx, vy), theta' = w."""
    x, y, th = start
    for vx, vy, w, d in segments:
        if abs(w) < 1e-12:
            dx, dy = vx * d, vy * d
        else:                # the body displacement of an arc, then turned by the heading
            dx = (vx * math.sin(w * d) - vy * (1 - math.cos(w * d))) / w
            dy = (vy * math.sin(w * d) + vx * (1 - math.cos(w * d))) / w
        c, s = math.cos(th), math.sin(th)
        x, y, th = x + c * dx - s * dy, y + s * dx + c * dy, th + w * d
    return x, y, th


def spec_wheels(vx, vy, w, alpha=math.pi / 4, L=0.16, W=0.12, R=0.06):
    """docs/spec.md, Inverse kinematics (matrix form): wheels = (1/R) A (vx, vy, w)."""
    c = 1 / math.tan(alpha)
    k = L + W * c
    return np.array([[-c, 1, k], [c, 1, -k], [-c, 1, -k], [c, 1, k]]) @ [vx, vy, w] / R


def spec_end(twist, t_end: float, w_max: float = 0.0, n: int = 400_000,
             vectorised: bool = False):
    """The end pose of the spec's pose ODE under twist(t) -> (vx, vy, w) on a fine grid
    (trapezoid rule, error ~1e-9 here); with w_max the wheel speeds of the spec's matrix are
    scaled down together (docs/closed-loop.md) and turned back by its least-squares inverse.
    `vectorised`: twist takes the whole grid at once (np.interp gives the same numbers for an
    array as point by point, without 400,001 Python calls)."""
    t = np.linspace(0.0, t_end, n + 1)
    body = (np.column_stack(twist(t)) if vectorised
            else np.array([twist(float(ti)) for ti in t]))
    if w_max:
        A = np.array([spec_wheels(*e) for e in np.eye(3)]).T * 0.06     # (1/R) A, times R
        wheels = body @ A.T / 0.06
        scale = np.minimum(1.0, w_max / np.maximum(np.abs(wheels).max(axis=1), 1e-300))
        body = (wheels * scale[:, None]) @ np.linalg.pinv(A).T * 0.06
    h = t_end / n
    theta = np.concatenate(([0.0], np.cumsum((body[1:, 2] + body[:-1, 2]) / 2 * h)))
    c, s = np.cos(theta), np.sin(theta)
    world = np.column_stack((c * body[:, 0] - s * body[:, 1], s * body[:, 0] + c * body[:, 1]))
    x, y = (np.sum((world[1:, i] + world[:-1, i]) / 2) * h for i in (0, 1))
    return float(x), float(y), float(theta[-1])


def test_references_agree():
    """The two references above (closed-form arcs, the fine grid) agree."""
    segs = [(0.1, 0.5, 0.3, 2.0), (-0.2, 0.1, -0.7, 1.5)]
    twist = lambda t: segs[0][:3] if t < 2.0 else segs[1][:3]
    np.testing.assert_allclose(spec_end(twist, 3.5, n=700_000), arcs(segs), atol=1e-5)


def test_several_chassis_with_segments_are_held_against_their_own_truth(fmu_dir, tmp_path):
    """compare.yaml driven by `segments:`: the mecanum and omni poses against the segments'
    arcs (not the seed's circle), the car against its steering command's circle. (A jump of a
    hold profile costs the co-simulation about h/2 of it: h = 0.001 for a match at 3 decimals.)"""
    segs = [(0.0, 0.5, 0.3, 2.0), (0.1, 0.5, 0.2, 2.0)]
    text = ("command:      {fmu: VelocitySource, segments: [{duration: 2, vy: 0.5, w: 0.3}, "
            "{duration: 3, vx: 0.1, vy: 0.5, w: 0.2}]}")
    graph = runner.prepare(with_command(tmp_path, text), fmu_dir=fmu_dir, step_size=0.001,
                           stop_time=4.0)
    out = runner.run(graph, tmp_path / "out", plots=False)
    poses = out.summary["poses"]
    expected = arcs(segs)
    for name in ("mecanum_pose", "omni_pose"):
        assert poses[name]["match"], poses[name]
        ref = poses[name]["reference_end_pose"]
        np.testing.assert_allclose([ref["x"], ref["y"], ref["theta"]], expected, atol=1e-7)
    car = poses["car_pose"]          # v = 0.5, phi = atan(0.3): a circle of radius 0.5/0.3
    np.testing.assert_allclose([car["reference_end_pose"][k] for k in ("x", "y", "theta")],
                               arcs([(0.0, 0.5, 0.3, 4.0)]), atol=1e-7)
    assert car["match"]


ROWS = np.array([[0, 0.0, 0.5, 0.3], [5, 0.2, 0.3, -0.4], [10, 0.0, 0.1, 0.0]])


def test_several_chassis_with_a_table_are_held_against_it(fmu_dir, tmp_path):
    (tmp_path / "profile.csv").write_text("time,vx,vy,w\n" + "\n".join(
        ",".join(f"{v:g}" for v in row) for row in ROWS) + "\n")
    text = ("command:      {fmu: VelocitySource, parameters: {table: profile.csv, "
            "interpolation: linear}}")
    graph = runner.prepare(with_command(tmp_path, text), fmu_dir=fmu_dir)
    poses = runner.run(graph, tmp_path / "out", plots=False).summary["poses"]
    expected = spec_end(lambda t: [np.interp(t, ROWS[:, 0], ROWS[:, i]) for i in (1, 2, 3)],
                        10.0, vectorised=True)
    for name in ("mecanum_pose", "omni_pose"):
        ref = poses[name]["reference_end_pose"]
        np.testing.assert_allclose([ref["x"], ref["y"], ref["theta"]], expected, atol=1e-7)
        assert poses[name]["match"], poses[name]


def test_several_chassis_with_a_failing_truth_keep_their_tables(fmu_dir, tmp_path):
    """The command's vx fails between the communication points: exit 1, results.csv and
    summary.json kept, the failure named per pose, the car (its own command) still judged."""
    text = (f'command:      {{fmu: VelocitySource, parameters: {{vx_expr: "{BETWEEN}", '
            'vy_expr: "0.5", w_expr: "0.3"}}')
    scenario = with_command(tmp_path, text)
    out = tmp_path / "out"
    proc = run_child("run", scenario, "--out", out, "--no-plots", "--fmu-dir", fmu_dir)
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    assert "the run itself is complete" in proc.stderr and "math domain error" in proc.stderr
    with open(out / "results.csv") as fh:
        rows = list(csv.reader(fh))
    assert len(rows) == 1 + 1001 and float(rows[-1][0]) == 10.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True
    assert "mecanum_pose" in summary["ground_truth_error"]
    poses = summary["poses"]
    for name in ("mecanum_pose", "omni_pose"):
        assert "math domain error" in poses[name]["ground_truth_error"]
        assert "match" not in poses[name]
    assert poses["car_pose"]["match"] is True


def test_a_twist_singular_between_the_rows_stops_the_truth_with_one_message(fmu_dir, tmp_path):
    """w = 1/(t - t_s) with t_s between two rows: the FMUs see finite values, the truth's solver
    cannot pass t_s. Exit 1, the results kept, one line that says where, no warning of the
    solver's own (scipy's ODEintWarning), no traceback."""
    scenario = tmp_path / "singular.yaml"
    scenario.write_text(CIRCLE.read_text().replace('w_expr: "0"', 'w_expr: "1/(t - 5.00001)"'))
    out = tmp_path / "out"
    proc = run_child("run", scenario, "--out", out, "--no-plots", "--fmu-dir", fmu_dir)
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
    assert "the ODE solver stopped 5.00001 s after the start" in proc.stderr, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and "singular" in summary["ground_truth_error"]


def test_where_the_solver_stopped_is_read_from_the_entries_it_wrote_only():
    """odeint leaves its info's entries past the output time it failed on unwritten
    (np.empty): whatever bits they hold (6e257 once, in a whole suite), the message says the
    t reached on the first time not reached; a value there that lies outside that row's
    interval (not written either) gives the row's start."""
    from mecanum_fmu.report.truth import _stopped
    times = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    excess = "Excess work done on this call (perhaps wrong Dfun type)."
    for garbage in (6.12032e257, -1e300, 0.0, np.nan, 2.5):
        tcur = np.array([1.0000001, 2.0, 2.4, garbage])
        message = _stopped({"tcur": tcur, "message": excess}, times)
        assert message.startswith("the ODE solver stopped 2.4 s after the start: "), message
        assert "100,000 steps between two rows" in message
    tcur = np.array([1.0, -1e300, 6.12032e257, 6.12032e257])
    assert _stopped({"tcur": tcur, "message": excess}, times).startswith(
        "the ODE solver stopped 1 s after the start")


def test_a_rate_that_is_not_finite_stops_the_solver_where_it_is_read():
    """An expression refuses a result that is not finite itself (ExpressionError); any other
    rate (another FMU's truth) is checked by the solver: LSODA alone would carry the NaN on
    and call the integration successful."""
    from mecanum_fmu.report.truth import solve_smooth

    def rates(tau, state):          # NaN on 4.995 < t < 5.015: read at least once (5 ms)
        return (1.0, 0.0, float("nan") if abs(tau - 5.005) < 0.01 else 0.0)
    with pytest.raises(ArithmeticError, match=r"not finite (4\.99[5-9]|5\.0[01])\d* s after"):
        solve_smooth(rates, (0.0, 0.0, 0.0), np.linspace(0.0, 10.0, 201), 1e-10, 1e-12, 0.005)
    path = solve_smooth(lambda tau, state: (1.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                        np.array([0.0, 2.5, 10.0]), 1e-10, 1e-12, 0.005)
    assert path[:, 0] == pytest.approx([0.0, 2.5, 10.0], abs=1e-12)     # x = t


def test_a_sweep_with_a_failing_truth_writes_its_runs(fmu_dir, tmp_path, capsys):
    scenario = tmp_path / "between.yaml"
    scenario.write_text(CIRCLE.read_text().replace('vx_expr: "sin(t)"', f'vx_expr: "{BETWEEN}"'))
    assert BETWEEN in scenario.read_text()
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"name: s\nscenario: {scenario}\ngrid:\n  w2c.dR1: [0.0, 0.0001]\n")
    out = tmp_path / "out"
    code = cli.main(["sweep", str(sweep), "--out", str(out), "--workers", "1", "--no-plots",
                     "--fmu-dir", str(fmu_dir)])
    assert code == 0, capsys.readouterr().err
    with open(out / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert all(r["error.position"] == "" for r in rows)
    assert json.loads((out / "summary.json").read_text())["ok"] == 2
    assert "no ground truth for 2 run(s)" in capsys.readouterr().out


FAST = np.array([[0, 0.0, 0.0, 0.0], [1, 0.0, 1.0, 0.0], [2, 1.0, 0.0, 0.5], [3, 0.0, 0.0, 0.0]])


def test_saturated_wheels_are_in_the_open_loop_truth(fmu_dir, tmp_path, capsys):
    """A table too fast for w_max = 10 rad/s (1 m/s needs 1/0.06 = 16.7 rad/s): the truth
    saturates as the car does, and both end where the saturated spec ODE ends."""
    assert max(abs(spec_wheels(0, 1, 0))) == pytest.approx(1 / 0.06)
    (tmp_path / "fast.csv").write_text("time,vx,vy,w\n" + "\n".join(
        ",".join(f"{v:g}" for v in row) for row in FAST) + "\n")
    text = CIRCLE.read_text()
    text = text.replace('parameters: {vx_expr: "sin(t)", vy_expr: "cos(t)", w_expr: "0"}',
                        "parameters: {table: fast.csv, interpolation: linear}")
    text = text.replace("c2w:    {fmu: Center2Wheel}", "c2w:    {fmu: Center2Wheel, parameters: {w_max: 10}}")
    assert "fast.csv" in text and "w_max: 10" in text
    (tmp_path / "fast.yaml").write_text(text)
    graph = runner.prepare(tmp_path / "fast.yaml", fmu_dir=fmu_dir, stop_time=3.0, step_size=0.01)
    out = runner.run(graph, tmp_path / "out", plots=False, quiet=False)
    twist = lambda t: [np.interp(t, FAST[:, 0], FAST[:, i]) for i in (1, 2, 3)]
    expected = spec_end(twist, 3.0, w_max=10.0, vectorised=True)
    free = spec_end(twist, 3.0, vectorised=True)
    assert math.hypot(expected[0] - free[0], expected[1] - free[1]) > 0.1    # it matters
    ref, end = out.summary["reference_end_pose"], out.summary["end_pose"]
    np.testing.assert_allclose([ref["x"], ref["y"], ref["theta"]], expected, atol=1e-7)
    assert out.summary["match"] is True and out.summary["error"]["position"] < 1e-4
    sat = out.summary["saturation"]
    assert sat["instance"] == "c2w" and sat["w_max"] == 10 and sat["in_ground_truth"] is True
    assert 0.5 < sat["from"] < 1.0 < sat["to"] < 3.0     # 0.6 m/s is reached at t = 0.6 s
    printed = capsys.readouterr().out
    assert "match!" in printed and "saturates them too" in printed


def test_saturated_follower_names_the_cause_not_the_step(fmu_dir, tmp_path):
    """The figure eight's crossing needs 25.1 rad/s (the reference's own velocity through the
    wheel matrix) against w_max = 18: the car lags its reference, whatever the step."""
    t = 2.5                                  # the crossing; heading 0: body = world
    vx = -1.2 * 0.2 * math.pi * math.sin(0.2 * math.pi * t)
    vy = -0.6 * 0.4 * math.pi * math.cos(0.4 * math.pi * t)
    need = max(abs(spec_wheels(vx, vy, 0.0)))
    assert need == pytest.approx(25.13, abs=0.01) and need > 18
    proc = run_child("run", FIGURE_EIGHT, "--out", tmp_path / "out", "--no-plots",
                     "--fmu-dir", fmu_dir)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "no match (the wheels saturate at w_max = 18 rad/s (c2w" in proc.stdout
    assert "smaller step changes nothing" in proc.stdout and "try a smaller step" not in proc.stdout
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    sat = summary["saturation"]
    assert sat["in_ground_truth"] is False and 1.0 <= sat["from"] <= t
    assert summary["match"] is False


def test_chassis_compare_runs_as_the_readme_gives_it(tmp_path):
    """`python -m mecanum_fmu.report.chassis_compare` (README): the figure and exit 0."""
    assert "mecanum_fmu.report.chassis_compare" in (ROOT / "README.md").read_text()
    png = tmp_path / "cmp.png"
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu.report.chassis_compare",
                           "--out", str(png)], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path, env=child_env())
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.count(", match") == 3 and png.stat().st_size > 10_000


def test_chassis_compare_bad_input_is_exit_2(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu.report.chassis_compare",
                           str(tmp_path / "missing.yaml")],
                          capture_output=True, text=True, timeout=120, env=child_env())
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "missing.yaml" in proc.stderr


def test_the_api_run_is_quiet_and_its_outcome_short(fmu_dir, tmp_path, capsys):
    graph = runner.prepare(CIRCLE, fmu_dir=fmu_dir)
    out = runner.run(graph, tmp_path / "out", plots=False)
    assert capsys.readouterr().out == ""
    text = repr(out)
    # short whatever the folder: the out_dir's length is the machine's TMPDIR's, not ours
    assert len(text) - len(str(out.out_dir)) < 120 and "circle" in text and "match=True" in text
    assert f"out_dir={str(out.out_dir)!r}" in text
    lines = []
    runner.run(graph, tmp_path / "again", plots=False, log=lines.append)
    assert "match!" in lines


def test_one_pose_evaluation_agrees_with_the_seed(fmu_dir, tmp_path):
    """The single-pose summary keeps its shape: the spec's end point, error and match."""
    graph = runner.prepare(CIRCLE, fmu_dir=fmu_dir)
    out = runner.run(graph, tmp_path / "out", plots=False)
    ref = out.summary["reference_end_pose"]
    assert (ref["x"], ref["y"]) == pytest.approx(SPEC_END, abs=1e-9)
    assert out.summary["match"] is True and "poses" not in out.summary
    assert out.evaluation.single.drive.chain == ("w2c", "c2w")
    assert out.evaluation.single.drive.origin == "source"
