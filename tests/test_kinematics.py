"""Mecanum kinematics against docs/spec.md (Wheel numbering, Kinematics, Expected results).

Every reference value is computed here from the formulas of docs/spec.md, never taken from the code.
"""
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mecanum_fmu.models.blocks.kinematics import check_geometry, center_to_wheel, wheel_to_center

# The seed's geometry (docs/spec.md, Parameters).
ALPHA, L0, W0, R0 = math.radians(45.0), 0.16, 0.12, 0.06


# ------------------------------------------------------------------ references from docs/spec.md

def spec_matrix(alpha, L, W):
    """The wheel matrix A of docs/spec.md, Inverse kinematics, written out row by row."""
    c = math.cos(alpha) / math.sin(alpha)
    k = L + W * c
    return np.array([[-c, 1.0, k],
                     [c, 1.0, -k],
                     [-c, 1.0, -k],
                     [c, 1.0, k]])


# docs/spec.md, Wheel numbering: wheel positions and roller directions u.
def wheel_positions(L, W):
    return [(L, W), (-L, W), (-L, -W), (L, -W)]   # 1 FR, 2 FL, 3 RL, 4 RR


def roller_directions(alpha):
    a, b = math.cos(alpha), math.sin(alpha)
    return [(-a, b), (a, b), (-a, b), (a, b)]     # wheels 1, 3: (-cos, sin); 2, 4: (cos, sin)


# ------------------------------------------------------------------ strategies

angles = st.floats(min_value=0.05, max_value=math.pi / 2 - 0.05)
lengths = st.floats(min_value=0.01, max_value=2.0)
speeds = st.floats(min_value=-10.0, max_value=10.0)
wheel_speeds = st.floats(min_value=-200.0, max_value=200.0)
geometries = st.tuples(angles, lengths, lengths, lengths)
twists = st.tuples(speeds, speeds, speeds)


def ck(alpha, L, W):
    c = math.cos(alpha) / math.sin(alpha)
    return c, L + W * c


def forward_tolerance(alpha, L, W, R, wheels):
    """Rounding bound (~500 ulps) for forward kinematics of these wheel speeds: the sums
    of |wi|*R, scaled by tan(alpha) (vx), 1 (vy) or 1/k (w)."""
    c, k = ck(alpha, L, W)
    return 1e-13 * (1e-300 + sum(abs(v) for v in wheels) * R) * max(1.0, 1.0 / c, 1.0 / k)


# ------------------------------------------ the seed scenario (docs/spec.md, Expected results)

@pytest.mark.parametrize("t", [0.0, 0.3, math.pi / 4, 1.0, 2.5, math.pi, 4.2, 7.0, 10.0])
def test_seed_wheel_speeds(t):
    w1, w2, w3, w4 = center_to_wheel(math.sin(t), math.cos(t), 0.0, ALPHA, L0, W0, R0)
    odd = (math.cos(t) - math.sin(t)) / 0.06
    even = (math.cos(t) + math.sin(t)) / 0.06
    assert w1 == pytest.approx(odd, rel=1e-12, abs=1e-12)
    assert w3 == pytest.approx(odd, rel=1e-12, abs=1e-12)
    assert w2 == pytest.approx(even, rel=1e-12, abs=1e-12)
    assert w4 == pytest.approx(even, rel=1e-12, abs=1e-12)


def test_seed_peak_wheel_speed():
    ts = np.linspace(0.0, 10.0, 100001)
    peak = max(max(abs(v) for v in center_to_wheel(math.sin(t), math.cos(t), 0.0, ALPHA, L0, W0, R0))
               for t in ts)
    assert peak == pytest.approx(math.sqrt(2) / 0.06, rel=1e-8)
    assert round(peak, 2) == 23.57
    # The peak of w2 = w4 is at t = pi/4 (cos + sin = sqrt 2), of |w1| = |w3| at 3pi/4.
    at = center_to_wheel(math.sin(math.pi / 4), math.cos(math.pi / 4), 0.0, ALPHA, L0, W0, R0)
    assert at[1] == pytest.approx(math.sqrt(2) / 0.06, rel=1e-12)
    assert at[0] == pytest.approx(0.0, abs=1e-12)


