"""The drive train's linearised error models (models/drive_error.py): each of A, B, C, D
against central differences of the blocks' own functions (blocks/motor.Motor, blocks/traction.
Chassis), in each of the motor's voltage regimes, with an input not linked, and the cases
where there is no model."""
from types import SimpleNamespace

import numpy as np
import pytest

from mecanum_fmu.models.blocks.kinematics import DEFAULT_GEOMETRY
from mecanum_fmu.models.blocks.motor import DEFAULT_MOTOR, Motor
from mecanum_fmu.models.blocks.traction import DEFAULT_BODY, Chassis
from mecanum_fmu.models.drive_error import body_linear, motor_linear

MOTOR = Motor(*DEFAULT_MOTOR.values())
CHASSIS = Chassis(*DEFAULT_GEOMETRY.values(), *DEFAULT_BODY.values())


def _instance(values: dict):
    return SimpleNamespace(value=lambda name: values.get(name, 0.0))


def _motor(x, u):
    """The motor's rates of (w, z, the energies) and its outputs (w, i, V, tau, energies)
    at state (w, z, energies) and inputs (w_ref, tau_load), from Motor's own methods."""
    w, z = x[0], x[1]
    rates = MOTOR.rates(w, z, 0.0, u[0], u[1])
    V = MOTOR.voltage(w, z, u[0])[0]
    i = MOTOR.current(w, 0.0, V)
    return (np.array([rates[0], rates[1], *rates[3:]]),
            np.array([w, i, V, MOTOR.k_t * i, *x[2:], 0.0, 0.0]))


def _differences(f, x, u, step):
    """Central differences of f's two parts in x and in u."""
    def column(dx, du):
        hi, lo = f(x + dx, u + du), f(x - dx, u - du)
        return [(a - b) / (2 * step) for a, b in zip(hi, lo)]
    by_x = [column(step * e, 0 * u) for e in np.eye(len(x))]
    by_u = [column(0 * x, step * e) for e in np.eye(len(u))]
    return (np.array([c[0] for c in by_x]).T, np.array([c[0] for c in by_u]).T,
            np.array([c[1] for c in by_x]).T, np.array([c[1] for c in by_u]).T)


def _motor_point(regime: str):
    """(w, z, w_ref, tau_load) where the PI's voltage is in force, or the current limit,
    or the supply clamp."""
    w = 10.0
    z = {"pi": MOTOR.k_e * w + 0.5, "current": MOTOR.k_e * w + 0.5, "supply": 11.0}[regime]
    w_ref = {"pi": w + 0.3, "current": w - 9.0, "supply": w + 40.0}[regime]
    return w, z, w_ref, 0.2


@pytest.mark.parametrize("regime", ["pi", "current", "supply"])
def test_the_motors_linearisation_is_the_derivative_of_its_rates(regime):
    w, z, w_ref, tau = _motor_point(regime)
    V, wanted = MOTOR.voltage(w, z, w_ref)
    span = MOTOR.R_a * MOTOR.i_max
    in_force = {"pi": V == wanted, "current": abs(V - MOTOR.k_e * w) == pytest.approx(span),
                "supply": abs(V) == MOTOR.V_supply}
    assert in_force[regime] and sum(in_force.values()) == 1    # the point is in that regime
    model = motor_linear(["w_ref", "tau_load"], _instance(DEFAULT_MOTOR))
    a, b, c, d = (m[0] for m in model.linearised(np.array([[w_ref, tau]]), np.array([[w, V]])))
    x = np.array([w, z, 0.0, 0.0, 0.0, 0.0, 0.0])
    A, B, C, D = _differences(_motor, x, np.array([w_ref, tau]), 1e-6)
    assert np.allclose(a, A, atol=1e-5) and np.allclose(b, B, atol=1e-5)
    assert np.allclose(c, C, atol=1e-6) and np.allclose(d, D, atol=1e-6)
    assert a.shape == (7, 7) and not a[:, 2:].any()       # no rate depends on an energy
    assert model.integrals == {n: 2 + k for k, n in enumerate(
        ("E_electrical", "E_copper", "E_viscous", "E_gear", "E_load"))}


def test_a_motor_input_not_linked_sits_at_its_start_value():
    w, z, w_ref, tau = _motor_point("pi")
    V = MOTOR.voltage(w, z, w_ref)[0]
    both = motor_linear(["w_ref", "tau_load"], _instance({**DEFAULT_MOTOR, "tau_load": tau}))
    alone = motor_linear(["w_ref"], _instance({**DEFAULT_MOTOR, "tau_load": tau}))
    full = both.linearised(np.array([[w_ref, tau]]), np.array([[w, V]]))
    one = alone.linearised(np.array([[w_ref]]), np.array([[w, V]]))
    assert np.allclose(one[0], full[0]) and np.allclose(one[2], full[2])
    assert np.allclose(one[1], full[1][:, :, :1]) and np.allclose(one[3], full[3][:, :, :1])


def test_a_motor_with_an_inductance_has_no_linear_model():
    assert motor_linear(["w_ref"], _instance({**DEFAULT_MOTOR, "La": 1e-3})) is None
    assert motor_linear(["w_ref", "V"], _instance(DEFAULT_MOTOR)) is None


def _body(x, u):
    """The body's rates of (vx, vy, w, E_slip, E_drive) and its outputs, from Chassis."""
    rates = CHASSIS.rates(*x[:3], *u, CHASSIS.eps)
    slips = CHASSIS.slips(*x[:3], u)
    loads = [CHASSIS.rim * f for f in CHASSIS.forces(slips, CHASSIS.eps)]
    return (np.array(rates), np.array([*x[:3], *loads, *slips, *x[3:],
                                       CHASSIS.kinetic(*x[:3]), 0.0]))


@pytest.mark.parametrize("twist", [(0.3, 1.0, 0.2), (0.0, 0.0, 0.0), (-0.5, 0.2, -1.5)])
def test_the_bodys_linearisation_is_the_derivative_of_its_rates(twist):
    wheels = np.array([16.0, 17.0, 15.5, 16.9])
    model = body_linear(["w1", "w2", "w3", "w4"], _instance({**DEFAULT_GEOMETRY,
                                                               **DEFAULT_BODY}))
    a, b, c, d = (m[0] for m in model.linearised(wheels[None], np.array([twist])))
    A, B, C, D = _differences(_body, np.array([*twist, 0.0, 0.0]), wheels, 1e-7)
    scale = np.abs(A).max()
    assert np.allclose(a, A, atol=1e-6 * scale) and np.allclose(b, B, atol=1e-6 * scale)
    assert np.allclose(c, C, atol=1e-5) and np.allclose(d, D, atol=1e-5)
    assert not a[:, 3:].any() and model.integrals == {"E_slip": 3, "E_drive": 4}


def test_the_bodys_wheels_in_another_order_are_its_columns_in_that_order():
    model = body_linear(["w3", "w1"], _instance({**DEFAULT_GEOMETRY, **DEFAULT_BODY,
                                                 "w2": 16.0, "w4": 16.9}))
    full = body_linear(["w1", "w2", "w3", "w4"], _instance({**DEFAULT_GEOMETRY,
                                                            **DEFAULT_BODY}))
    twist = np.array([[0.3, 1.0, 0.2]])
    part = model.linearised(np.array([[15.5, 17.0]]), twist)
    whole = full.linearised(np.array([[17.0, 16.0, 15.5, 16.9]]), twist)
    assert np.allclose(part[0], whole[0])
    assert np.allclose(part[1], whole[1][:, :, [2, 0]])
    assert np.allclose(part[3], whole[3][:, :, [2, 0]])
