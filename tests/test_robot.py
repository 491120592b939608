"""The drive train (issue 30): DCMotor and MecanumDynamics, checked against the datasheet and
closed forms computed here, never against the code under test.

Reference values: the motor constants by the standard relations of docs/robot.md (written out
again below from the datasheet), the PI + motor response as the matrix exponential of its
linear ODE (scipy), the free-roller acceleration limit mu g sin(alpha), the seed circle's
kinematic end point (1 - cos 10, sin 10), and the inverse kinematics' wheel signs.
"""
import math
import subprocess

import numpy as np
import pytest
from scipy.linalg import expm

from helpers import ROOT, cli_args, with_experiment
from mecanum_fmu import master
from mecanum_fmu.models.modes import MODES, wheel_sign_list
from mecanum_fmu.report.drive_train import drive_train_limits, limit_lines
from mecanum_fmu.runner import prepare, run

ROBOT = ROOT / "scenarios" / "robot"
# Pololu 37D 30:1 12 V datasheet (docs/robot.md): 330 rpm / 0.2 A no load, 14 kg cm / 5.5 A stall
V_S, TAU_S, I_S = 12.0, 140.0e-3 * 9.80665, 5.5
W_0, I_0 = 330.0 * math.pi / 30.0, 0.2
J, KP, KI = 2.0e-3, 2.0, 150.0                    # the DCMotor's defaults
R_A, K_T = V_S / I_S, TAU_S / I_S
K_E = (V_S - R_A * I_0) / W_0
B = K_T * I_0 / W_0
G, ALPHA = 9.81, math.pi / 4
KINEMATIC_END = (1.0 - math.cos(10.0), math.sin(10.0))   # docs/spec.md, the seed study


def motor_alone(fmu_dir, stop: float, **parameters):
    """One DCMotor, its inputs held at start values, stepped by the quadratic master."""
    doc = {"experiment": {"start_time": 0.0, "stop_time": stop, "step_size": 1e-3},
           "components": {"motor": {"fmu": "DCMotor", "parameters": parameters}},
           "connections": []}
    graph = prepare(doc, fmu_dir=fmu_dir)
    return master.simulate(graph, graph.scenario.experiment)


def test_unloaded_at_full_voltage_settles_at_the_no_load_speed(fmu_dir):
    # a command above the no-load speed: the PI asks for more than V_supply and gets V_supply
    results = motor_alone(fmu_dir, 1.0, w_ref=2.0 * W_0)
    assert abs(results.final("motor.w") / W_0 - 1.0) < 0.005
    assert results.final("motor.V") == pytest.approx(V_S, rel=1e-12)
    # and the report names the saturation, as it names a Center2Wheel's w_max
    graph = prepare({"components": {"motor": {"fmu": "DCMotor", "parameters": {
        "w_ref": 2.0 * W_0}}}, "connections": []}, fmu_dir=fmu_dir)
    clamp = drive_train_limits(graph, results)["motors"]["motor"]["voltage_clamp"]
    assert clamp["from"] == 0.0 and clamp["to"] == pytest.approx(1.0)
    assert any("motor: |V| at V_supply = 12 V" in line for line in limit_lines(
        drive_train_limits(graph, results)))


def test_held_at_zero_speed_at_full_voltage_it_gives_the_stall_torque(fmu_dir):
    results = motor_alone(fmu_dir, 0.2, w_ref=W_0, tau_load=TAU_S)
    assert np.max(np.abs(results["motor.w"])) < 1e-9
    assert results.final("motor.tau") == pytest.approx(TAU_S, rel=1e-9)
    assert results.final("motor.i") == pytest.approx(I_S, rel=1e-9)


