"""The car-like robot of "Kinematic modelling of a car" as a kinematic bicycle
(docs/chassis.md; docs/spec.md, Kinematic bicycle).

Rear-axle speed v, steering angle phi (positive turns left, counter-clockwise), wheelbase l.
The body twist (this project's frame: +Y forward, +X right) of the reference point:
rear axle (0, v, v tan(phi)/l); front axle (-v tan(phi), v, v tan(phi)/l). The instantaneous
centre of rotation lies on the rear-axle line, l/tan(phi) to the left of the rear axle.
"""
import math

REAR, FRONT = 0, 1
MAX_STEER = math.radians(89.0)   # |phi| beyond this: tan(phi) and the front speed blow up


def bicycle_problem(l: float, reference: int):
    """(parameter, message) for the first parameter outside its valid range, else None."""
    if not isinstance(l, (int, float)) or not math.isfinite(l) or not l > 0.0:
        return "l", f"parameter l = {l!r} m must be a finite number > 0"
    if reference not in (REAR, FRONT):
        return "reference", (f"parameter reference = {reference!r} must be 0 (rear axle) "
                             "or 1 (front axle)")
    return None


def check_bicycle(l: float, reference: int) -> None:
    """Raise ValueError for the first parameter outside its valid range."""
    problem = bicycle_problem(l, reference)
    if problem is not None:
        raise ValueError(problem[1])


def bicycle_twist(v: float, phi: float, l: float,
                  reference: int = REAR) -> tuple[float, float, float]:
    """Body twist (vx, vy, w) of the rear- (0) or front-axle (1) point for speed v, steering phi."""
    if not abs(phi) <= MAX_STEER:
        raise ValueError(f"steering angle phi = {phi!r} rad is outside |phi| <= 89 deg")
    w = v * math.tan(phi) / l
    return (-w * l if reference == FRONT else 0.0), v, w
