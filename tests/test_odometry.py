"""Encoders, gyro and odometry (docs/robot.md): each check against an independent computation.

The references come from closed forms written out here: ros2_controllers' odometry formulas as
docs/spec.md states them (ROS frame, fl/fr/rl/rr), the geometric sum of Euler's rotations, the
seed circle's wheel angles (SPEC section 5), the telescoping bound of quantisation, and the
random-walk variances of white noise through the forward kinematics.
"""
import math
from contextlib import contextmanager

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from helpers import ROOT
from mecanum_fmu import master
from mecanum_fmu.models.blocks.kinematics import wheel_to_center
from mecanum_fmu.models.blocks.odometry import euler_step
from mecanum_fmu.models.blocks.sensors import ENCODER_SALT, GYRO_SALT, standard_normal
from mecanum_fmu.runner import prepare
from mecanum_fmu.runtime import RUNTIME

OPEN = ROOT / "scenarios" / "robot" / "belief_open_circle.yaml"
TRACK = ROOT / "scenarios" / "robot" / "belief_track_circle.yaml"
R, L, W = 0.06, 0.16, 0.12
K = L + W                                     # L + W cot(45 deg): ros2_controllers' k
ENCODERS = ("enc1", "enc2", "enc3", "enc4")
SEEDS = {"enc1": 1, "enc2": 2, "enc3": 3, "enc4": 4}   # belief_open_circle's


def ideal(cpr=0, **more):
    """belief_open_circle's sensors made ideal: no noise, no gyro bias, cpr as given."""
    values = {f"{e}.{p}": v for e in ENCODERS for p, v in (("cpr", cpr), ("sigma", 0.0))}
    values.update({"gyro.sigma": 0.0, "gyro.bias": 0.0})
    values.update(more)
    return values


def simulate(fmu_dir, parameters, path=OPEN, **experiment):
    graph = prepare(path, fmu_dir=fmu_dir, parameters=parameters, **experiment)
    return master.simulate(graph, graph.scenario.experiment)


def pose_gap(results, a="odom", b="pose"):
    return max(float(np.max(np.abs(results[f"{a}.{v}"] - results[f"{b}.{v}"])))
               for v in ("x", "y", "theta"))


# ------------------------------------------------------------------ ros2_controllers' formulas


def ros2_odometry_twist(w_fl, w_fr, w_rl, w_rr, r, k):
    """docs/spec.md section 10, in the ROS frame (x forward, y left)."""
    return (r / 4 * (w_fl + w_fr + w_rl + w_rr), r / 4 * (-w_fl + w_fr + w_rl - w_rr),
            r / (4 * k) * (-w_fl + w_fr - w_rl + w_rr))


def test_ros2_formulas_are_the_seed_forward_kinematics_at_45_degrees():
    rng = np.random.default_rng(3)
    for w1, w2, w3, w4 in rng.normal(0, 10, (20, 4)):
        # wheels: fl = 2, fr = 1, rl = 3, rr = 4; ROS (x, y) = ours (vy, -vx)
        vx_ros, vy_ros, wz = ros2_odometry_twist(w2, w1, w3, w4, R, K)
        vx, vy, w = wheel_to_center(w1, w2, w3, w4, math.pi / 4, L, W, R)
        assert (vy, -vx, w) == pytest.approx((vx_ros, vy_ros, wz), abs=1e-12)
    # at another roller angle ros2's formulas (no tan(alpha), k = L + W) are not the chassis'
    vx, vy, w = wheel_to_center(1.0, -1.0, 1.0, -1.0, math.radians(30), L, W, R)
    vx_ros, vy_ros, _ = ros2_odometry_twist(-1.0, 1.0, 1.0, -1.0, R, K)
    assert abs(-vx - vy_ros) > 0.01


# ------------------------------------------------------------------ ideal sensors, exact update


@pytest.mark.parametrize("master_name", ["gauss-seidel", "trapezoidal"])
@pytest.mark.parametrize("heading", ["wheels", "gyro"])
def test_ideal_sensors_with_the_exact_update_are_the_true_pose(fmu_dir, master_name, heading):
    """Turning (w = 0.5 cos 0.7t): encoders without noise or quantisation (and the gyro
    without bias or noise, for the heading), update exact."""
    values = ideal(**{"odom.update": "exact", "odom.heading": heading,
                      "source.w_expr": "0.5*cos(0.7*t)"})
    results = simulate(fmu_dir, values, master_name=master_name)
    assert abs(results.final("pose.theta")) > 0.3            # it turns
    assert pose_gap(results) <= 1e-9