# ------------------------------------------------------------------ inverse kinematics

@settings(max_examples=300, deadline=None)
@given(twists, geometries)
def test_inverse_is_spec_matrix(twist, geometry):
    alpha, L, W, R = geometry
    expected = spec_matrix(alpha, L, W) @ np.array(twist) / R
    got = np.array(center_to_wheel(*twist, alpha, L, W, R))
    c, k = ck(alpha, L, W)
    vx, vy, w = twist
    tol = 1e-13 * (1e-300 + abs(c * vx) + abs(vy) + abs(k * w)) / R
    np.testing.assert_allclose(got, expected, rtol=0, atol=tol)


def test_inverse_written_out_for_one_case():
    # docs/spec.md, Inverse kinematics, by hand: alpha = 30 deg, c = sqrt(3), k = L + W*sqrt(3).
    alpha, L, W, R = math.radians(30.0), 0.2, 0.1, 0.05
    vx, vy, w = 0.4, -0.3, 1.5
    c = math.sqrt(3.0)
    k = L + W * c
    expected = ((-c * vx + vy + k * w) / R, (c * vx + vy - k * w) / R,
                (-c * vx + vy - k * w) / R, (c * vx + vy + k * w) / R)
    assert center_to_wheel(vx, vy, w, alpha, L, W, R) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("twist, signs", [
    ((0.0, 1.0, 0.0), (1, 1, 1, 1)),        # forward: every wheel rolls forward
    ((0.0, -1.0, 0.0), (-1, -1, -1, -1)),   # backward
    ((1.0, 0.0, 0.0), (-1, 1, -1, 1)),      # sideways to the right (+X)
    ((0.0, 0.0, 1.0), (1, -1, -1, 1)),      # spin counter-clockwise: right wheels forward
    ((0.0, 0.0, -1.0), (-1, 1, 1, -1)),     # spin clockwise
    ((1.0, 1.0, 0.0), (0, 1, 0, 1)),        # diagonal forward-right at 45 deg: 1 and 3 idle
])
def test_basic_motion_sign_patterns(twist, signs):
    wheels = center_to_wheel(*twist, ALPHA, L0, W0, R0)
    for value, sign in zip(wheels, signs):
        if sign == 0:
            assert value == pytest.approx(0.0, abs=1e-12)
        else:
            assert math.copysign(1.0, value) == sign and abs(value) > 1.0


# ------------------------------------------------------------------ forward kinematics

@settings(max_examples=300, deadline=None)
@given(twists, geometries)
def test_forward_inverts_inverse(twist, geometry):
    alpha, L, W, R = geometry
    wheels = center_to_wheel(*twist, alpha, L, W, R)
    back = wheel_to_center(*wheels, alpha, L, W, R)
    np.testing.assert_allclose(back, twist, rtol=0,
                               atol=forward_tolerance(alpha, L, W, R, wheels))


@settings(max_examples=300, deadline=None)
@given(st.tuples(wheel_speeds, wheel_speeds, wheel_speeds, wheel_speeds), geometries)
def test_forward_is_least_squares(wheels, geometry):
    alpha, L, W, R = geometry
    A = spec_matrix(alpha, L, W) / R
    expected, *_ = np.linalg.lstsq(A, np.array(wheels), rcond=None)
    got = wheel_to_center(*wheels, alpha, L, W, R)
    # lstsq (SVD) is accurate to ~eps * cond(A) relative to the size of the solution.
    c, k = ck(alpha, L, W)
    cond = max(c, 1.0, k) / min(c, 1.0, k)
    size = float(np.linalg.norm(wheels)) * R / min(c, 1.0, k)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-14 * cond * size)


@settings(max_examples=200, deadline=None)
@given(twists, geometries, st.floats(min_value=0.5, max_value=50.0))
def test_forward_ignores_slip_no_twist_can_make(twist, geometry, slip):
    """Wheel speeds = A v / R + s*n with n orthogonal to every column of A give back v."""
    alpha, L, W, R = geometry
    A = spec_matrix(alpha, L, W)
    n = np.array([1.0, 1.0, -1.0, -1.0])
    assert np.allclose(A.T @ n, 0.0)          # n is in the left null space of A
    wheels = A @ np.array(twist) / R + slip * n
    # Truly inconsistent: no twist reproduces these wheel speeds.
    fit, residual, *_ = np.linalg.lstsq(A / R, wheels, rcond=None)
    assert residual[0] > 0.0
    got = wheel_to_center(*wheels, alpha, L, W, R)
    np.testing.assert_allclose(got, twist, rtol=0,
                               atol=forward_tolerance(alpha, L, W, R, wheels))


