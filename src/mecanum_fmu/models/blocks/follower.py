"""Path following for a holonomic (mecanum) chassis: reference feed-forward + pose feedback.

World frame and pose as in docs/spec.md, Pose: x' = vx cos(theta) - vy sin(theta),
y' = vx sin(theta) + vy cos(theta), theta' = w, with the body twist (vx right, vy forward, w).

The command asks for the world velocity  v = r'(t) + k_pos (r(t) - p)  and the yaw rate
w = theta_r'(t) + k_theta wrap(theta_r(t) - theta), and turns v into the body frame with the
measured heading. Because the chassis is holonomic, the closed loop is then exactly linear:
the position error and the heading error each decay as exp(-k t), independently.

The reference rates r'(t) are central differences of the reference expressions (the safe
evaluator builds closures, it does not differentiate symbolically): step d = 6e-6 max(1, |t|),
truncation error d^2/6 |r'''|, about 1e-11 for smooth references. Standard library only: this
source is inlined verbatim into the standalone FMU script.
"""
import math


def central_difference(f, t):
    """f'(t) by a central difference with a step scaled to t."""
    d = 6e-6 * max(1.0, abs(t))
    up, down = t + d, t - d
    return (f(up) - f(down)) / (up - down)


def wrap_angle(a):
    """a wrapped into [-pi, pi]."""
    return math.atan2(math.sin(a), math.cos(a))


def follow(t, x, y, theta, refs, k_pos, k_theta):
    """Body twist (vx, vy, w) that steers the pose (x, y, theta) onto the reference.

    refs: three functions of t, (x_ref, y_ref, theta_ref)."""
    fx, fy, fth = refs
    vx_world = central_difference(fx, t) + k_pos * (fx(t) - x)
    vy_world = central_difference(fy, t) + k_pos * (fy(t) - y)
    w = central_difference(fth, t) + k_theta * wrap_angle(fth(t) - theta)
    c, s = math.cos(theta), math.sin(theta)
    # world -> body: the transpose of the rotation in the pose equations
    return c * vx_world + s * vy_world, -s * vx_world + c * vy_world, w