def test_a_huge_cpr_stays_within_its_tick(fmu_dir):
    """cpr = 2^31 - 1 (the largest Integer): one tick is 2.9e-9 rad, so the belief is off by
    at most the quantisation bound (test below) for that tick, here a few 1e-10 m."""
    cpr = 2**31 - 1
    results = simulate(fmu_dir, ideal(cpr, **{"odom.update": "exact"}), master_name="gauss-seidel")
    tick = 2 * math.pi / cpr
    assert pose_gap(results) <= 2 * R * tick * (1 + 10.0 / K)
    assert pose_gap(results) <= 1e-9


# ------------------------------------------------------------------ Euler's error, closed form


def euler_sum(vx, vy, w, period, n):
    """ros2's Euler: heading first, so step k moves along exp(i k w P): a geometric sum."""
    z = complex(vx, vy) * period
    phi = w * period
    q = complex(math.cos(phi), math.sin(phi))
    total = z * q * (1 - q**n) / (1 - q)
    return total.real, total.imag, n * phi


def exact_arc(vx, vy, w, t):
    z = complex(vx, vy) * (complex(math.cos(w * t), math.sin(w * t)) - 1) / complex(0, w)
    return z.real, z.imag, w * t


def test_euler_error_on_a_turning_run_is_the_closed_form_sum(fmu_dir):
    vx, vy, w, period, stop = 0.2, 0.5, 0.8, 0.05, 10.0
    results = simulate(fmu_dir, ideal(**{"source.vx_expr": str(vx), "source.vy_expr": str(vy),
                                         "source.w_expr": str(w), "period": period}),
                       step_size=period)
    n = round(stop / period)
    euler = euler_sum(vx, vy, w, period, n)
    exact = exact_arc(vx, vy, w, stop)
    believed = tuple(results.final(f"odom.{v}") for v in ("x", "y", "theta"))
    true = tuple(results.final(f"pose.{v}") for v in ("x", "y", "theta"))
    assert believed == pytest.approx(euler, abs=1e-9)
    assert true == pytest.approx(exact, abs=1e-9)
    gap = math.dist(euler[:2], exact[:2])
    assert gap > 0.01                                          # Euler's error is visible
    assert math.dist(believed[:2], true[:2]) == pytest.approx(gap, rel=1e-6)


def test_euler_is_exact_on_the_seed_circle(fmu_dir):
    """w = 0: the heading stays 0 and each sample's mean speed times its period is exact."""
    results = simulate(fmu_dir, ideal(), master_name="gauss-seidel")
    assert pose_gap(results) <= 1e-9


# ------------------------------------------------------------------ quantisation alone


def circle_wheel_angles(t):
    """SPEC section 5 at alpha = 45 deg: w1 = w3 = (cos t - sin t)/R, w2 = w4 = (cos t + sin t)/R,
    integrated from 0."""
    a13 = (np.sin(t) + np.cos(t) - 1) / R
    a24 = (np.sin(t) - np.cos(t) + 1) / R
    return {"enc1": a13, "enc2": a24, "enc3": a13, "enc4": a24}


CPRS = {"enc1": 64, "enc2": 50, "enc3": 71, "enc4": 57}   # unequal: the wheels' errors differ


def quantised(fmu_dir, stop):
    values = ideal(**{"odom.update": "euler"}, **{f"{e}.cpr": c for e, c in CPRS.items()})
    # the quadratic master: the wheel angle the encoders integrate is the closed form's to 1e-6
    return simulate(fmu_dir, values, stop_time=stop)


def quantisation_bound(results):
    """(heading bound, position bound at every row) from one tick per wheel: the heading is
    R/(4k) times a signed sum of the four wheel angles, so off by less than R/(4k) sum(tick);
    the body-frame displacement (R/4 times signed sums, tan 45 deg = 1) by less than
    sqrt2 R/4 sum(tick) = E at every sample (the counts telescope). Euler turns each sample's
    displacement by the believed heading: summed by parts, the position is off by at most
    E (1 + the believed heading's total variation) + the heading bound times the distance."""
    ticks = sum(2 * math.pi / c for c in CPRS.values())
    heading, e = R / (4 * K) * ticks, math.sqrt(2) * R / 4 * ticks
    variation = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(results["odom.theta"])))])
    distance = results.time                                     # the circle's speed: 1 m/s
    return heading, e * (1 + variation) + heading * distance


