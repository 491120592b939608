"""The responses of the bundled FMUs without a state: the Jacobian of their outputs in their
inputs, per row of a run, for the fixed-step masters' embedded pair (master/pair.py). A
client the pair is handed (Graph.responses), so that master/ knows nothing of kinematics:
with them it carries a PoseIntegrator's error around a closed loop (pose -> PathFollower ->
Center2Wheel -> Wheel2Center -> pose) instead of handing the estimate over to Richardson.

The response interface: `inputs` (the linked Real inputs it covers, in the pair's order),
`outputs` (the Real outputs it covers), `divides` (an output -> the output it is divided by
and the floor below which it is not: that one's error must stay small against its value),
jacobian(ins, outs) -> d outputs / d inputs per row,
shape (rows, outputs, inputs), from the inputs' and outputs' values in those rows (arrays
(rows, inputs) and (rows, outputs)). The kinematics' linear maps are read off their own
functions (blocks/kinematics.py) at unit inputs: the equations keep one home.
"""
from __future__ import annotations

import inspect

import numpy as np

from .blocks.kinematics import center_to_wheel, instantaneous_center, wheel_to_center

_POSE = ("x", "y", "theta")
_TWIST = ("vx", "vy", "w")
_WHEELS = ("w1", "w2", "w3", "w4")
_GEOMETRY = ("alpha", "L", "W", "R")
_FLIP = np.array([1.0, -1.0])     # (a, b) -> (a, -b)
# the |w| below which Wheel2Center reports no ICR (and 0 for its place)
ICR_TOLERANCE = inspect.signature(instantaneous_center).parameters["tol"].default


class Response:
    """One FMU's Jacobian in its linked inputs (`names`, in the pair's order): the model's
    full Jacobian (`full`, in the model's order of `inputs`) at the linked values, the others
    at their start values."""

    def __init__(self, names: list[str], inputs: tuple, outputs: tuple, full, inst,
                 divides: dict):
        self.inputs, self.outputs, self.full = tuple(names), outputs, full
        # output -> (the output it divides by where that one is at least a floor): its
        # Jacobian holds only where that one's error is small against its value (the ICR,
        # -vy/w for |w| >= its tolerance, where w nears 0)
        self.divides = divides
        self.order = [inputs.index(n) for n in names]
        self.fixed = np.array([_number(inst, n) for n in inputs])
        self.whole = self.order == list(range(len(inputs)))  # every input linked, in order

    def jacobian(self, ins: np.ndarray, outs: np.ndarray) -> np.ndarray:
        if self.whole:
            return self.full(ins, outs)
        return self.full(all_inputs(ins, self.order, self.fixed), outs)[:, :, self.order]


def all_inputs(ins: np.ndarray, order: list[int], fixed: np.ndarray) -> np.ndarray:
    """A model's every input per row: the linked ones `ins` at their places `order` among its
    own, the others at their start values `fixed`."""
    values = np.broadcast_to(fixed, (len(ins), len(fixed))).copy()
    values[:, order] = ins
    return values


def response(names: list[str], inst) -> Response | None:
    """The response of a bundled FMU without a state whose linked Real inputs are `names`
    (in the pair's order), or None: not one of these models, or an input it does not cover."""
    known = _RESPONSES.get(inst.model_name)
    if known is None or not set(names) <= set(known[0]):
        return None
    inputs, outputs, make = known
    return Response(names, inputs, outputs, make(inst), inst, _DIVIDES.get(inst.model_name, {}))


def has_response(model_name: str) -> bool:
    """Whether the bundled model of that name has a response here."""
    return model_name in _RESPONSES


def _number(inst, name: str) -> float:
    return float(inst.value(name))


