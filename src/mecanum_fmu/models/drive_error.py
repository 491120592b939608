"""The drive train's error models for the fixed-step masters' embedded pair: a DCMotor's and a
MecanumDynamics' equations linearised about the run's own values, per row. A client the pair
is handed (Graph.error_models), so that master/ knows nothing of motors or floors: with them
it carries the coupling error through the motors, the floor and back (master/pair_network.py)
instead of handing the estimate over to Richardson.

The linear interface: `inputs` (the linked Real inputs, in the pair's order), `outputs` (the
Real outputs covered), `reads` (the outputs whose values it linearises about), `states` (the
size of its state), `integrals` (an output -> its place in the state, for the states that are
integrals no rate depends on: the energies), linearised(ins, outs) -> (A, B, C, D) per row:
the error x of its state and the error u of its inputs give x' = A x + B u and the outputs'
error C x + D u, arrays (rows, states, states), (rows, states, inputs), (rows, outputs,
states), (rows, outputs, inputs), from the inputs' and the read outputs' values in those rows.
Each is the derivative of the block's own rates (blocks/motor.Motor.rates, blocks/traction.
Chassis.rates), which tests/test_drive_error.py checks against their central differences.
"""
from __future__ import annotations

import numpy as np

from .blocks.kinematics import DEFAULT_GEOMETRY
from .blocks.motor import DEFAULT_MOTOR, Motor
from .blocks.traction import BODY, Chassis
from .responses import all_inputs

_MOTOR_IN = ("w_ref", "tau_load")
_MOTOR_OUT = ("w", "i", "V", "tau", "E_electrical", "E_copper", "E_viscous", "E_gear",
              "E_load", "V_clamp", "i_clamp")
_WHEELS = ("w1", "w2", "w3", "w4")
_BODY_OUT = ("vx", "vy", "w", "tau_load1", "tau_load2", "tau_load3", "tau_load4", "slip1",
             "slip2", "slip3", "slip4", "E_slip", "E_drive", "E_kinetic", "eps")
# the outputs each model linearises about (`reads`): the masters keep them where the scenario
# does not record them (Graph.watched)
MOTOR_READS = ("w", "V")
BODY_READS = ("vx", "vy", "w")
# a clamp is in force where V is within this share of the clamp's value of it
_ON_CLAMP = 1e-12


class Linear:
    """The part every linearised model shares: the linked inputs' places among its own, the
    others at their start values (`fixed`)."""

    def __init__(self, names: list[str], own: tuple, fixed: list[float], outputs: tuple,
                 reads: tuple, states: int, integrals: dict):
        self.inputs, self.outputs, self.reads, self.states = tuple(names), outputs, reads, states
        self.integrals = integrals
        self.order, self.fixed = [own.index(n) for n in names], np.array(fixed)

    def linearised(self, ins: np.ndarray, outs: np.ndarray) -> tuple:
        a, b, c, d = self.full(all_inputs(ins, self.order, self.fixed), outs)
        return a, b[:, :, self.order], c, d[:, :, self.order]


def motor_linear(names: list[str], inst) -> "MotorLinear | None":
    """The linearised DCMotor whose linked Real inputs are `names` (among w_ref, tau_load),
    or None: an armature inductance (La > 0: the current is a state of its own)."""
    values = [float(inst.value(n)) for n in DEFAULT_MOTOR]
    if not set(names) <= set(_MOTOR_IN) or dict(zip(DEFAULT_MOTOR, values))["La"] > 0.0:
        return None
    return MotorLinear(names, Motor(*values), float(inst.value("w_ref")),
                       float(inst.value("tau_load")))


class MotorLinear(Linear):
    """A DCMotor with La = 0, state (w, z, the five energies), inputs (w_ref, tau_load). Its
    voltage is the PI's V* = kp (w_ref - w) + z, or the current limit k_e w +- R_a i_max, or
    the supply +-V_supply, whichever is in force on the row (from its V and w): dV is kp
    (dw_ref - dw) + dz, k_e dw or 0; i = (V - k_e w) / R_a."""

    def __init__(self, names, motor: Motor, w_ref: float, tau_load: float):
        super().__init__(names, _MOTOR_IN, [w_ref, tau_load], _MOTOR_OUT, MOTOR_READS, 7,
                         {n: 2 + k for k, n in enumerate(_MOTOR_OUT[4:9])})
        self.m = motor

    def full(self, values: np.ndarray, outs: np.ndarray) -> tuple:
        m, rows = self.m, len(values)
        tau = values[:, 1]
        w, V = outs[:, 0], outs[:, 1]
        i = (V - m.k_e * w) / m.R_a
        # dV, d wanted in (w, z, w_ref): the clamp in force decides dV
        wanted = np.array([-m.kp, 1.0, m.kp])
        span = m.R_a * m.i_max
        supply = np.abs(np.abs(V) - m.V_supply) <= _ON_CLAMP * m.V_supply
        limit = ~supply & (np.abs(np.abs(V - m.k_e * w) - span) <= _ON_CLAMP * max(span, 1.0))
        dv = np.where(supply[:, None], 0.0, np.where(limit[:, None], [m.k_e, 0.0, 0.0],
                                                     wanted))
        di = (dv - [m.k_e, 0.0, 0.0]) / m.R_a                       # (rows, 3)
        # the rates' derivatives in (w, z, w_ref, tau_load): w', z', then the energies'
        g = np.zeros((rows, 7, 4))
        g[:, 0, :3] = (m.k_t * di - [m.b, 0.0, 0.0]) / m.J
        g[:, 0, 3] = -1.0 / m.J
        g[:, 1, :3] = m.ki * np.array([-1.0, 0.0, 1.0]) + m.k_b * (dv - wanted)
        g[:, 2, :3] = i[:, None] * dv + V[:, None] * di               # V i
        g[:, 3, :3] = 2.0 * m.R_a * i[:, None] * di                   # R_a i^2
        g[:, 4, 0] = 2.0 * m.b * w                                    # b w^2
        gear = m.k_e - m.k_t                                          # (k_e - k_t) i w
        g[:, 5, :3] = gear * (w[:, None] * di + i[:, None] * np.array([1.0, 0.0, 0.0]))
        g[:, 6, 0], g[:, 6, 3] = tau, w                               # tau_load w
        a = np.zeros((rows, 7, 7))
        a[:, :, :2] = g[:, :, :2]
        b = g[:, :, 2:]
        # the outputs in (w, z, w_ref, tau_load): w, i, V, tau, the energies, the clamps
        h = np.zeros((rows, 11, 4))
        h[:, 0, 0] = 1.0
        h[:, 1, :3], h[:, 2, :3], h[:, 3, :3] = di, dv, m.k_t * di
        c = np.zeros((rows, 11, 7))
        c[:, :, :2] = h[:, :, :2]
        c[:, 4:9, 2:] = np.eye(5)
        return a, b, c, h[:, :, 2:]