@pytest.mark.parametrize("stop", [10.0, 40.0])
def test_quantisation_each_wheel_off_by_less_than_one_tick(fmu_dir, stop):
    results = quantised(fmu_dir, stop)
    angles = circle_wheel_angles(results.time)
    for enc, cpr in CPRS.items():
        tick = 2 * math.pi / cpr
        counted = np.cumsum(results[f"{enc}.w_meas"]) * 0.01    # every row is a sample
        error = np.abs(counted - angles[enc])
        # less than one tick, plus the master's own error on the wheel angle (4e-7 rad at 40 s)
        assert np.max(error) < tick + 1e-6
        assert np.max(error) > 0.5 * tick                       # quantisation does show
    heading, position = quantisation_bound(results)
    theta = np.abs(results["odom.theta"] - results["pose.theta"])
    assert np.max(theta) < heading and np.max(theta) > 0.1 * heading
    gap = np.hypot(results["odom.x"] - results["pose.x"], results["odom.y"] - results["pose.y"])
    assert np.all(gap <= position)


# ------------------------------------------------------------------ white noise alone


def noisy_straight_runs(runs, n, period, sigma, speed):
    """Euler odometry of `runs` straight drives (vy = speed, w = 0) from encoders with white
    noise of sd sigma per sample, drawn by the sensors' own generator (run r, wheel i: seed
    4r + i). Returns the believed (x, y) after each sample, shape runs x n."""
    true_w = speed / R
    xs, ys = np.empty((runs, n)), np.empty((runs, n))
    for r in range(runs):
        x = y = th = 0.0
        seeds = [4 * r + i for i in range(4)]
        for k in range(1, n + 1):
            meas = [true_w + sigma * standard_normal(s, ENCODER_SALT, k) for s in seeds]
            vx, vy, w = wheel_to_center(*meas, math.pi / 4, L, W, R)
            x, y, th = euler_step(x, y, th, vx, vy, w, period)
            xs[r, k - 1], ys[r, k - 1] = x, y
    return xs, ys


def random_walk_sd(n, period, sigma, speed):
    """The prediction: each twist component is a fixed combination of the four wheel noises
    (sd R sigma/2 along and across, R sigma/(2k) in yaw; independent, the combinations are
    orthogonal). Along-track: a random walk of the speed, sd (R sigma/2) P sqrt(n). Cross-track:
    that of vx, plus the heading's random walk times the speed, summed over the samples
    (Euler uses the new heading: sample j's yaw noise acts on n - j + 1 steps)."""
    s_lin, s_yaw = R * sigma / 2, R * sigma / (2 * K)
    along = s_lin * period * np.sqrt(n)
    squares = n * (n + 1) * (2 * n + 1) / 6
    cross = np.sqrt((s_lin * period) ** 2 * n + (speed * s_yaw * period**2) ** 2 * squares)
    return along, cross


def test_white_noise_drift_is_the_random_walk(capsys):
    runs, n, period, sigma, speed = 1000, 160, 0.05, 0.5, 0.5
    xs, ys = noisy_straight_runs(runs, n, period, sigma, speed)
    rows = []
    for m in (20, 40, 80, 160):
        along, cross = np.std(ys[:, m - 1] - speed * m * period), np.std(xs[:, m - 1])
        p_along, p_cross = random_walk_sd(m, period, sigma, speed)
        rows.append((m * period, along, p_along, cross, p_cross))
        assert along == pytest.approx(p_along, rel=0.10)
        assert cross == pytest.approx(p_cross, rel=0.10)
    t, along, _, cross, _ = np.array(rows).T
    slope_along = np.polyfit(np.log(t), np.log(along), 1)[0]
    slope_cross = np.polyfit(np.log(t[-2:]), np.log(cross[-2:]), 1)[0]
    assert slope_along == pytest.approx(0.5, abs=0.05)           # sqrt(t)
    assert 1.3 < slope_cross < 1.55                              # towards t^1.5
    with capsys.disabled():
        print("\n  t [s]   along sd [mm] (predicted)   cross sd [mm] (predicted)")
        for row in rows:
            print("  {:5.1f}   {:8.3f} ({:8.3f})       {:8.3f} ({:8.3f})".format(
                row[0], *(1e3 * v for v in row[1:])))
        print(f"  log-log slopes: along {slope_along:.3f}, cross {slope_cross:.3f} (last two)")


# ------------------------------------------------------------------ a wheel-radius error alone


