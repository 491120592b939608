"""Pose integration against docs/spec.md, Pose integration.

References are computed here: the closed-form rotation about the instantaneous centre of
rotation (ICR), a numerical solution of the spec's ODE, and an exact rational Taylor series.
"""
import math
from fractions import Fraction

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mecanum_fmu.models.blocks.pose import pose_rate, pose_step

START = (0.4, -0.7, 0.9)


def rotate(theta, x, y):
    c, s = math.cos(theta), math.sin(theta)
    return c * x - s * y, s * x + c * y


def icr_world(x, y, theta, vx, vy, w):
    """The ICR is at (-vy/w, vx/w) in the body frame (docs/spec.md, Instantaneous centre of
    rotation)."""
    bx, by = rotate(theta, -vy / w, vx / w)
    return x + bx, y + by


def ode_reference(start, twist, h):
    """Integrate the pose ODE (docs/spec.md, Pose integration) numerically (independent of any
    closed form)."""
    vx, vy, w = twist

    def rhs(_t, p):
        th = p[2]
        return [vx * math.cos(th) - vy * math.sin(th), vx * math.sin(th) + vy * math.cos(th), w]
    sol = solve_ivp(rhs, (0.0, h), list(start), method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.success
    return sol.y[:, -1]


def exact_displacement(vx, vy, w, h):
    """Body-frame displacement h * [[a, -b], [b, a]] @ (vx, vy), with a = sin(phi)/phi and
    b = (1 - cos(phi))/phi summed as exact rational Taylor series (small |phi| only)."""
    phi = Fraction(w) * Fraction(h)
    assert abs(phi) <= Fraction(1, 5)
    a = b = Fraction(0)
    term_a, term_b = Fraction(1), phi / 2          # phi^0/1!, phi^1/2!
    for n in range(12):
        a += term_a
        b += term_b
        term_a *= -phi * phi / ((2 * n + 2) * (2 * n + 3))
        term_b *= -phi * phi / ((2 * n + 3) * (2 * n + 4))
    H, VX, VY = Fraction(h), Fraction(vx), Fraction(vy)
    return float(H * (a * VX - b * VY)), float(H * (b * VX + a * VY))


# ------------------------------------------------------------------ rate (the ODE itself)

def test_pose_rate_is_spec_ode():
    theta, vx, vy, w = 0.7, 0.3, -1.2, 0.4
    expected = (vx * math.cos(theta) - vy * math.sin(theta),
                vx * math.sin(theta) + vy * math.cos(theta), w)
    assert pose_rate(theta, vx, vy, w) == pytest.approx(expected, rel=1e-15, abs=1e-15)
    # theta = 0: body = world (the seed's case).
    assert pose_rate(0.0, vx, vy, w) == pytest.approx((vx, vy, w), abs=0)


# ------------------------------------------------------------------ step-size independence

@pytest.mark.parametrize("twist", [
    (0.3, 1.0, 0.7),
    (-0.5, 0.2, -1.3),
    (1.0, 0.0, 0.0),
    (0.0, 1.0, 0.5),
    (0.2, -0.9, 3.0),
    (0.3, 1.0, 0.0015),     # a slow turn: small steps have w*h of a few 1e-6
])
def test_one_big_step_equals_1000_small_steps(twist):
    h = 2.0
    big = pose_step(*START, *twist, h)
    p = START
    for _ in range(1000):
        p = pose_step(*p, *twist, h / 1000)
    assert p == pytest.approx(big, abs=1e-12, rel=0)


@pytest.mark.parametrize("twist, h", [
    ((0.3, -0.8, 1.2), 3.0),
    ((1.0, 0.5, -2.0), 1.7),
    ((math.sin(0.4), math.cos(0.4), 0.0), 5.0),
])
def test_step_matches_numerical_solution_of_the_ode(twist, h):
    got = pose_step(*START, *twist, h)
    assert got == pytest.approx(ode_reference(START, twist, h), abs=1e-10, rel=0)


# ------------------------------------------------------------------ straight line (w = 0)

def test_heading_rotates_the_displacement():
    # Facing world -X (theta0 = pi/2), forward (vy = 1) moves along -x.
    x, y, theta = pose_step(1.0, 2.0, math.pi / 2, 0.0, 1.0, 0.0, 2.0)
    assert (x, y, theta) == pytest.approx((-1.0, 2.0, math.pi / 2), abs=1e-15)
    # ...and right (vx = 1) moves along +y.
    x, y, theta = pose_step(1.0, 2.0, math.pi / 2, 1.0, 0.0, 0.0, 2.0)
    assert (x, y, theta) == pytest.approx((1.0, 4.0, math.pi / 2), abs=1e-15)


@pytest.mark.parametrize("theta0", [0.0, 0.7, -2.5, math.pi])
def test_straight_line_when_w_is_zero(theta0):
    vx, vy, h = 0.3, -0.4, 1.5
    dx, dy = rotate(theta0, h * vx, h * vy)
    got = pose_step(1.0, -2.0, theta0, vx, vy, 0.0, h)
    assert got == pytest.approx((1.0 + dx, -2.0 + dy, theta0), abs=1e-15)
    if theta0 == 0.0:   # body = world: the Simulink diagram's direct integration
        assert got[:2] == pytest.approx((1.0 + h * vx, -2.0 + h * vy), abs=1e-15)


# ------------------------------------------------------------------ arcs about the ICR

@pytest.mark.parametrize("twist", [(0.0, 1.0, 0.5), (0.3, 1.0, 0.7), (-0.6, 0.25, -1.9)])
def test_arc_is_a_rotation_about_the_icr(twist):
    vx, vy, w = twist
    centre = icr_world(*START, vx, vy, w)
    radius = math.hypot(vx, vy) / abs(w)
    # The ICR lies at distance |v|/|w| from the chassis centre (docs/spec.md, Instantaneous
    # centre of rotation).
    assert math.dist(centre, START[:2]) == pytest.approx(radius, rel=1e-14)
    for h in np.linspace(0.1, 9.0, 12):
        x, y, theta = pose_step(*START, vx, vy, w, h)
        assert theta == pytest.approx(START[2] + w * h, abs=1e-14)
        # Still on the circle, and the ICR seen from the new pose has not moved.
        assert math.dist((x, y), centre) == pytest.approx(radius, abs=1e-12)
        assert icr_world(x, y, theta, vx, vy, w) == pytest.approx(centre, abs=1e-12)
        # The position is the start turned about the ICR by w*h (counter-clockwise for w > 0).
        rx, ry = rotate(w * h, START[0] - centre[0], START[1] - centre[1])
        assert (x, y) == pytest.approx((centre[0] + rx, centre[1] + ry), abs=1e-12)


def test_pure_forward_with_yaw_is_the_closed_form_arc():
    # From the origin, heading +Y, vy = 1, w = 0.5: x = 2(cos(t/2) - 1), y = 2 sin(t/2).
    for t in (0.5, 3.0, 10.0):
        x, y, theta = pose_step(0.0, 0.0, 0.0, 0.0, 1.0, 0.5, t)
        assert (x, y, theta) == pytest.approx(
            (2 * (math.cos(t / 2) - 1), 2 * math.sin(t / 2), t / 2), abs=1e-14)


def test_pure_spin_stays_in_place():
    x, y, theta = pose_step(*START, 0.0, 0.0, 2.0, 1.3)
    assert (x, y) == (START[0], START[1])
    assert theta == pytest.approx(START[2] + 2.6, abs=1e-15)


@pytest.mark.parametrize("w", [0.8, -0.8, 2 * math.pi])
def test_full_turn_returns_to_start(w):
    vx, vy = 0.3, 1.0
    h = 2 * math.pi / abs(w)
    x, y, theta = pose_step(*START, vx, vy, w, h)
    assert (x, y) == pytest.approx(START[:2], abs=1e-12)
    assert (math.cos(theta), math.sin(theta)) == pytest.approx(
        (math.cos(START[2]), math.sin(START[2])), abs=1e-12)
    # Half a turn lands diametrically opposite across the ICR.
    cx, cy = icr_world(*START, vx, vy, w)
    x, y, _ = pose_step(*START, vx, vy, w, h / 2)
    assert (x, y) == pytest.approx((2 * cx - START[0], 2 * cy - START[1]), abs=1e-12)


# ------------------------------------------------------------------ tiny w: the series branch

@pytest.mark.parametrize("w", [1e-9, -1e-9, 1e-12, 0.0])
def test_tiny_w_agrees_with_the_straight_line(w):
    vx, vy = 0.3, -1.1
    # Over a short step the bend (|w| h^2 |v| / 2 < 1e-15) is invisible: the w = 0 formula.
    h = 1e-3
    dx, dy = rotate(START[2], h * vx, h * vy)
    x, y, theta = pose_step(*START, vx, vy, w, h)
    assert (x, y) == pytest.approx((START[0] + dx, START[1] + dy), abs=1e-12)
    assert theta == START[2] + w * h
    # Over a long step it bends by ~|w| h^2 |v| / 2 and no more.
    h = 10.0
    dx, dy = rotate(START[2], h * vx, h * vy)
    x, y, _ = pose_step(*START, vx, vy, w, h)
    bend = abs(w) * h * h * math.hypot(vx, vy) / 2
    assert math.dist((x, y), (START[0] + dx, START[1] + dy)) == pytest.approx(bend, rel=1e-6, abs=1e-14)


@pytest.mark.parametrize("phi", [
    1e-12, 1e-9, 3e-8, 5e-7, 9.99e-7, 1.001e-6, 1.5e-6, 3e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.1])
def test_accuracy_across_the_series_threshold(phi):
    """Exact for every w*h: compare the body-frame displacement with an exact rational series,
    on both sides of the switch between the series and sin/cos formulas."""
    vx, vy, h = 0.3, 1.0, 1.0
    x, y, theta = pose_step(0.0, 0.0, 0.0, vx, vy, phi / h, h)
    ex, ey = exact_displacement(vx, vy, phi / h, h)
    assert (x, y) == pytest.approx((ex, ey), abs=1e-14, rel=0)
