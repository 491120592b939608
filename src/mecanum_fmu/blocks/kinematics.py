"""Mecanum kinematics of the O-layout chassis (SPEC.md section 3).

Body frame: +Y forward, +X right, yaw rate w counter-clockwise. Wheels 1 front-right,
2 front-left, 3 rear-left, 4 rear-right; a wheel speed is positive when it rolls the car forward.
"""
import math


def check_geometry(alpha: float, L: float, W: float, R: float) -> None:
    """Raise ValueError naming the first parameter outside its valid range."""
    for name, value in (("alpha", alpha), ("L", L), ("W", W), ("R", R)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"parameter {name} = {value!r} is not a finite number")
    if not 0.0 < alpha < math.pi / 2:
        raise ValueError(
            f"parameter alpha = {alpha!r} rad is outside 0 < alpha < pi/2 "
            "(cot and tan of the roller angle blow up at the ends)")
    for name, value in (("L", L), ("W", W), ("R", R)):
        if not value > 0.0:
            raise ValueError(f"parameter {name} = {value!r} m must be > 0")


def check_radius_deviations(R: float, dR: tuple[float, ...]) -> None:
    """Raise ValueError naming the first wheel whose effective radius R + dRi is not > 0."""
    for i, d in enumerate(dR, start=1):
        if not isinstance(d, (int, float)) or not math.isfinite(d):
            raise ValueError(f"parameter dR{i} = {d!r} is not a finite number")
        if not R + d > 0.0:
            raise ValueError(f"parameter dR{i} = {d!r} m makes the effective radius "
                             f"R + dR{i} = {R + d!r} m, which must be > 0")


def lever_arm(alpha: float, L: float, W: float) -> float:
    """k = L + W*cot(alpha): the yaw lever arm in the wheel rows of the matrix."""
    return L + W / math.tan(alpha)


def center_to_wheel(vx: float, vy: float, w: float,
                    alpha: float, L: float, W: float, R: float) -> tuple[float, float, float, float]:
    """Inverse kinematics: chassis twist (body frame) -> wheel angular speeds w1..w4 [rad/s]."""
    c = 1.0 / math.tan(alpha)
    k = L + W * c
    a = c * vx
    return ((-a + vy + k * w) / R,
            (a + vy - k * w) / R,
            (-a + vy - k * w) / R,
            (a + vy + k * w) / R)


def wheel_to_center(w1: float, w2: float, w3: float, w4: float,
                    alpha: float, L: float, W: float, R: float,
                    dR: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
                    ) -> tuple[float, float, float]:
    """Forward kinematics: wheel speeds -> chassis twist (vx, vy, w).

    The columns of the wheel matrix are orthogonal, so this is exactly its least-squares
    inverse: inconsistent wheel speeds (slip, noise) give the best-fitting twist.
    dR: per-wheel effective-radius deviations (a worn or slipping wheel rolls the chassis
    with R + dRi): wheel i counts as the speed wi * (R + dRi) / R of a nominal wheel. At
    dRi = 0 the factor is exactly 1.0, so the result is bit-for-bit the nominal one.
    """
    if dR[0] or dR[1] or dR[2] or dR[3]:
        w1, w2, w3, w4 = (w * ((R + d) / R) for w, d in zip((w1, w2, w3, w4), dR))
    k = L + W / math.tan(alpha)
    return (R * math.tan(alpha) / 4.0 * (-w1 + w2 - w3 + w4),
            R / 4.0 * (w1 + w2 + w3 + w4),
            R / (4.0 * k) * (w1 - w2 - w3 + w4))


def instantaneous_center(vx: float, vy: float, w: float,
                         tol: float = 1e-9) -> tuple[float, float, bool]:
    """Instantaneous centre of rotation in the body frame (SPEC.md section 4, seeds/003 eq. 20).

    Returns (icr_x, icr_y, has_icr): (-vy/w, vx/w, True) for |w| >= tol; a pure translation
    (|w| < tol) has none: (0.0, 0.0, False).
    """
    if not abs(w) >= tol:
        return 0.0, 0.0, False
    return -vy / w, vx / w, True