def test_a_radius_error_is_a_scale_error(fmu_dir):
    """All four real wheels dR larger than the R the controller and the odometry assume (w =
    0): the true path is the commanded circle scaled by (R + dR)/R about the start, the belief
    is the commanded circle itself. With the odometry's own R off instead, the belief is the
    true path scaled by R_odom / R."""
    dR, end = 0.0006, np.array([1 - math.cos(10.0), math.sin(10.0)])
    # the quadratic master: 1.8e-8 m from the closed form on the seed circle (make run)
    results = simulate(fmu_dir, ideal(**{f"w2c.dR{i}": dR for i in range(1, 5)}))
    true = np.array([results.final("pose.x"), results.final("pose.y")])
    believed = np.array([results.final("odom.x"), results.final("odom.y")])
    assert true == pytest.approx((R + dR) / R * end, abs=1e-7)
    assert believed == pytest.approx(end, abs=1e-7)
    assert np.linalg.norm(true - believed) == pytest.approx(dR / R * np.linalg.norm(end), rel=1e-5)
    results = simulate(fmu_dir, ideal(**{"odom.R": R - dR}))
    for v in ("x", "y"):
        assert results.final(f"odom.{v}") == pytest.approx((R - dR) / R * results.final(f"pose.{v}"),
                                                           abs=1e-7)


# ------------------------------------------------------------------ noise that reproduces


def test_noise_is_indexed_by_sample_not_by_step(fmu_dir):
    """A constant twist (the mean over a sample is exact at any step): each encoder's and the
    gyro's samples at h = 0.01, 0.005 and 0.0025 s are the same, and their noise is sigma
    times the generator's draw for (seed, sample index)."""
    constant = {"source.vx_expr": "0.3", "source.vy_expr": "0.6", "source.w_expr": "0.4"}
    values = ideal(**constant, **{f"{e}.sigma": 0.05 for e in ENCODERS},
                   **{"gyro.sigma": 0.002, "gyro.bias": 0.001})
    samples = {}
    for h in (0.01, 0.005, 0.0025):
        results = simulate(fmu_dir, values, step_size=h, stop_time=2.0)
        on_sample = np.isclose(results.time / 0.01, np.round(results.time / 0.01), atol=1e-9)
        samples[h] = {c: results[c][on_sample][1:] for c in
                      [f"{e}.w_meas" for e in ENCODERS] + ["gyro.w_meas"]}
    for h in (0.005, 0.0025):
        for column, values_h in samples[h].items():
            assert values_h == pytest.approx(samples[0.01][column], abs=1e-9), column
    true_w = 0.6 / R + (K * 0.4) / R - 0.3 / R                # SPEC section 3, wheel 1
    k = np.arange(1, len(samples[0.01]["enc1.w_meas"]) + 1)
    draws = np.array([standard_normal(SEEDS["enc1"], ENCODER_SALT, int(i)) for i in k])
    assert samples[0.01]["enc1.w_meas"] == pytest.approx(true_w + 0.05 * draws, abs=1e-9)
    draws = np.array([standard_normal(5, GYRO_SALT, int(i)) for i in k])
    assert samples[0.01]["gyro.w_meas"] == pytest.approx(0.4 + 0.001 + 0.002 * draws, abs=1e-9)


def test_the_generator_is_standard_normal():
    draws = np.array([standard_normal(7, ENCODER_SALT, k) for k in range(100_000)])
    assert abs(draws.mean()) < 0.02 and abs(draws.std() - 1) < 0.01
    other = np.array([standard_normal(8, ENCODER_SALT, k) for k in range(100_000)])
    assert abs(np.corrcoef(draws, other)[0, 1]) < 0.02
    gyro = np.array([standard_normal(7, GYRO_SALT, k) for k in range(100_000)])
    assert abs(np.corrcoef(draws, gyro)[0, 1]) < 0.02


@contextmanager
def encoder(fmu_dir, **values):
    """An Encoder instance on fmpy, initialised with `values` (Real or Integer)."""
    unzipdir = RUNTIME.extracted(fmu_dir / "Encoder.fmu")
    md = read_model_description(unzipdir)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="enc")
    fmu.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    try:
        for name, value in values.items():
            (fmu.setInteger if isinstance(value, int) else fmu.setReal)([vr[name]], [value])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        yield fmu, vr
    finally:
        fmu._functions["fmi2FreeInstance"](fmu.component)   # never unload the library