def _follower(inst):
    """PathFollower (blocks/follower.follow): body = R(theta)^T (r' + k_pos (r - p)), w =
    theta_r' + k_theta wrap(theta_r - theta); d body / d theta = (vy, -vx) of the output."""
    kp, kt = _number(inst, "k_pos"), _number(inst, "k_theta")
    still = np.zeros((1, 3, 3))     # the entries that do not move: 0, and d w / d theta
    still[0, 2, 2] = -kt

    def full(ins, outs):
        j = still.repeat(len(ins), axis=0)
        j[:, 0, 0] = j[:, 1, 1] = -kp * np.cos(ins[:, 2])
        j[:, 1, 0] = kp * np.sin(ins[:, 2])
        j[:, 0, 1] = -j[:, 1, 0]
        j[:, :2, 2] = outs[:, 1::-1] * _FLIP       # (vy, -vx)
        return j
    return full


def _matrix(function, n: int, *args) -> np.ndarray:
    """The matrix of a linear map of n inputs (its columns: the map of each unit input)."""
    return np.array([function(*np.eye(n)[i], *args) for i in range(n)]).T


def _center2wheel(inst):
    """Center2Wheel: w = M twist, scaled down by w_max / peak where the peak |w_i| passes
    w_max (kinematics.limit_wheel_speeds): d (w_max s / |s_i|) = (w_max / peak) (I - s
    sign(s_i) e_i^T / peak) ds."""
    geometry = [_number(inst, n) for n in _GEOMETRY]
    m = _matrix(center_to_wheel, 3, *geometry)
    w_max = _number(inst, "w_max")

    def full(ins, outs):
        if not w_max > 0.0:
            return np.broadcast_to(m, (len(ins), 4, 3))
        j = m[None].repeat(len(ins), axis=0)
        speeds = ins @ m.T
        size = np.abs(speeds)
        over = size.max(axis=1) > w_max       # the peak |w_i| past w_max
        if over.any():
            s = speeds[over]
            i = np.argmax(size[over], axis=1)
            p, sign = size[over, i], np.sign(s[np.arange(len(s)), i])
            scale = np.eye(4) - np.einsum("ra,rb->rab", s * (sign / p)[:, None], np.eye(4)[i])
            j[over] = (w_max / p)[:, None, None] * scale @ m
        return j
    return full


def _wheel2center(inst):
    """Wheel2Center: twist = N w (with the radius deviations), and the ICR (-vy/w, vx/w)
    where |w| >= the ICR's tolerance (kinematics.instantaneous_center; else 0)."""
    geometry = [_number(inst, n) for n in _GEOMETRY]
    deviations = tuple(_number(inst, f"dR{i}") for i in range(1, 5))
    n = _matrix(lambda *a: wheel_to_center(*a[:4], *a[4:8], a[8]), 4, *geometry, deviations)

    icr = np.array([-n[1], n[0]])     # d (icr_x, icr_y) / dw_i w, but for w's change
    turn = np.array([n[2], -n[2]])    # w's change's: times (vy, vx) / w

    def full(ins, outs):
        j = np.empty((len(ins), 5, 4))
        j[:, :3] = n
        w = outs[:, 2]
        # d (icr_x, icr_y) = (-dvy / w + vy dw / w^2, dvx / w - vx dw / w^2), 0 where no ICR
        inverse = np.divide(1.0, w, out=np.zeros_like(w), where=np.abs(w) >= ICR_TOLERANCE)
        lever = outs[:, 1::-1] * inverse[:, None]       # (vy / w, vx / w)
        np.multiply(inverse[:, None, None], icr + lever[:, :, None] * turn, out=j[:, 3:])
        return j
    return full


# per model name: its inputs, its outputs (the Jacobian's rows and columns), its Jacobian
_RESPONSES = {
    "PathFollower": (_POSE, _TWIST, _follower),
    "Center2Wheel": (_TWIST, _WHEELS, _center2wheel),
    "Wheel2Center": (_WHEELS, _TWIST + ("icr_x", "icr_y"), _wheel2center),
}
_DIVIDES = {"Wheel2Center": {"icr_x": ("w", ICR_TOLERANCE), "icr_y": ("w", ICR_TOLERANCE)}}
