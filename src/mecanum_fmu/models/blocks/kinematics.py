"""Mecanum kinematics of the O-layout chassis (docs/spec.md, Kinematics).

Body frame: +Y forward, +X right, yaw rate w counter-clockwise. Wheels 1 front-right,
2 front-left, 3 rear-left, 4 rear-right; a wheel speed is positive when it rolls the car forward.
"""
import math


GEOMETRY = ("alpha", "L", "W", "R")
# The seed study's chassis: 45 degree rollers, L = 0.16 m, W = 0.12 m, R = 0.06 m.
DEFAULT_GEOMETRY = {"alpha": math.pi / 4, "L": 0.16, "W": 0.12, "R": 0.06}


def geometry_problem(alpha: float, L: float, W: float, R: float):
    """(parameter, message) for the first parameter outside its valid range, else None."""
    for name, value in (("alpha", alpha), ("L", L), ("W", W), ("R", R)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return name, f"parameter {name} = {value!r} is not a finite number"
    if not 0.0 < alpha < math.pi / 2:
        return "alpha", (f"parameter alpha = {alpha!r} rad is outside 0 < alpha < pi/2 "
                         "(cot and tan of the roller angle blow up at the ends)")
    for name, value in (("L", L), ("W", W), ("R", R)):
        if not value > 0.0:
            return name, f"parameter {name} = {value!r} m must be > 0"
    return None


def check_geometry(alpha: float, L: float, W: float, R: float) -> None:
    """Raise ValueError for the first parameter outside its valid range."""
    problem = geometry_problem(alpha, L, W, R)
    if problem is not None:
        raise ValueError(problem[1])


def check_wheel_limit(w_max: float) -> None:
    """Raise ValueError unless w_max is a finite number >= 0 (0: no limit)."""
    if not isinstance(w_max, (int, float)) or not math.isfinite(w_max) or w_max < 0.0:
        raise ValueError(f"parameter w_max = {w_max!r} rad/s must be a finite number >= 0 "
                         "(0: no wheel speed limit)")


def radius_deviation_problem(R: float, *dR: float):
    """(parameter, message) for the first wheel whose effective radius R + dRi is not > 0."""
    for i, d in enumerate(dR, start=1):
        if not isinstance(d, (int, float)) or not math.isfinite(d):
            return f"dR{i}", f"parameter dR{i} = {d!r} is not a finite number"
        if not R + d > 0.0:
            return f"dR{i}", (f"parameter dR{i} = {d!r} m makes the effective radius "
                              f"R + dR{i} = {R + d!r} m, which must be > 0")
    return None


def check_radius_deviations(R: float, dR: tuple[float, ...]) -> None:
    """Raise ValueError for the first wheel whose effective radius R + dRi is not > 0."""
    problem = radius_deviation_problem(R, *dR)
    if problem is not None:
        raise ValueError(problem[1])


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
    """Instantaneous centre of rotation in the body frame (docs/spec.md,
    Instantaneous centre of rotation).

    Returns (icr_x, icr_y, has_icr): (-vy/w, vx/w, True) for |w| >= tol; a pure translation
    (|w| < tol) has none: (0.0, 0.0, False).
    """
    if not abs(w) >= tol:
        return 0.0, 0.0, False
    return -vy / w, vx / w, True


def limit_wheel_speeds(speeds: tuple[float, ...], w_max: float) -> tuple[float, ...]:
    """Scale all wheel speeds by one factor so that none exceeds w_max [rad/s] in magnitude.

    One common factor keeps the ratios between the wheels, so the chassis keeps its direction
    of motion and its ICR and only slows down. w_max = 0 means no limit.
    """
    if not w_max > 0.0:
        return tuple(speeds)
    peak = max(abs(s) for s in speeds)
    if peak <= w_max:
        return tuple(speeds)
    scale = w_max / peak
    return tuple(s * scale for s in speeds)
