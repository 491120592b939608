"""`mecanum-fmu sweep`: bad sweep files (exit 2, file and place), the run plan, per-wheel
radius deviations, and the Dask runs: a real `dask scheduler` with two `dask worker`s on
127.0.0.1 gives the same runs.csv bytes as local workers, and a worker killed mid-sweep loses
no run."""
from __future__ import annotations

import csv
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT
from mecanum_fmu import cli

CIRCLE = ROOT / "scenarios" / "circle.yaml"
DRAWS = """\
random:
  samples: 10
  seed: 7
  w2c.dR1: {normal: [0.0, 0.0003]}
  w2c.dR3: {uniform: [-0.0003, 0.0003]}
"""


def write_sweep(folder: Path, body: str, name: str = "s") -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(f"name: {name}\nscenario: {CIRCLE}\n" + body)
    return path


# ---------------------------------------------------------------------------------------------
BAD = {
    "unknown_parameter": ("random:\n  samples: 3\n  w2c.alfa: {normal: [0.7, 0.001]}\n",
                          "random.w2c.alfa", "did you mean 'alpha'"),
    "unknown_instance": ("grid:\n  wc2.R: [0.05]\n", "grid.wc2.R", "did you mean 'w2c'"),
    "bad_distribution": ("random:\n  samples: 3\n  w2c.dR1: {gauss: [0, 0.001]}\n",
                         "random.w2c.dR1", "unknown distribution 'gauss'"),
    "negative_sd": ("random:\n  samples: 3\n  w2c.dR1: {normal: [0, -1]}\n",
                    "random.w2c.dR1.normal", "sd >= 0"),
    "empty_grid": ("grid: {}\n", "grid", "empty"),
    "empty_value_list": ("grid:\n  w2c.R: []\n", "grid.w2c.R", "non-empty list"),
    "zero_samples": ("random:\n  samples: 0\n  w2c.dR1: {normal: [0, 0.001]}\n",
                     "random.samples", "> 0"),
    "negative_samples": ("random:\n  samples: -5\n  w2c.dR1: {normal: [0, 0.001]}\n",
                         "random.samples", "> 0"),
    "output_not_settable": ("grid:\n  pose.x: [1.0]\n", "grid.pose.x", "cannot be set"),
    "bad_grid_value": ("grid:\n  w2c.R: [0.06, -0.01]\n", "grid.w2c.R", "must be > 0"),
    "nan_value": ("grid:\n  w2c.R: [.nan]\n", "grid.w2c.R", "finite"),
    "too_many_runs": ("random:\n  samples: 2000000\n  w2c.dR1: {normal: [0, 0.001]}\n",
                      "random.samples", "split the study"),
    "bad_step": ("experiment: {step_size: 0}\ngrid:\n  w2c.R: [0.06]\n", "experiment.step_size", "> 0"),
    "bad_expression": ("grid:\n  source.w_expr: ['0', 'sin(']\n", "grid.source.w_expr", ""),
    "text_for_a_number": ("grid:\n  w2c.R: ['big']\n", "grid.w2c.R", "expected a number"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sweep_file_is_exit_2_naming_file_and_place(tmp_path, capsys, built_fmus, case):
    body, place, hint = BAD[case]
    path = write_sweep(tmp_path, body)
    code = cli.main(["sweep", str(path), "--out", str(tmp_path / "out"),
                     "--fmu-dir", str(built_fmus["Wheel2Center"].parent)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"{path}: {place}: " in err, err
    assert hint in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()        # nothing started


def test_missing_scenario_names_the_sweep_file(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text("scenario: nope.yaml\n" + DRAWS)
    assert cli.main(["sweep", str(path)]) == 2
    assert f"{path}: scenario: " in capsys.readouterr().err


@pytest.mark.parametrize("name", ["..", "a/b", "a b"])
def test_a_sweep_name_follows_the_scenario_name_rule(tmp_path, capsys, name):
    """The name names results/<name>/: the scenario's rule (scenario.usable_name) applies."""
    path = tmp_path / "s.yaml"
    path.write_text(f"name: '{name}'\nscenario: {CIRCLE}\n" + DRAWS)
    assert cli.main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: name: " in err and "not a usable name" in err, err


# ---------------------------------------------------------------------------------------------
def test_plan_counts_grid_points_first_and_draws_reproducibly(tmp_path, built_fmus):
    from mecanum_fmu.sweep.cluster import prepare_sweep
    path = write_sweep(tmp_path, "grid:\n  source.w_expr: ['0', '0.1']\n  pose.theta0: [0.0, 0.3]\n"
                       + DRAWS)
    _, _, runs = prepare_sweep(path, built_fmus["Wheel2Center"].parent)
    assert [r.index for r in runs] == list(range(40))
    rng = np.random.default_rng(7)                # drawn in file order, reused per grid point
    dr1, dr3 = rng.normal(0.0, 0.0003, 10), rng.uniform(-0.0003, 0.0003, 10)
    for r in runs:
        point, sample = divmod(r.index, 10)
        values = {str(k): v for k, v in r.values.items()}
        assert (values["source.w_expr"], values["pose.theta0"]) == \
            [("0", 0.0), ("0", 0.3), ("0.1", 0.0), ("0.1", 0.3)][point]
        assert (values["w2c.dR1"], values["w2c.dR3"]) == (dr1[sample], dr3[sample])


def test_a_draw_that_breaks_the_rules_is_a_failed_row(tmp_path, built_fmus):
    from mecanum_fmu.sweep.cluster import prepare_sweep
    path = write_sweep(tmp_path, "random:\n  samples: 50\n  w2c.dR2: {uniform: [-0.1, 0.1]}\n")
    _, _, runs = prepare_sweep(path, built_fmus["Wheel2Center"].parent)
    bad = [r for r in runs if r.problem]
    assert bad and all(r.values[next(iter(r.values))] <= -0.06 for r in bad)
    assert all("R + dR2" in r.problem for r in bad)


def test_wheel_radius_deviations_follow_the_rolling_radius(built_fmus):
    """Equal deviations d on all four wheels scale the twist by (R + d)/R: the circle's end
    point moves to (R + d)/R times the ground truth's (w = 0, so theta stays 0)."""
    from mecanum_fmu import master
    from mecanum_fmu.report.ground_truth import ground_truth
    from mecanum_fmu.runner import prepare
    from mecanum_fmu.scenario.document import VarRef
    from mecanum_fmu.sweep.worker import with_values
    graph = prepare(CIRCLE, fmu_dir=built_fmus["Wheel2Center"].parent)
    d = 0.0006
    variant = with_values(graph, {VarRef("w2c", f"dR{i}"): d for i in range(1, 5)})
    results = master.simulate(variant, variant.scenario.experiment)
    truth = ground_truth(graph, results.time)
    scale = (0.06 + d) / 0.06
    assert results.final("pose.x") == pytest.approx(scale * truth.x[-1], abs=1e-3)
    assert results.final("pose.y") == pytest.approx(scale * truth.y[-1], abs=1e-3)
    # against the nominal run the shift is 1 % of the end point, well above the tolerance
    assert abs(results.final("pose.x") - truth.x[-1]) > 0.015


def test_forward_kinematics_with_radius_deviations_is_least_squares():
    """An independent reference: least squares on the wheel rolling speeds (R + dRi) wi."""
    from mecanum_fmu.models.blocks.kinematics import wheel_to_center
    alpha, L, W, R = 0.7, 0.16, 0.12, 0.06
    c, k = 1 / np.tan(alpha), 0.16 + 0.12 / np.tan(alpha)
    J = np.array([[-c, 1, k], [c, 1, -k], [-c, 1, -k], [c, 1, k]])
    wheels, dR = (3.0, -2.0, 5.0, 1.5), (0.001, -0.002, 0.0005, 0.003)
    rolling = np.array([(R + d) * w for w, d in zip(wheels, dR)])
    expected = np.linalg.lstsq(J, rolling, rcond=None)[0]
    assert wheel_to_center(*wheels, alpha, L, W, R, dR) == pytest.approx(expected, abs=1e-12)
    assert wheel_to_center(*wheels, alpha, L, W, R, (0.0,) * 4) == \
        wheel_to_center(*wheels, alpha, L, W, R)


# ---------------------------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """A real `dask scheduler` and two `dask worker`s (no nanny: killing one loses it)."""
    folder = tmp_path_factory.mktemp("dask")
    env = {**os.environ, "TMPDIR": str(folder)}
    address = f"tcp://127.0.0.1:{_free_port()}"
    dask = [sys.executable, "-m", "dask"]
    common = dict(env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                  start_new_session=True)
    procs = [subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port",
                                      address.rsplit(":", 1)[1], "--no-dashboard"], **common)]
    procs += [subprocess.Popen(dask + ["worker", address, "--nthreads", "1", "--no-nanny",
                                       "--no-dashboard", "--local-directory", str(folder)],
                               **common) for _ in range(2)]
    from distributed import Client
    with Client(address, timeout="60s") as client:
        client.wait_for_workers(2, timeout=120)
    yield address, procs[1:]
    # a worker may hang in pythonfmu's exit crash (master.exit_now's reason) until it is
    # killed: terminated, one waited the whole 5 s in each of two whole suites; the workers
    # hold nothing to keep
    for p in procs[1:]:
        p.kill()
    procs[0].terminate()
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _sweep_cli(args, tmp_path, env_tmp) -> subprocess.CompletedProcess:
    env = {**os.environ, "TMPDIR": str(env_tmp)}
    return subprocess.run([sys.executable, "-m", "mecanum_fmu", "sweep", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=600)


@pytest.fixture(scope="module")
def twenty_runs(tmp_path_factory, built_fmus):
    folder = tmp_path_factory.mktemp("sweep20")
    path = write_sweep(folder, "grid:\n  source.w_expr: ['0', '0.2']\n" + DRAWS, "twenty")
    local_tmp = folder / "tmp"
    local_tmp.mkdir()
    out = folder / "local"
    done = _sweep_cli([path, "--out", out, "--workers", "1", "--no-plots",
                       "--fmu-dir", built_fmus["Wheel2Center"].parent], folder, local_tmp)
    assert done.returncode == 0, done.stderr
    assert list(local_tmp.iterdir()) == []       # nothing left in TMPDIR
    return path, out


def test_local_sweep_writes_one_row_per_run(twenty_runs):
    path, out = twenty_runs
    with open(out / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["run"]) for r in rows] == list(range(20))
    assert {r["status"] for r in rows} == {"ok"}
    assert sorted(os.listdir(out)) == ["runs.csv", "summary.json"]   # no partial files
    import json
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["runs"], summary["ok"], summary["complete"]) == (20, 20, True)
    # the w = 0 grid point at dR = 0 would end on the ground truth within 1e-3 (docs/spec.md);
    # with 0.3 mm radius errors the error is larger but bounded by a few cm
    errors = [float(r["error.position"]) for r in rows[:10]]
    assert 0 < max(errors) < 0.1


def test_scheduler_sweep_gives_the_same_bytes(twenty_runs, dask_cluster, tmp_path, built_fmus):
    path, local = twenty_runs
    address, _ = dask_cluster
    done = _sweep_cli([path, "--out", tmp_path / "remote", "--scheduler", address, "--no-plots",
                       "--fmu-dir", built_fmus["Wheel2Center"].parent], tmp_path, tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "remote" / "runs.csv").read_bytes() == (local / "runs.csv").read_bytes()


def test_killed_worker_loses_no_run(twenty_runs, dask_cluster, built_fmus):
    from mecanum_fmu.sweep.cluster import execute, prepare_sweep
    path, local = twenty_runs
    address, workers = dask_cluster
    _, graph, runs = prepare_sweep(path, built_fmus["Wheel2Center"].parent)
    killed = []

    def kill_one(done, total):
        if not killed and done < total:
            os.kill(workers[0].pid, signal.SIGKILL)
            killed.append(done)
    ex = execute(graph, runs, scheduler=address, progress=kill_one)
    assert killed and killed[0] < 20
    assert workers[0].wait(timeout=30) == -signal.SIGKILL
    assert sorted(ex.results) == list(range(20))
    assert all(r.status == "ok" for r in ex.results.values())
    with open(local / "runs.csv") as fh:
        expected = {int(r["run"]): float(r["pose.x"]) for r in csv.DictReader(fh)}
    assert {i: r.ends["pose.x"] for i, r in ex.results.items()} == expected


def test_one_worn_wheel_turns_the_car_by_the_integrated_wheel_speed(built_fmus):
    """dR1 alone adds dR1 * w1 / (4k) to the yaw rate (docs/spec.md, Kinematics: the yaw row
    of the forward kinematics), with w1 = (vy - vx)/R at alpha = 45 deg and w = 0. Over the
    circle the heading ends at dR1 / (4kR) * (sin 10 + cos 10 - 1); wheel 2 instead would turn
    it by -dR2 / (4kR) * (sin 10 - cos 10 + 1)."""
    from mecanum_fmu import master
    from mecanum_fmu.runner import prepare
    from mecanum_fmu.scenario.document import VarRef
    from mecanum_fmu.sweep.worker import with_values
    import math
    graph = prepare(CIRCLE, fmu_dir=built_fmus["Wheel2Center"].parent)
    R, k, d = 0.06, 0.16 + 0.12, 0.0003
    for wheel, integral in ((1, math.sin(10) + math.cos(10) - 1),
                            (2, -(math.sin(10) - math.cos(10) + 1))):
        variant = with_values(graph, {VarRef("w2c", f"dR{wheel}"): d})
        theta = master.simulate(variant, variant.scenario.experiment).final("pose.theta")
        assert theta == pytest.approx(d / (4 * k * R) * integral, rel=1e-3)


# Signals at every moment of a sweep (the workers starting, mid-runs, the evaluation, the
# writing; Ctrl-C and SIGTERM, to the sweep or its process group): test_sweep_hardening.py.


def test_runs_csv_has_each_runs_error_estimate(twenty_runs):
    """master/estimate.py's columns: the w = 0 runs are the seed circle with 0.3 mm radius
    errors, whose coupling error at h = 0.05 under the quadratic master is about the seed's: at
    most 1.57e-5 m in x over the run (against the closed form x = 1 - cos t), within 3x."""
    path, out = twenty_runs
    with open(out / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert {"estimate.pose.x.max", "estimate.pose.x.end", "estimate.pose.theta.end"} <= set(rows[0])
    for r in rows[:10]:
        assert 1.57e-5 / 3 < float(r["estimate.pose.x.max"]) < 1.57e-5 * 3, r
