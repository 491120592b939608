"""The seed system in other FMI hosts - libcosim, Ecos, and Ecos' command-line program (a
non-Python host; our FMUs carry their Python) - loaded from our exported SSP and compared
with our Jacobi master at the same step (mecanum_fmu.interop.cross_check explains the tolerance).

A host that cannot be loaded skips with what to install; with MECANUM_FMU_REQUIRE_TOOLS=1 (CI)
it fails instead.
"""
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import CHAIN_CONNECTIONS, ROOT, SPEC_END, run_host_or_skip, tool_missing, \
    write_scenario
from mecanum_fmu.interop.cross_check import HOST_TOLERANCE, TOLERANCE, compared_outputs, cross_check, \
    difference, ours_jacobi
from mecanum_fmu.interop.other_hosts import HOSTS, HostUnavailable, run_host
from mecanum_fmu.runner import prepare
from mecanum_fmu.interop.ssp_write import export_ssp



def run_or_skip(host, ssp, graph, names):
    exp = graph.scenario.experiment
    return run_host_or_skip(host, ssp, start=exp.start_time, stop=exp.stop_time,
                            step=exp.step_size, variables=names)


@pytest.fixture(scope="module")
def seed(fmu_dir, tmp_path_factory):
    """The seed circle at h = 0.05 under the Jacobi master: graph, SSP and our end values."""
    folder = tmp_path_factory.mktemp("interop")
    graph = prepare(ROOT / "scenarios" / "circle.yaml", master_name="jacobi", step_size=0.05,
                    fmu_dir=fmu_dir)
    ssp = export_ssp(graph, folder / "circle.ssp")
    names = compared_outputs(graph)
    return graph, ssp, names, ours_jacobi(graph, names)


def test_compared_outputs_are_the_ones_without_feedthrough(seed):
    _, _, names, _ = seed
    assert names == ["source.vx", "source.vy", "source.w", "pose.x", "pose.y", "pose.theta"]


@pytest.mark.parametrize("host", HOSTS)
def test_seed_circle_in_host_agrees_with_our_jacobi(seed, host):
    graph, ssp, names, ours = seed
    run = run_or_skip(host, ssp, graph, names)
    assert run.end_time == pytest.approx(10.0, abs=1e-9)
    assert difference(run.values, ours.values, names) <= HOST_TOLERANCE.get(host, TOLERANCE)
    # and against docs/spec.md, Expected results: a Jacobi chain of three feedthrough hops lags
    # the velocity by at most 3h (2h of hops + h/2 of hold, rounded up), so the end point is off
    # by at most 3h * |v(T) - v(0)| with v = (sin t, cos t) - first order in h
    bound = 3 * 0.05 * math.hypot(math.sin(10.0) - 0.0, math.cos(10.0) - 1.0)
    error = math.hypot(run.values["pose.x"] - SPEC_END[0], run.values["pose.y"] - SPEC_END[1])
    assert 0 < error <= bound


MISMATCHED = """\
name: mismatched
description: inverse and forward kinematics with different geometry, a start pose, a turn
experiment: {start_time: 0.0, stop_time: 4.0, step_size: 0.02, master: jacobi}
components:
  source: {fmu: VelocitySource, parameters: {vx_expr: "0.4", vy_expr: "0.3*sin(2*t)", w_expr: "0.5*cos(t)"}}
  c2w: {fmu: Center2Wheel, parameters: {alpha: 0.6, L: 0.2, W: 0.15, R: 0.06}}
  w2c: {fmu: Wheel2Center, parameters: {alpha: 0.6, L: 0.2, W: 0.15, R: 0.05}}
  pose: {fmu: PoseIntegrator, parameters: {x0: 0.5, y0: -0.25, theta0: 0.3}}
""" + CHAIN_CONNECTIONS


