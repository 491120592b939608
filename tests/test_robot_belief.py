"""A loop closed on belief with the drive train (issue 31 item 5): scenarios/robot/belief_drive_*.

The PathFollower is fed the Odometry; four DCMotors and the MecanumDynamics stand between its
twist and the true pose; the encoders read the motors' wheel speeds, the gyro the body's yaw
rate. The reference values are independent of the odometry:

- The dynamics' own contact slips. A free-roller contact slips by
  slip_i = (v + w x r_i).u_i - R sin(alpha) w_i (docs/robot.md), and with no slip the wheel
  speeds would be the inverse kinematics of the body's twist. So the body's twist is the forward
  kinematics FK of w_i + slip_i / (R sin alpha), and ideal sensors with the exact update believe
  FK(w): the belief minus the truth is minus the time integral of FK(slip) / (R sin alpha),
  turned into the world frame. The integral is taken here (trapezoid) from the recorded slips.
- A wheel-radius error: FK is linear in R, so real wheels (1 + e) times the R the odometry
  assumes move the body (1 + e) times the believed twist, on top of the slip.
- A gyro bias b: the heading from the gyro drifts by b t.

Tolerances: the encoders and the body read the motors' speeds at the same instants, but the
master may hand them to the two one step apart; the sums of the held speeds then telescope to
one step of motion at the end minus one at the start, and the robot starts at rest: the pose is
off by at most h max|v|, the heading by h max|w|. The trapezoid's own error is far smaller: the
ideal run's residual is 2.7e-5 m against h max|v| = 1.1e-3 m.
"""
import math
import subprocess

import numpy as np
import pytest

from helpers import ROOT, cli_args
from mecanum_fmu import master
from mecanum_fmu.models.blocks.kinematics import wheel_to_center
from mecanum_fmu.runner import prepare

ROBOT = ROOT / "scenarios" / "robot"
TRACK = ROBOT / "belief_drive_track_circle.yaml"
GYRO = ROBOT / "belief_drive_track_gyro.yaml"
ALPHA, L, W, R = math.pi / 4, 0.16, 0.12, 0.06          # the scenarios' geometry
PERIOD = 0.01                                            # their sensors' sample period [s]
ENCODERS = ("enc1", "enc2", "enc3", "enc4")


def ideal(**more):
    """The scenario's sensors made ideal, the exact update, the real wheels the assumed ones."""
    values = {f"{e}.{p}": v for e in ENCODERS for p, v in (("cpr", 0), ("sigma", 0.0))}
    values.update({"gyro.sigma": 0.0, "gyro.bias": 0.0, "odom.update": "exact", "body.R": R})
    values.update(more)
    return values


def simulate(path, parameters, stop=3.0):
    graph = prepare(path, fmu_dir=ROOT / "fmus", parameters=parameters, stop_time=stop)
    assert graph.scenario.experiment.master == "quadratic"            # the scenarios' default
    return master.simulate(graph, graph.scenario.experiment)


def at_samples(results):
    """The rows at the sensors' sample times (the belief is held between them)."""
    k = results.time / PERIOD
    return np.abs(k - np.round(k)) < 1e-6


def slip_integral(results, r_true):
    """The world-frame integral of FK(slip) / (r_true sin alpha) [m]: truth minus FK(w)."""
    slips = np.column_stack([results[f"body.slip{i}"] for i in range(1, 5)])
    twist = np.array([wheel_to_center(*s, ALPHA, L, W, r_true) for s in slips])
    twist /= r_true * math.sin(ALPHA)
    th = results["pose.theta"]
    world = np.column_stack([np.cos(th) * twist[:, 0] - np.sin(th) * twist[:, 1],
                             np.sin(th) * twist[:, 0] + np.cos(th) * twist[:, 1]])
    steps = np.diff(results.time)[:, None] * (world[1:] + world[:-1]) / 2
    return np.vstack([np.zeros(2), np.cumsum(steps, axis=0)])


def one_step_of_motion(results):
    h = results.time[1] - results.time[0]
    speed = np.hypot(results["body.vx"], results["body.vy"])
    return h * float(np.max(speed)), h * float(np.max(np.abs(results["body.w"])))