def body_linear(names: list[str], inst) -> "BodyLinear | None":
    """The linearised MecanumDynamics whose linked Real inputs are `names` (among w1..w4)."""
    if not set(names) <= set(_WHEELS):
        return None
    chassis = Chassis(*(float(inst.value(n)) for n in DEFAULT_GEOMETRY),
                      *(float(inst.value(n)) for n in BODY))
    return BodyLinear(names, chassis, [float(inst.value(n)) for n in _WHEELS])


class BodyLinear(Linear):
    """A MecanumDynamics, state (vx, vy, w, E_slip, E_drive), inputs the wheel speeds. Contact
    i slips at s_i = u_i . (v + w x r_i) - rim w_i and is pushed by F_i = -mu N tanh(s_i /
    eps): dF_i = -(mu N / eps) sech^2(s_i / eps) ds_i."""

    def __init__(self, names, chassis: Chassis, wheels: list[float]):
        super().__init__(names, _WHEELS, wheels, _BODY_OUT, BODY_READS, 5,
                         {"E_slip": 3, "E_drive": 4})
        self.c = chassis
        self.axes, self.levers = np.array(chassis.axes), np.array(chassis.levers)
        self.arms = np.array(chassis.arms)

    def full(self, values: np.ndarray, outs: np.ndarray) -> tuple:
        c, rows = self.c, len(values)
        vx, vy, w = outs[:, 0], outs[:, 1], outs[:, 2]
        ux, uy = self.axes[:, 0], self.axes[:, 1]
        x, y = self.arms[:, 0], self.arms[:, 1]
        s = ((vx[:, None] - w[:, None] * y) * ux + (vy[:, None] + w[:, None] * x) * uy
             - c.rim * values)                                        # (rows, 4)
        t = np.tanh(s / c.eps)
        force, gain = -c.push * t, c.push / c.eps * (1.0 - t * t)
        # ds_i and dF_i in (vx, vy, w, w1..w4)
        ds = np.zeros((rows, 4, 7))
        ds[:, :, 0], ds[:, :, 1], ds[:, :, 2] = ux, uy, self.levers
        ds[:, :, 3:] = -c.rim * np.eye(4)
        df = -gain[:, :, None] * ds
        g = np.zeros((rows, 5, 7))
        g[:, 0] = np.einsum("rik,i->rk", df, ux) / c.m
        g[:, 0, 1] += w
        g[:, 0, 2] += vy
        g[:, 1] = np.einsum("rik,i->rk", df, uy) / c.m
        g[:, 1, 0] -= w
        g[:, 1, 2] -= vx
        g[:, 2] = np.einsum("rik,i->rk", df, self.levers) / c.Iz
        g[:, 3] = -(np.einsum("rik,ri->rk", df, s) + np.einsum("rik,ri->rk", ds, force))
        g[:, 4] = c.rim * np.einsum("rik,ri->rk", df, values)
        g[:, 4, 3:] += c.rim * force
        a = np.zeros((rows, 5, 5))
        a[:, :, :3] = g[:, :, :3]
        h = np.zeros((rows, 15, 7))
        h[:, 0, 0] = h[:, 1, 1] = h[:, 2, 2] = 1.0
        h[:, 3:7], h[:, 7:11] = c.rim * df, ds
        h[:, 13, 0], h[:, 13, 1], h[:, 13, 2] = c.m * vx, c.m * vy, c.Iz * w
        cc = np.zeros((rows, 15, 5))
        cc[:, :, :3] = h[:, :, :3]
        cc[:, 11, 3] = cc[:, 12, 4] = 1.0
        return a, g[:, :, 3:], cc, h[:, :, 3:]