def test_small_step_matches_the_closed_form_of_motor_and_pi(fmu_dir):
    w_start, step = 10.0, 0.5
    results = motor_alone(fmu_dir, 0.3, w0=w_start, w_ref=w_start + step)
    # x = (w, z): J w' = (k_t / R_a)(kp (r - w) + z - k_e w) - b w, z' = ki (r - w)
    A = np.array([[-(K_T * (KP + K_E) / R_A + B) / J, K_T / (R_A * J)], [-KI, 0.0]])
    u = np.array([K_T * KP / (R_A * J), KI]) * (w_start + step)
    x0 = np.array([w_start, (K_E + R_A * B / K_T) * w_start])
    M = np.zeros((3, 3))
    M[:2, :2], M[:2, 2] = A, u
    expected = [(expm(M * t) @ np.append(x0, 1.0))[0] for t in results.time]
    assert np.max(np.abs(results["motor.w"] - expected)) < 1e-6
    assert np.max(np.abs(results["motor.V"])) < V_S        # linear: no clamp on the way


def test_derived_constants_are_the_datasheet_relations():
    from mecanum_fmu.models.blocks.motor import DEFAULT_MOTOR, DATASHEET, derived
    assert derived(*(DEFAULT_MOTOR[k] for k in DATASHEET)) == pytest.approx((R_A, K_T, K_E, B))
    assert K_E > K_T      # a gear motor: the gear loss (k_e - k_t) i w is kept, not zeroed


def energy_residual(results) -> tuple[float, float]:
    """(electrical energy in, what it does not account for): kinetic of body and wheels, copper,
    viscous, gear and slip losses (La = 0: no magnetic energy)."""
    e_in, used = 0.0, results.final("body.E_kinetic") + results.final("body.E_slip")
    for k in range(1, 5):
        m = f"motor{k}"
        e_in += results.final(f"{m}.E_electrical")
        w = results[f"{m}.w"]
        used += 0.5 * J * (w[-1] ** 2 - w[0] ** 2)
        used += sum(results.final(f"{m}.{e}") for e in ("E_copper", "E_viscous", "E_gear"))
    return e_in, e_in - used


@pytest.mark.parametrize("mu", [1.0, 0.1])
def test_hard_start_is_capped_at_the_free_roller_limit_and_balances(fmu_dir, mu):
    graph = prepare(ROBOT / "hard_start.yaml", fmu_dir=fmu_dir, parameters={"body.mu": mu})
    results = master.simulate(graph, graph.scenario.experiment)
    t, vy = np.asarray(results.time), np.asarray(results["body.vy"])
    eps = np.asarray(results["body.eps"])
    sliding = np.all([np.abs(results[f"body.slip{k}"]) > 3 * eps for k in range(1, 5)], axis=0)
    window = sliding & (t > 0.01) & (vy < 1.2)
    assert window.sum() > 20
    slope = np.polyfit(t[window], vy[window], 1)[0]
    assert slope == pytest.approx(mu * G * math.sin(ALPHA), rel=0.01)
    assert np.max(np.abs(results["body.vx"])) < 1e-9 and np.max(np.abs(results["body.w"])) < 1e-9
    e_in, residual = energy_residual(results)
    assert abs(residual) < 0.01 * e_in
    assert np.max(np.abs(results["motor1.V"])) == pytest.approx(V_S)     # the supply clamps it
    # no chatter across the two FMUs: the reaction rises and falls, it does not flip step by step
    load = np.asarray(results["body.tau_load1"])
    assert np.sum(np.abs(np.diff(load))) <= 3 * (load.max() - load.min())


def test_hard_start_report_names_the_clamp_and_the_slip(fmu_dir, tmp_path):
    graph = prepare(ROBOT / "hard_start.yaml", fmu_dir=fmu_dir)
    lines = []
    outcome = run(graph, tmp_path / "out", plots=False, quiet=False, log=lines.append)
    assert outcome.results.complete and outcome.summary["drive_train"]["motors"]
    text = "\n".join(lines)
    for k in range(1, 5):
        assert f"motor{k}: |V| at V_supply = 12 V" in text
    assert "sliding (|slip| >= 3 eps) on slip1, slip2, slip3, slip4" in text


@pytest.mark.parametrize("mode", [m for m in MODES if m.key in
                                  ("forward", "left", "diagonal", "spin_ccw")],
                         ids=lambda m: m.key)
