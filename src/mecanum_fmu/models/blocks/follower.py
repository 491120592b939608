"""Path following for a holonomic (mecanum) chassis: reference feed-forward + pose feedback.

World frame and pose as in docs/spec.md, Pose: x' = vx cos(theta) - vy sin(theta),
y' = vx sin(theta) + vy cos(theta), theta' = w, with the body twist (vx right, vy forward, w).

The command asks for the world velocity  v = r'(t) + k_pos (r(t) - p)  and the yaw rate
w = theta_r'(t) + k_theta wrap(theta_r(t) - theta), and turns v into the body frame with the
measured heading. Because the chassis is holonomic, the closed loop is then exactly linear:
the position error and the heading error each decay as exp(-k t), independently.

The reference is expressions of t or a recorded path (blocks/profile_table.py, path_sampler:
linear between rows, its rates the rows' slopes). For expressions, the rates r'(t) are
central differences of the reference expressions (the safe
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


def expression_reference(refs):
    """The reference of three functions of t (x_ref, y_ref, theta_ref) as a function
    t -> ((x, y, theta), (x', y', theta')), the rates by central difference."""
    def reference(t):
        return (tuple(f(t) for f in refs), tuple(central_difference(f, t) for f in refs))
    return reference


def follow(t, x, y, theta, reference, k_pos, k_theta):
    """Body twist (vx, vy, w) that steers the pose (x, y, theta) onto the reference.

    reference: t -> ((x_ref, y_ref, theta_ref), their rates): expression_reference, or
    profile_table.path_sampler for a recorded path (rates: the table's slopes)."""
    (xr, yr, thr), (dxr, dyr, dthr) = reference(t)
    vx_world = dxr + k_pos * (xr - x)
    vy_world = dyr + k_pos * (yr - y)
    w = dthr + k_theta * wrap_angle(thr - theta)
    c, s = math.cos(theta), math.sin(theta)
    # world -> body: the transpose of the rotation in the pose equations
    return c * vx_world + s * vy_world, -s * vx_world + c * vy_world, w