def test_ticks_count_the_wheel_angle_as_a_32_bit_counter(fmu_dir):
    """At a constant 200 rad/s for 100 steps of 0.01 s the count is floor(angle cpr / 2 pi)
    after each step; with cpr = 2^31 - 1 it passes 2^31 and wraps to negative, as a 32-bit
    register does, while w_meas (from the unwrapped counts) stays right."""
    for cpr in (1000, 2**31 - 1):
        with encoder(fmu_dir, cpr=cpr, period=0.01) as (fmu, vr):
            seen = []
            for k in range(100):
                fmu.setReal([vr["w"]], [200.0])
                fmu.doStep(0.01 * k, 0.01)
                seen.append((fmu.getInteger([vr["ticks"]])[0], fmu.getReal([vr["w_meas"]])[0]))
        for k, (ticks, w_meas) in enumerate(seen, start=1):
            count = math.floor(200.0 * 0.01 * k * cpr / (2 * math.pi))
            assert ticks == (count + 2**31) % 2**32 - 2**31
            assert abs(w_meas - 200.0) <= 2 * math.pi / cpr / 0.01 + 1e-6
    assert any(t < 0 for t, _ in seen)                           # it wrapped


def test_a_rollback_repeats_the_samples(fmu_dir):
    """fmi2GetFMUstate after 7 steps, 20 more steps, fmi2SetFMUstate, the same 20 again: the
    same samples, noise and counts (the state carries the angle, the last count and the
    sample index: the generator's state)."""
    with encoder(fmu_dir, cpr=1024, sigma=0.1, seed=9, period=0.01) as (fmu, vr):
        def steps(t0):
            out = []
            for k in range(20):
                fmu.setReal([vr["w"]], [3.0 + math.sin(t0 + 0.01 * k)])
                fmu.doStep(t0 + 0.01 * k, 0.01)
                out.append((fmu.getReal([vr["w_meas"]])[0], fmu.getInteger([vr["ticks"]])[0]))
            return out
        for k in range(7):
            fmu.setReal([vr["w"]], [3.0])
            fmu.doStep(0.01 * k, 0.01)
        state = fmu.getFMUstate()
        first = steps(0.07)
        fmu.setFMUstate(state)
        again = steps(0.07)
        fmu.freeFMUstate(state)
    assert again == first
    assert len({w for w, _ in first}) == 20                      # the noise moves every sample


def test_validate_warns_when_the_step_does_not_divide_the_period(fmu_dir):
    graph = prepare(OPEN, fmu_dir=fmu_dir, step_size=0.003)
    assert any("period = 0.01 s is not a whole number of steps of 0.003 s" in w
               and "up to one step late" in w for w in graph.warnings)
    graph = prepare(OPEN, fmu_dir=fmu_dir, step_size=0.02)
    assert any("2 samples fall in one step and only the last is seen" in w for w in graph.warnings)
    assert not any("period" in w for w in prepare(OPEN, fmu_dir=fmu_dir).warnings)


# ------------------------------------------------------------------ the drift study's sweep


def test_a_sweep_draws_a_noise_seed_per_run(tmp_path, fmu_dir):
    """`integers: [low, high]` draws whole numbers low <= n < high for an Integer parameter
    (NumPy's integers on the sweep's generator, in file order), so each run has its own noise."""
    from mecanum_fmu.errors import ScenarioError
    from mecanum_fmu.sweep.cluster import prepare_sweep
    path = tmp_path / "s.yaml"
    path.write_text(f"name: s\nscenario: {OPEN}\nrandom:\n  samples: 30\n  seed: 4\n"
                    "  enc1.seed: {integers: [0, 1000]}\n  enc1.sigma: {uniform: [0.0, 0.1]}\n")
    _, _, runs = prepare_sweep(path, fmu_dir)
    rng = np.random.default_rng(4)
    seeds, sigmas = rng.integers(0, 1000, 30), rng.uniform(0.0, 0.1, 30)
    assert [r.values[next(k for k in r.values if str(k) == "enc1.seed")] for r in runs] == list(seeds)
    assert all(isinstance(v, int) for r in runs for k, v in r.values.items() if str(k) == "enc1.seed")
    assert [r.values[next(k for k in r.values if str(k) == "enc1.sigma")] for r in runs] == list(sigmas)
    for bad, words in (("enc1.sigma: {integers: [0, 5]}", "random draws are real numbers"),
                       ("enc1.seed: {integers: [3, 3]}", "whole numbers with low < high"),
                       ("enc1.seed: {integers: [0.5, 3]}", "whole numbers with low < high")):
        path.write_text(f"name: s\nscenario: {OPEN}\nrandom:\n  samples: 3\n  {bad}\n")
        with pytest.raises(ScenarioError, match=words):
            prepare_sweep(path, fmu_dir)


