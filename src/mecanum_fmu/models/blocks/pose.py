"""Pose integration on SE(2) (docs/spec.md, Pose integration)."""
import math


def pose_step(x: float, y: float, theta: float,
              vx: float, vy: float, w: float, h: float) -> tuple[float, float, float]:
    """Advance the world-frame pose by h seconds under a body-frame twist held constant.

    Exact (the SE(2) exponential): a straight line when w == 0, an arc of radius |v|/|w|
    otherwise, so a constant twist gives the exact path for any step size.
    """
    phi = w * h
    if abs(phi) < 1e-6:
        # Series of sin(phi)/phi and (1 - cos(phi))/phi: avoids 0/0.
        phi2 = phi * phi
        a = 1.0 - phi2 / 6.0 + phi2 * phi2 / 120.0
        b = phi / 2.0 - phi * phi2 / 24.0
    else:
        a = math.sin(phi) / phi
        # 1 - cos(phi) = 2 sin^2(phi/2): no cancellation for small phi.
        half = math.sin(0.5 * phi)
        b = 2.0 * half * half / phi
    # Displacement in the body frame at the start of the step.
    dx = h * (a * vx - b * vy)
    dy = h * (b * vx + a * vy)
    c, s = math.cos(theta), math.sin(theta)
    return x + c * dx - s * dy, y + s * dx + c * dy, theta + phi


def pose_rate(theta: float, vx: float, vy: float, w: float) -> tuple[float, float, float]:
    """Time derivative of the pose: (x', y', theta')."""
    c, s = math.cos(theta), math.sin(theta)
    return vx * c - vy * s, vx * s + vy * c, w


def world_to_body(vX: float, vY: float, theta: float) -> tuple[float, float]:
    """World-frame velocity -> body-frame (vx, vy) at heading theta: the inverse of pose_rate's
    rotation (field-oriented driving; identity at theta = 0)."""
    c, s = math.cos(theta), math.sin(theta)
    return vX * c + vY * s, -vX * s + vY * c