def test_motion_modes_keep_their_wheel_signs_under_dynamics(fmu_dir, mode):
    graph = prepare(ROBOT / "hard_start.yaml", fmu_dir=fmu_dir, parameters={
        "source.vx_expr": repr(mode.vx), "source.vy_expr": repr(mode.vy),
        "source.w_expr": repr(mode.w)})
    graph, exp = with_experiment(graph, stop_time=0.5)
    results = master.simulate(graph, exp)
    speeds = [results.final(f"motor{k}.w") for k in range(1, 5)]
    peak = max(abs(s) for s in speeds)
    signs = ["0" if abs(s) <= 1e-3 * peak else ("+" if s > 0 else "-") for s in speeds]
    assert signs == wheel_sign_list(mode.vx, mode.vy, mode.w)


# What the drive train's 10 s runs here ask (how far the end is from a point 4 to 6 mm away)
# the trapezoidal master answers as the scenarios' quadratic one does, to 2e-8 m at their
# step of 1e-3 s (robot/circle with mu = 5: 5.710676e-3 against 5.710658e-3 m; track_circle
# 4.297842e-3 against 4.297837e-3 m), in 0.4x the time: one pass a step, no prediction
ONE_PASS = "trapezoidal"


def circle_error(fmu_dir, **parameters) -> float:
    """The end's distance from the kinematic end point (the run alone: its estimate's pair,
    a tenth of its time, is not read here)."""
    graph = prepare(ROBOT / "circle.yaml", fmu_dir=fmu_dir, parameters=parameters,
                    estimate="none", master_name=ONE_PASS)
    results = master.simulate(graph, graph.scenario.experiment, keep_rows=2)
    return math.hypot(results.final("pose.x") - KINEMATIC_END[0],
                      results.final("pose.y") - KINEMATIC_END[1])


@pytest.mark.heavy(12)
def test_seed_circle_with_large_mu_ends_within_1_cm_and_nearer_with_higher_gains(fmu_dir):
    default = circle_error(fmu_dir, **{"body.mu": 5.0})
    stiffer = circle_error(fmu_dir, **{"body.mu": 5.0, "kp": 2 * KP, "ki": 4 * KI})
    assert default < 0.01
    assert stiffer < default