def test_the_same_noise_on_one_worker_or_two(tmp_path, fmu_dir):
    """Six runs with drawn seeds and noise, on one Dask worker and on two: the same belief,
    bit for bit (the noise is a function of seed and sample index; no process state)."""
    from mecanum_fmu.sweep.cluster import execute, prepare_sweep
    path = tmp_path / "s.yaml"
    path.write_text(f"name: s\nscenario: {OPEN}\nexperiment: {{stop_time: 1.0}}\nrandom:\n"
                    "  samples: 6\n  seed: 2\n"
                    + "".join(f"  {e}.seed: {{integers: [0, 1000]}}\n" for e in ENCODERS)
                    + "  enc1.sigma: {uniform: [0.05, 0.1]}\n")
    _, graph, runs = prepare_sweep(path, fmu_dir)
    ends = {}
    for workers in (1, 2):
        done = execute(graph, runs, workers=workers)
        ends[workers] = {i: (r.ends["odom.x"], r.ends["odom.y"], r.ends["odom.theta"])
                         for i, r in done.results.items()}
    assert sorted(ends[1]) == list(range(6)) and ends[1] == ends[2]
    assert len({v for v in ends[1].values()}) == 6               # each run its own noise


def test_a_loop_on_belief_reports_the_drift(fmu_dir, tmp_path):
    """belief_track_circle: the follower holds the belief on the reference, so the true pose's
    tracking error is the belief's drift; summary.json says so and gives the drift."""
    import json
    from mecanum_fmu.runner import run
    graph = prepare(TRACK, fmu_dir=fmu_dir)
    lines = []
    run(graph, tmp_path, plots=False, quiet=False, log=lines.append)
    summary = json.loads((tmp_path / "summary.json").read_text())
    belief = summary["belief"]
    assert belief["instance"] == "odom" and belief["closes_the_loop"] is True
    ref, end = summary["reference_end_pose"], summary["end_pose"]
    # the belief ends on the reference within the follower's lag: it acts on a belief up to a
    # sample period old (docs/masters.md, "Samples"), and the reference moves at 1 m/s, so it
    # trails by about half a period of travel, v P / 2 = 1 m/s x 5 ms (between a quarter and
    # a whole period of travel; a follower fed each sample a step early trailed by 0.3 mm);
    # the truth is 27 mm off it
    trail = math.dist((belief["end_pose"]["x"], belief["end_pose"]["y"]), (ref["x"], ref["y"]))
    assert 0.25 * 0.01 < trail < 0.01
    drift = math.dist((belief["end_pose"]["x"], belief["end_pose"]["y"]), (end["x"], end["y"]))
    assert belief["drift"]["position"] == pytest.approx(drift, rel=1e-12) and drift > 0.01
    assert any("fed the odometry's belief" in line for line in lines)
    assert "no estimate" in summary["error_estimate_method"]


# ------------------------------------------------------------------ the step order


def test_a_block_steps_after_the_blocks_feeding_it(fmu_dir):
    """The Odometry steps after its Encoders (their outputs depend on no input, so the
    variable-level sort alone put it first and it read the step before's samples); the
    orders of the existing scenarios are those the sort gave before (printed by `validate`
    on main)."""
    order = [i.name for i in prepare(OPEN, fmu_dir=fmu_dir).instances]
    assert all(order.index("odom") > order.index(e) for e in ENCODERS + ("gyro",))
    before = {"circle.yaml": "source c2w w2c pose",
              "closed_loop/track_circle.yaml": "pose follower c2w w2c",
              "chassis/compare.yaml": "command car_command mecanum_c2w omni_c2w car mecanum_w2c "
                                      "omni_w2c car_pose mecanum_pose omni_pose",
              "chassis/omni_field_circle.yaml": "command pose field c2w w2c"}
    for name, names in before.items():
        graph = prepare(ROOT / "scenarios" / name, fmu_dir=fmu_dir)
        assert [i.name for i in graph.instances] == names.split(), name
    track = [i.name for i in prepare(TRACK, fmu_dir=fmu_dir).instances]
    assert track[:5] == list(ENCODERS) + ["odom"]                 # the loop's state first