def positions(results, name):
    return np.column_stack([results[f"{name}.x"], results[f"{name}.y"]])


@pytest.fixture(scope="module")
def ideal_run():
    return simulate(TRACK, ideal())


def test_ideal_sensors_believe_the_kinematics_and_miss_only_the_slip(ideal_run):
    r = ideal_run
    gap = positions(r, "odom") - positions(r, "pose")
    slip = slip_integral(r, R)
    tol, _ = one_step_of_motion(r)
    rows = at_samples(r)
    residual = np.linalg.norm(gap + slip, axis=1)[rows]
    assert np.max(residual) < tol
    # the slip is what the belief misses: the start asks more than the floor gives (mu = 1)
    assert np.linalg.norm(gap[-1]) > 10 * tol
    # with the sign turned the check fails: it is the integral, not its size, that matches
    assert np.max(np.linalg.norm(gap - slip, axis=1)[rows]) > 10 * tol
    heading = r["odom.theta"] - r["pose.theta"]
    assert np.max(np.abs(heading[rows])) < one_step_of_motion(r)[1] + 1e-12


def test_a_radius_error_scales_the_true_path(ideal_run):
    """Real wheels e = 0.5 % larger (the scenario's body.R): truth = (1 + e) belief + slip."""
    e = 0.0003 / R
    r = simulate(TRACK, ideal(**{"body.R": R * (1 + e)}))
    believed, true = positions(r, "odom"), positions(r, "pose")
    slip = slip_integral(r, R * (1 + e))
    tol, _ = one_step_of_motion(r)
    rows = at_samples(r)
    # the heading stays near 0 (theta_ref = 0), so the scale acts on the displacement alone;
    # a heading theta adds at most e |theta| per metre travelled
    travelled = float(np.sum(np.hypot(np.diff(true[:, 0]), np.diff(true[:, 1]))))
    tol += e * float(np.max(np.abs(r["pose.theta"]))) * travelled
    predicted = (1 + e) * believed + slip
    assert np.max(np.linalg.norm(true - predicted, axis=1)[rows]) < (1 + e) * tol
    scale_drift = e * np.linalg.norm(believed[-1])              # about 10 mm after 3 s
    assert scale_drift > 5 * tol
    # without the scale term the prediction misses by the scale drift
    assert np.linalg.norm(true[-1] - believed[-1] - slip[-1]) == pytest.approx(
        (1 + e) * scale_drift, abs=2 * tol)


def test_the_gyro_heading_drifts_by_its_bias(tmp_path):
    """belief_drive_track_gyro with a noiseless gyro of bias b: heading drift b t."""
    bias = 0.01
    r = simulate(GYRO, ideal(**{"gyro.bias": bias}), stop=1.0)
    rows = at_samples(r)
    drift = (r["odom.theta"] - r["pose.theta"])[rows]
    _, tol = one_step_of_motion(r)
    assert np.max(np.abs(drift - bias * r.time[rows])) < tol + 1e-12
    assert bias * r.time[-1] > 100 * (tol + 1e-12)


@pytest.mark.parametrize("path", [TRACK, GYRO], ids=lambda p: p.stem)
def test_the_scenarios_validate_strictly(path):
    done = subprocess.run(cli_args("validate", "--strict", str(path)), capture_output=True,
                          text=True, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "step 0.001 s" in done.stdout


def test_the_run_reports_and_draws_the_belief_and_its_drift(tmp_path):
    """`run` under the scenario's master: summary.json's belief, the dashboard's panels."""
    import json
    done = subprocess.run(cli_args("run", str(TRACK), "--stop-time", "2", "--out",
                                   str(tmp_path)), capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    belief = summary["belief"]
    assert belief["instance"] == "odom" and belief["closes_the_loop"] is True
    end = summary["end_pose"]
    drift = math.dist((belief["end_pose"]["x"], belief["end_pose"]["y"]), (end["x"], end["y"]))
    assert belief["drift"]["position"] == pytest.approx(drift, rel=1e-9) and drift > 0.01
    assert "fed the odometry's belief" in done.stdout
    for name in ("belief.png", "drift.png", "slip.png", "dashboard.png"):
        assert (tmp_path / name).stat().st_size > 10_000
