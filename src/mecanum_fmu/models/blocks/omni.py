"""The four-wheel 45-degree omni X-drive of "Kinematics of a four-wheel omni-wheel chassis"
(docs/chassis.md; docs/spec.md, Omni X-drive).

Wheels in that document's numbering: 1 front-left, 2 rear-left, 3 rear-right, 4 front-right,
each at distance L from the chassis centre on a diagonal, rolling tangentially: a positive
wheel speed pushes the chassis counter-clockwise. The document's rows, in its own frame
(x forward, y left; u, v the body velocities along x, y):

    v_i = (sqrt2/2)(a_i u + b_i v) + L w,  (a, b) = (-1, 1), (-1, -1), (1, -1), (1, 1)

In this project's body frame (+Y forward, +X right) u = vy and v = -vx.
"""
import math

_S = math.sqrt(0.5)   # sqrt(2)/2


def omni_geometry_problem(L: float, R: float):
    """(parameter, message) for the first parameter that is not a finite number > 0, else None."""
    for name, value in (("L", L), ("R", R)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return name, f"parameter {name} = {value!r} is not a finite number"
        if not value > 0.0:
            return name, f"parameter {name} = {value!r} m must be > 0"
    return None


def check_omni_geometry(L: float, R: float) -> None:
    """Raise ValueError for the first parameter that is not a finite number > 0."""
    problem = omni_geometry_problem(L, R)
    if problem is not None:
        raise ValueError(problem[1])


def omni_center_to_wheel(vx: float, vy: float, w: float,
                         L: float, R: float) -> tuple[float, float, float, float]:
    """Inverse kinematics: body twist -> wheel angular speeds w1..w4 [rad/s] (rim speed / R)."""
    a = _S * (vy + vx)    # the document's sqrt2/2 (u - v)
    b = _S * (vy - vx)    # the document's sqrt2/2 (u + v)
    k = L * w
    return (-a + k) / R, (-b + k) / R, (a + k) / R, (b + k) / R


def omni_wheel_to_center(w1: float, w2: float, w3: float, w4: float,
                         L: float, R: float) -> tuple[float, float, float]:
    """Forward kinematics: wheel speeds -> body twist (vx, vy, w).

    The columns of the wheel matrix are orthogonal, so this is its exact least-squares
    inverse: inconsistent wheel speeds give the best-fitting twist.
    """
    v1, v2, v3, v4 = w1 * R, w2 * R, w3 * R, w4 * R
    h = 0.5 * _S          # sqrt(2)/4
    return (h * (-v1 + v2 + v3 - v4),
            h * (-v1 - v2 + v3 + v4),
            (v1 + v2 + v3 + v4) / (4.0 * L))
