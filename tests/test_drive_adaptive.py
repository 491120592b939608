"""The drive train under the adaptive master (issue 30, item 4; docs/robot.md, Stability).

Reference values: the back-calculation anti-windup's rates as docs/robot.md writes them
(z' = ki e + k_b (V - V*), k_b = ki / kp), from the datasheet constants computed here, and the
run's own facts (it finishes, the clamp holds and releases), never values of the code under
test.
"""
import dataclasses
import math

import numpy as np
import pytest

from helpers import ROOT
from mecanum_fmu import master
from mecanum_fmu.models.blocks.motor import DEFAULT_MOTOR, Motor
from mecanum_fmu.runner import prepare

ROBOT = ROOT / "scenarios" / "robot"
V_S, KP, KI = 12.0, 2.0, 150.0          # the DCMotor's defaults (docs/robot.md)
R_A, K_T = V_S / 5.5, 140.0e-3 * 9.80665 / 5.5
K_E = (V_S - R_A * 0.2) / (330.0 * math.pi / 30.0)


def test_the_integrator_rate_is_continuous_across_the_clamp_release():
    """z' follows ki e unclamped and (ki / kp)(V_supply - z) on the clamp: no switch where
    the clamp releases (the old anti-windup stopped z there: z' jumped from 0 to ki e)."""
    motor = Motor(**DEFAULT_MOTOR)
    w, z = 10.0, 8.0             # V* = kp e + z crosses V_supply at e = (12 - 8) / 2 = 2
    errors = np.linspace(1.0, 3.0, 2001)
    rates = np.array([motor.rates(w, z, 0.0, w + e, 0.0)[1] for e in errors])
    expected = np.where(KP * errors + z > V_S, KI / KP * (V_S - z), KI * errors)
    assert np.max(np.abs(rates - expected)) < 1e-9
    assert np.max(np.abs(np.diff(rates))) < 2 * KI * (errors[1] - errors[0])
    assert rates[-1] == pytest.approx(KI / KP * (V_S - z))   # on the clamp, z is still driven


def test_the_adaptive_hard_start_passes_the_clamp_release(fmu_dir):
    """Before: `--tolerance 1e-3` stopped at t = 0.1975 s, where the clamp releases, wanting
    a step of 5e-13 s; now the run through the release finishes in a few hundred steps."""
    graph = prepare(ROBOT / "hard_start.yaml", fmu_dir=fmu_dir, tolerance=1e-3, stop_time=0.3,
                    estimate="none")
    results = master.simulate(graph, graph.scenario.experiment)
    assert results.complete and results.steps_taken < 1000
    V = np.asarray(results["motor1.V"])
    t = np.asarray(results.time)
    assert np.all(V[t < 0.15] == pytest.approx(V_S))     # clamped at the start ...
    assert V[-1] < V_S - 0.5                             # ... released before 0.3 s


def _quadratic(graph, step: float):
    """The same graph (h_ref kept: the same friction) under the quadratic master at `step`."""
    exp = dataclasses.replace(graph.scenario.experiment, master="quadratic", step_size=step,
                              tolerance=None, relative_tolerance=None)
    fine = dataclasses.replace(graph, scenario=dataclasses.replace(graph.scenario,
                                                                   experiment=exp))
    return master.simulate(fine, exp, keep_rows=2)


def test_the_adaptive_estimate_on_the_circle_is_within_3x_of_a_fine_reference(fmu_dir):
    """The circle's first 0.02 s at --tolerance 1e-3 against the quadratic master at 2e-5 and
    1e-5 s, extrapolated at its first order (2 y(1e-5) - y(2e-5)); the pose's estimate
    includes the twist error it integrates (before: 1e-9 of a 1e-7 error)."""
    graph = prepare(ROBOT / "circle.yaml", fmu_dir=fmu_dir, tolerance=1e-3, stop_time=0.02)
    results = master.simulate(graph, graph.scenario.experiment, keep_rows=2)
    estimate = master.estimate_error(graph, results)["error_estimate"]
    coarse, fine = _quadratic(graph, 2e-5), _quadratic(graph, 1e-5)
    for name in ("pose.x", "body.vx"):
        reference = 2 * fine.final(name) - coarse.final(name)
        error = abs(results.final(name) - reference)
        assert abs(fine.final(name) - coarse.final(name)) < error   # the reference can judge
        assert error / 3 <= estimate[name]["end"] <= 3 * error, name