@pytest.mark.parametrize("name", ["circle", "hard_start", "track_circle"])
def test_robot_scenarios_pass_strict_validation(name):
    proc = subprocess.run(cli_args("validate", "--strict", str(ROBOT / f"{name}.yaml")),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert ": ok - 8 components" in proc.stdout


@pytest.mark.heavy(4)
def test_follower_with_motors_and_floor_reaches_the_reference(fmu_dir):
    graph = prepare(ROBOT / "track_circle.yaml", fmu_dir=fmu_dir, estimate="none",
                    master_name=ONE_PASS)
    results = master.simulate(graph, graph.scenario.experiment, keep_rows=2)
    # the follower's reference at t = 10 is the seed's kinematic end point
    assert math.hypot(results.final("pose.x") - KINEMATIC_END[0],
                      results.final("pose.y") - KINEMATIC_END[1]) < 0.01


@pytest.mark.parametrize("host", ["ecos-cli"])
def test_hard_start_ssp_runs_in_ecos_program_as_our_jacobi(fmu_dir, tmp_path, host):
    from helpers import run_host_or_skip
    from mecanum_fmu.interop.cross_check import HOST_TOLERANCE, compared_outputs, difference, \
        ours_jacobi
    from mecanum_fmu.interop.ssp_write import export_ssp
    graph = prepare(ROBOT / "hard_start.yaml", master_name="jacobi", fmu_dir=fmu_dir)
    graph, exp = with_experiment(graph, stop_time=0.2)
    ssp = export_ssp(graph, tmp_path / "hard_start.ssp")
    names = compared_outputs(graph)
    assert "body.vy" in names and "motor1.w" in names     # the states, no feedthrough
    ours = ours_jacobi(graph, names)
    theirs = run_host_or_skip(host, ssp, start=0.0, stop=0.2, step=exp.step_size,
                              variables=names)
    assert theirs.end_time == pytest.approx(0.2, abs=1e-9)
    assert difference(theirs.values, ours.values, names) <= HOST_TOLERANCE[host]  # its CSV
    assert theirs.values["body.vy"] > 0.5      # it moved: the free-roller limit is 6.9 m/s^2


def test_sweep_over_mu_and_the_four_motors_kp_plans_one_run_per_pair(fmu_dir):
    from mecanum_fmu.sweep.cluster import prepare_sweep
    sweep, graph, runs = prepare_sweep(ROBOT / "sweep_mu_kp.yaml", fmu_dir)
    pairs = []
    for run_ in runs:
        gains = {run_.values[r] for r in sweep.varied if r.variable == "kp"}
        assert len(gains) == 1 and len([r for r in sweep.varied if r.variable == "kp"]) == 4
        pairs.append((next(v for r, v in run_.values.items() if r.variable == "mu"), *gains))
    assert pairs == [(mu, kp) for mu in (1.0, 0.3, 0.2, 0.1) for kp in (0.5, 4.0)]
    assert graph.scenario.experiment.stop_time == 4.0
    # the sweep's step_size (0.002, its `experiment:`) is the regularisation's reference step
    assert graph.instance("body").value("h_ref") == graph.scenario.experiment.step_size == 0.002


def test_a_fine_step_reference_run_confirms_the_error_estimate(fmu_dir):
    """No closed form for the dynamics: a run at h / 8 of the same model (the graph keeps
    body.h_ref, so eps stays eps_rate h_ref) stands in for it, and the estimate of the run at
    h must be within a factor 3 of its distance from that reference."""
    graph = prepare(ROBOT / "hard_start.yaml", fmu_dir=fmu_dir)
    graph, exp = with_experiment(graph, stop_time=0.5)
    results = master.simulate(graph, exp)
    estimate = master.estimate_error(graph, results)["error_estimate"]["pose.y"]["end"]
    fine_graph, fine = with_experiment(graph, stop_time=0.5, step_size=exp.step_size / 8)
    reference = master.simulate(fine_graph, fine, keep_rows=2).final("pose.y")
    actual = abs(results.final("pose.y") - reference)
    assert fine_graph.instance("body").value("h_ref") == exp.step_size    # one model
    assert actual > 1e-5                     # the step matters: the coupling is first order
    assert actual / 3 <= estimate <= 3 * actual


EPS_RATE, EPS_MIN = 40.0, 1.0e-3      # MecanumDynamics' defaults (docs/robot.md, Stability)


def test_the_regularisation_is_fixed_for_the_run_at_the_scenario_step(fmu_dir):
    """eps = max(eps_min, eps_rate h_ref), h_ref the experiment's step_size unless the scenario
    sets it, the same at every step (before: eps followed each doStep's h)."""
    import yaml
    path = ROBOT / "hard_start.yaml"
    step = yaml.safe_load(path.read_text())["experiment"]["step_size"]
    assert prepare(path, fmu_dir=fmu_dir).instance("body").value("h_ref") == step
    finer = prepare(path, fmu_dir=fmu_dir, step_size=step / 2)
    assert finer.instance("body").value("h_ref") == step / 2      # the run's step
    own = prepare(path, fmu_dir=fmu_dir, parameters={"body.h_ref": 2e-3}, stop_time=0.05)
    assert own.instance("body").value("h_ref") == 2e-3            # the scenario's wins
    for graph, exp in (with_experiment(own, step_size=5e-4),
                       with_experiment(own, master="adaptive", tolerance=1e-3)):
        eps = np.asarray(master.simulate(graph, exp)["body.eps"])
        # the adaptive master's rows are interpolated between its steps: to round-off
        assert eps == pytest.approx(np.full(len(eps), max(EPS_MIN, EPS_RATE * 2e-3)),
                                    rel=1e-13)


def _body_rates(vx, vy, w, wheels, mu, eps, L=0.16, W=0.12, R=0.06, m=4.0, Iz=0.053):
    """The planar body on four free rollers (docs/robot.md, The floor), written out here."""
    fx = fy = torque = 0.0
    for (x, y), sign, wheel in zip(((L, W), (-L, W), (-L, -W), (L, -W)), (-1, 1, -1, 1), wheels):
        ux, uy = sign * math.cos(ALPHA), math.sin(ALPHA)
        slip = (vx - w * y) * ux + (vy + w * x) * uy - R * math.sin(ALPHA) * wheel
        force = -mu * m * G / 4 * math.tanh(slip / eps)
        fx, fy, torque = fx + force * ux, fy + force * uy, torque + force * (x * uy - y * ux)
    return [fx / m + w * vy, fy / m - w * vx, torque / Iz]


@pytest.mark.parametrize("step", [4e-3, 1e-3, 2.5e-4])
def test_the_body_steps_one_model_at_any_step(fmu_dir, step):
    """MecanumDynamics alone, its wheels held: at any step (its RK4 substeps follow it) the
    twist is the ODE's solution with eps = eps_rate h_ref, h_ref = 1e-3, solved here by
    scipy. A master's step and its two half steps therefore step the same model."""
    from scipy.integrate import solve_ivp
    wheels, mu = (20.0, 4.0, 4.0, 20.0), 0.5      # forward and turning left
    doc = {"experiment": {"start_time": 0.0, "stop_time": 0.04, "step_size": 1e-3},
           "components": {"body": {"fmu": "MecanumDynamics", "parameters": {
               "mu": mu, "vy0": 0.3, **{f"w{k}": v for k, v in enumerate(wheels, 1)}}}},
           "connections": []}
    graph, exp = with_experiment(prepare(doc, fmu_dir=fmu_dir), step_size=step)
    results = master.simulate(graph, exp)
    eps = max(EPS_MIN, EPS_RATE * 1e-3)
    exact = solve_ivp(lambda t, x: _body_rates(*x, wheels, mu, eps), (0.0, 0.04),
                      [0.0, 0.3, 0.0], rtol=1e-12, atol=1e-12).y[:, -1]
    # the substeps' RK4 error (contact rate x substep 0.25) is a few 1e-9; eps following the
    # step (0.16 m/s at h = 4e-3, 0.01 m/s at 2.5e-4) moves it by 5e-3 to 0.27 (scipy)
    for name, value in zip(("body.vx", "body.vy", "body.w"), exact):
        assert results.final(name) == pytest.approx(value, abs=2e-8)
    assert exact[2] > 0.5 and exact[1] > 0.35       # it turned and sped up


def test_the_adaptive_master_on_a_drive_train_is_not_warned_about(fmu_dir):
    """--tolerance finishes a drive train (docs/robot.md, Stability): the warning that it did
    not is gone (nothing for validate --strict to refuse)."""
    warned = prepare(ROBOT / "hard_start.yaml", fmu_dir=fmu_dir, tolerance=1e-3).warnings
    assert not [w for w in warned if "drive train" in w or "components.body" in w]


@pytest.mark.parametrize("La", [0.0, 2.0e-3])
def test_the_motors_inlined_rates_are_the_methods_bit_for_bit(La):
    """Motor._rates (voltage() and current() inlined, for speed) gives the same bits as the
    readable methods, inside and outside both clamps, with and without inductance."""
    import random
    from mecanum_fmu.models.blocks.motor import DEFAULT_MOTOR, Motor
    values = dict(DEFAULT_MOTOR, La=La)
    m = Motor(*(values[k] for k in ("V_supply", "stall_torque", "stall_current",
                                    "no_load_speed", "no_load_current", "La", "J", "kp", "ki",
                                    "i_max")))
    rng = random.Random(7)
    clamped = 0
    for _ in range(5000):
        w, z, i, tau = (rng.uniform(-40, 40), rng.uniform(-15, 15), rng.uniform(-8, 8),
                        rng.uniform(-2, 2))
        w_ref = w + rng.uniform(-8, 8)
        V, wanted = m.voltage(w, z, w_ref)
        clamped += V != wanted
        j = m.current(w, i, V)
        di = (V - m.R_a * j - m.k_e * w) / La if La > 0.0 else 0.0
        assert m.rates(w, z, i, w_ref, tau) == (
            (m.k_t * j - m.b * w - tau) / m.J, m.ki * (w_ref - w) + m.k_b * (V - wanted), di,
            V * j, m.R_a * j * j, m.b * w * w, (m.k_e - m.k_t) * j * w, tau * w)
    assert 100 < clamped < 4900         # both sides of the clamps were met