@pytest.mark.parametrize("host", HOSTS)
def test_component_parameters_travel_in_the_ssp(fmu_dir, tmp_path, host):
    """Every parameter binding counts: the forward model's radius differs from the inverse
    model's (the body moves 5/6 as fast), the start pose is not zero and the car turns."""
    graph = prepare(write_scenario(tmp_path, "mismatched", MISMATCHED), fmu_dir=fmu_dir)
    names = compared_outputs(graph)
    ours = ours_jacobi(graph, names)
    # the parameters matter: without them the end pose is far from ours
    plain = prepare(write_scenario(tmp_path, "plain", MISMATCHED.replace(
        "R: 0.05", "R: 0.06").replace("x0: 0.5, y0: -0.25, theta0: 0.3", "x0: 0.0")),
        fmu_dir=fmu_dir)
    assert difference(ours_jacobi(plain, names).values, ours.values, names) > 0.1
    bound = {"c2w.alpha": 0.6, "c2w.L": 0.2, "c2w.W": 0.15, "c2w.R": 0.06, "w2c.alpha": 0.6,
             "w2c.L": 0.2, "w2c.W": 0.15, "w2c.R": 0.05, "pose.x0": 0.5, "pose.y0": -0.25,
             "pose.theta0": 0.3}
    run = run_or_skip(host, export_ssp(graph, tmp_path / "mismatched.ssp"), graph,
                      names + list(bound))
    assert {k: run.values[k] for k in bound} == bound          # every binding arrived
    # Ecos applies a parameter set after its initial value propagation; the exported
    # VelocitySource carries the scenario's expressions as its own defaults (a baked variant
    # FMU, interop/ssp_bake.py), so even that propagation starts from the scenario's twist and
    # every host agrees with our Jacobi master from the first step.
    assert difference(run.values, ours.values, names) <= HOST_TOLERANCE.get(host, TOLERANCE)


def test_cross_check_command_reports_agreement(fmu_dir, tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "mecanum_fmu", "cross-check", str(ROOT / "scenarios/circle.yaml"),
         "--hosts", "libcosim,ecos", "--step-size", "0.1", "--require", "--fmu-dir", str(fmu_dir)],
        capture_output=True, text=True, timeout=300)
    if proc.returncode == 1 and "not run" in proc.stdout:
        tool_missing(proc.stdout)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.count("agrees") == 2
    assert "Traceback" not in proc.stderr


def test_cross_check_rejects_an_unknown_host(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "cross-check",
                           str(ROOT / "scenarios/circle.yaml"), "--hosts", "libcosim,omsim"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "--hosts" in proc.stderr and "omsim" in proc.stderr and "ecos-cli" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_cross_check_refuses_a_step_that_does_not_divide_the_run():
    # the hosts take fixed steps: 0.03 s would end libcosim at 10.02 s and Ecos at 9.99 s
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "cross-check",
                           str(ROOT / "scenarios/circle.yaml"), "--step-size", "0.03"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "circle.yaml" in proc.stderr and "experiment.step_size" in proc.stderr
    assert "--step-size 0.025" in proc.stderr          # 10 / 0.025 = 400 steps
    assert "Traceback" not in proc.stderr and proc.stdout == ""


@pytest.fixture
def hidden_hosts(tmp_path, monkeypatch):
    """Child processes see `libcosimpy` and `ecospy` packages that fail to import."""
    for name in ("libcosimpy", "ecospy"):
        (tmp_path / "shadow" / name).mkdir(parents=True)
        (tmp_path / "shadow" / name / "__init__.py").write_text(
            "raise ImportError('simulated: not installed')\n")
    src = str(ROOT / "src")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path / "shadow"), src]))


@pytest.mark.parametrize("host", HOSTS)
def test_missing_host_says_what_to_install(seed, hidden_hosts, host):
    graph, ssp, names, _ = seed
    exp = graph.scenario.experiment
    with pytest.raises(HostUnavailable, match="install: pip install (libcosimpy|ecospy)"):
        run_host(host, ssp, start=exp.start_time, stop=exp.stop_time, step=exp.step_size,
                 variables=names)


def test_cross_check_goes_on_without_a_host_unless_required(seed, hidden_hosts):
    graph, _, _, _ = seed
    check = cross_check(graph, ["libcosim"])
    assert check.rows[0].run is None and "pip install libcosimpy" in check.rows[0].problem
    assert check.rows[0].missing
    assert not check.rows[0].agrees
    base = [sys.executable, "-m", "mecanum_fmu", "cross-check", str(ROOT / "scenarios/circle.yaml"),
            "--hosts", "libcosim", "--fmu-dir", str(Path(graph.instances[0].fmu_path).parent)]
    lenient = subprocess.run(base, capture_output=True, text=True, timeout=120)
    strict = subprocess.run(base + ["--require"], capture_output=True, text=True, timeout=120)
    assert lenient.returncode == 0 and "not run" in lenient.stdout
    assert strict.returncode == 1 and "pip install libcosimpy" in strict.stdout