def test_forward_written_out_for_one_case():
    alpha, L, W, R = math.radians(60.0), 0.15, 0.25, 0.04
    w1, w2, w3, w4 = 3.0, -1.0, 2.0, 5.0
    t = math.sqrt(3.0)
    k = L + W / t
    expected = (R * t / 4 * (-w1 + w2 - w3 + w4), R / 4 * (w1 + w2 + w3 + w4),
                R / (4 * k) * (w1 - w2 - w3 + w4))
    assert wheel_to_center(w1, w2, w3, w4, alpha, L, W, R) == pytest.approx(expected, rel=1e-12)


# ------------------------------------------------------------------ derivation check

@settings(max_examples=300, deadline=None)
@given(twists, geometries)
def test_roller_constraint_holds_at_every_wheel(twist, geometry):
    """docs/spec.md, Why the matrix is right: the wheel centre's speed along the roller axis u
    equals the rim's."""
    vx, vy, w = twist
    alpha, L, W, R = geometry
    wheels = center_to_wheel(vx, vy, w, alpha, L, W, R)
    for wi, (rx, ry), (ux, uy) in zip(wheels, wheel_positions(L, W), roller_directions(alpha)):
        centre_velocity = (vx - w * ry, vy + w * rx)
        along_u = centre_velocity[0] * ux + centre_velocity[1] * uy
        rim = wi * R * (0.0 * ux + 1.0 * uy)          # Y = (0, 1)
        scale = 1.0 + abs(vx) + abs(vy) + abs(w) * (L + W) + abs(wi) * R
        assert along_u == pytest.approx(rim, abs=1e-12 * scale * max(1.0, 1.0 / math.sin(alpha)))


@pytest.mark.parametrize("twist", [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.5, 0.2, -0.7)])
def test_wrong_roller_hand_breaks_the_constraint(twist):
    """The check above can fail: one roller hand for all wheels (the report's erratum)
    violates it for a sideways or spinning motion."""
    vx, vy, w = twist
    wheels = center_to_wheel(vx, vy, w, ALPHA, L0, W0, R0)
    rx, ry = wheel_positions(L0, W0)[0]
    ux, uy = roller_directions(ALPHA)[1]            # wheel 1 with wheel 2's roller direction
    along_u = (vx - w * ry) * ux + (vy + w * rx) * uy
    assert abs(along_u - wheels[0] * R0 * uy) > 1e-3


# ------------------------------------------------------------------ valid parameters

def test_check_geometry_accepts_the_seed_and_ranges():
    check_geometry(ALPHA, L0, W0, R0)
    check_geometry(1e-6, 1e-9, 1e-9, 1e-9)
    check_geometry(math.pi / 2 - 1e-6, 100.0, 100.0, 100.0)


BAD = [
    ("alpha", 0.0), ("alpha", math.pi / 2), ("alpha", -0.3), ("alpha", 2.0),
    ("alpha", float("nan")), ("alpha", float("inf")),
    ("L", 0.0), ("L", -0.16), ("L", float("nan")), ("L", float("inf")),
    ("W", 0.0), ("W", -0.12), ("W", float("nan")),
    ("R", 0.0), ("R", -0.06), ("R", float("nan")), ("R", -float("inf")),
]


@pytest.mark.parametrize("name, value", BAD)
def test_check_geometry_rejects_and_names_the_parameter(name, value):
    params = {"alpha": ALPHA, "L": L0, "W": W0, "R": R0}
    params[name] = value
    with pytest.raises(ValueError) as info:
        check_geometry(**params)
    message = str(info.value)
    assert re.search(rf"\b{name}\b", message), message
    for other in params:
        if other != name:
            assert not re.search(rf"\b{other}\b", message), (other, message)
