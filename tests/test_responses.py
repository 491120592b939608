"""The Jacobians the embedded pair carries a loop's error through (models/responses.py),
against central differences of the blocks' own functions."""
import math

import numpy as np
import pytest

from mecanum_fmu.models.blocks.follower import expression_reference, follow
from mecanum_fmu.models.blocks.kinematics import (center_to_wheel, instantaneous_center,
                                                  limit_wheel_speeds, wheel_to_center)
from mecanum_fmu.models.responses import response

GEOMETRY = {"alpha": math.pi / 4, "L": 0.16, "W": 0.12, "R": 0.06}


class _Inst:
    def __init__(self, model_name, **values):
        self.model_name, self.values = model_name, values

    def value(self, name):
        return self.values[name]


def _differences(function, x: np.ndarray, d: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(len(x)):
        up, down = x.copy(), x.copy()
        up[i] += d
        down[i] -= d
        cols.append((np.array(function(up)) - np.array(function(down))) / (2 * d))
    return np.array(cols).T


def _check(model, names, values, function, inputs):
    r = response(names, _Inst(model, **values))
    ins = np.array([inputs])
    outs = np.array([function(np.array(inputs))])
    found = r.jacobian(ins, outs)[0]
    assert np.allclose(found, _differences(function, np.array(inputs)), rtol=1e-5,
                       atol=1e-6), found


def test_the_follower_s_jacobian_in_the_pose():
    ref = expression_reference((lambda t: 1 - math.cos(t), math.sin, lambda t: 0.3 * t))

    def f(p):
        return follow(1.3, p[0], p[1], p[2], ref, 2.0, 3.0)
    _check("PathFollower", ["x", "y", "theta"], {"k_pos": 2.0, "k_theta": 3.0,
                                                  "x": 0.0, "y": 0.0, "theta": 0.0},
           f, [0.4, -0.2, 0.7])


def test_an_input_order_other_than_the_model_s():
    ref = expression_reference((math.sin, math.cos, lambda t: 0.0))
    r = response(["theta", "x", "y"], _Inst("PathFollower", k_pos=1.5, k_theta=2.0, x=0.0,
                                            y=0.0, theta=0.0))
    pose = np.array([0.3, 0.1, -0.4])           # (x, y, theta)
    out = np.array([follow(0.5, *pose, ref, 1.5, 2.0)])
    j = r.jacobian(pose[[2, 0, 1]][None], out)[0]
    full = _differences(lambda p: follow(0.5, *p, ref, 1.5, 2.0), pose)
    assert np.allclose(j, full[:, [2, 0, 1]], atol=1e-6)


@pytest.mark.parametrize("w_max", [0.0, 20.0])
def test_center2wheel_with_and_without_its_wheel_limit(w_max):
    """At w_max = 20 rad/s the twist asks for more (the peak wheel): all four scale down."""
    def f(v):
        return limit_wheel_speeds(center_to_wheel(*v, *GEOMETRY.values()), w_max)
    twist = [0.9, 1.2, 0.8]
    assert max(map(abs, center_to_wheel(*twist, *GEOMETRY.values()))) > 20.0
    _check("Center2Wheel", ["vx", "vy", "w"], {**GEOMETRY, "w_max": w_max, "vx": 0.0,
                                                "vy": 0.0, "w": 0.0}, f, twist)


def test_wheel2center_with_radius_deviations_and_its_icr():
    dev = {"dR1": 0.002, "dR2": -0.001, "dR3": 0.0, "dR4": 0.003}

    def f(w):
        twist = wheel_to_center(*w, *GEOMETRY.values(), tuple(dev.values()))
        return (*twist, *instantaneous_center(*twist)[:2])
    _check("Wheel2Center", ["w1", "w2", "w3", "w4"], {**GEOMETRY, **dev, "w1": 0.0,
                                                      "w2": 0.0, "w3": 0.0, "w4": 0.0},
           f, [3.0, -1.0, 2.5, 4.0])


def test_no_response_for_an_input_it_does_not_cover_or_another_model():
    inst = _Inst("Center2Wheel", **GEOMETRY, w_max=0.0, vx=0.0, vy=0.0, w=0.0)
    assert response(["vx", "speed"], inst) is None
    assert response(["x"], _Inst("Feedthrough")) is None
