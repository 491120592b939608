"""The PoseIntegrator's error model for the adaptive master: a client it is handed (through
Graph.error_models), so that master/ knows nothing of poses.

The master's own, generic error of a step (master/adaptive.py, the embedded hold pair) sees
what the hold of an input costs; it cannot see what an SE(2) integrator does with a twist
that changes within a step while the frame turns. This client adds that, from the twist the
step already moved (no extra doStep): the hold's signed next term on each twist component,
the frame turning within the step, J (w dv - dw v) h^2 / 12, and the heading's lever arm (a
heading error e_t at p_t moves every later point by J (p - p_t)). docs/masters.md, "The
adaptive master".
"""
from __future__ import annotations

import math

import numpy as np

_TWIST = ("vx", "vy", "w")
_POSE = ("x", "y", "theta")


def pose_error(blend, names: list[str], inst) -> "PoseError | None":
    """The client for a PoseIntegrator whose vx, vy and w the blend holds (else None)."""
    if not all(n in names for n in _TWIST):
        return None
    return PoseError(blend, [names.index(n) for n in _TWIST], inst)


class PoseError:
    """The signed error of one pose, accumulated over the accepted steps: the body-frame
    errors of each step turned into the world frame (heading and position tracked from the
    held twist), and the heading's errors carried along the path travelled since.

    The client interface (master/adaptive.py): `outputs` (the variables it covers), step(h,
    left) -> (this step's own error, in the outputs' unit, and an update), after(h, update)
    (the largest accumulated |error| if the step were accepted), accept(h, update), now(signed)
    (per output: the accumulated error)."""

    def __init__(self, blend, index: list[int], inst):
        self.blend, self.index, self.name = blend, index, inst.name
        self.outputs = _POSE
        self.theta = float(inst.value("theta0"))
        self.p = np.zeros(2)
        # per sum: position errors made on the steps (world frame), the heading errors and
        # the sum of p_t * heading error_t; [0] with the cubic's term as a bound (|u4|: the
        # controller's), [1] signed (the run's estimate: errors that cancel do)
        self.e = np.zeros((2, 2))
        self.heading = np.zeros(2)
        self.moment = np.zeros((2, 2))

    @property
    def sources(self):
        """The buffer slots of the twist's sources (vx, vy, w)."""
        return self.blend.src[self.index]

    def step(self, h: float, left: float, upstream=((0.0,) * 3,) * 2) -> tuple[float, tuple]:
        """The larger of this step's position error bound (m) and |heading error| (rad),
        and the signed update to apply if the step is accepted. `upstream`: the error the
        twist (vx, vy, w) already carries from its sources, for the bound and for the
        estimate (the master's, accumulated): the pose integrates it, h times it per step."""
        e, signed = self.blend.error()
        ivx, ivy, iw = self.index
        ux, uy, uw = (h * float(v) for v in upstream[0])
        sx, sy, sw = (h * float(v) for v in upstream[1])
        now, u, mean = self.blend.rows[0], self.blend.rows[1], self.blend.staging
        vx, vy, w = mean[ivx], mean[ivy], mean[iw]
        dvx, dvy, dw = now[ivx] - u[ivx], now[ivy] - u[ivy], now[iw] - u[iw]
        # held minus true: the cubic's term (the third derivative's, h^4/24 over the step)
        # and the frame turning within the step, -J (w dv - dw v) h^2 / 12 (docs/masters.md)
        tx, ty = (w * dvx - dw * vx) * h * h / 12, (w * dvy - dw * vy) * h * h / 12
        body = np.array([(h * abs(e[ivx]) + abs(ux) + ty, h * abs(e[ivy]) + abs(uy) - tx),
                         (h * signed[ivx] + sx + ty, h * signed[ivy] + sy - tx)])
        e_theta = np.array([h * abs(e[iw]) + abs(uw), h * signed[iw] + sw])
        bound = math.hypot(*body[0]) + e_theta[0] * math.hypot(vx, vy) * left
        return max(bound, float(e_theta[0])), (body, e_theta, (vx, vy, w))

    def after(self, h: float, update: tuple) -> float:
        """The largest |error| of x, y, theta if the step were accepted."""
        saved = (self.theta, self.p.copy(), self.e.copy(), self.heading.copy(),
                 self.moment.copy())
        self.accept(h, update)
        worst = max(self.now())
        self.theta, self.p, self.e, self.heading, self.moment = saved
        return worst

    def accept(self, h: float, update: tuple) -> None:
        body, e_theta, (vx, vy, w) = update
        c, s = math.cos(self.theta), math.sin(self.theta)
        self.e += np.column_stack((c * body[:, 0] - s * body[:, 1],
                                   s * body[:, 0] + c * body[:, 1]))
        self.p += (h * (c * vx - s * vy), h * (s * vx + c * vy))
        self.theta += h * w
        self.heading += e_theta
        self.moment += np.outer(e_theta, self.p)

    def now(self, signed: bool = False) -> tuple[float, float, float]:
        """|error| of x, y, theta now (the bound, or `signed`: the estimate): the steps' own,
        plus J (p S - sum p_t e_t) of the heading errors (a heading error e_t at p_t moves
        every later point by J (p - p_t))."""
        k = int(signed)
        carried = self.p * self.heading[k] - self.moment[k]
        return (abs(self.e[k, 0] - carried[1]), abs(self.e[k, 1] + carried[0]),
                abs(self.heading[k]))
