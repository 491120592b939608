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
_EYE = np.eye(3)[None]      # a linearised step's A but for the heading's column
# at most this many small phi (a run's first steps from rest) take their series in Python
# floats, one by one: a NumPy call costs more than a handful of values
_FEW = 8


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
    (per output: the accumulated error), terms() (per output: the size of the terms the
    signed one sums, for the master's test of cancellation)."""

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
        # the signed sums' terms taken apart, but for the jumps' own steps (their error is
        # exact, h (new - old) / 2): |position error| per axis, |heading error|, and |heading
        # error| x |p_t| per axis
        self.sizes = np.zeros(5)

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
        return max(bound, float(e_theta[0])), (body, e_theta, (vx, vy, w), self.blend.exact)

    def after(self, h: float, update: tuple) -> float:
        """The largest |error| of x, y, theta if the step were accepted."""
        saved = (self.theta, self.p.copy(), self.e.copy(), self.heading.copy(),
                 self.moment.copy(), self.sizes.copy())
        self.accept(h, update)
        worst = max(self.now())
        self.theta, self.p, self.e, self.heading, self.moment, self.sizes = saved
        return worst

    def accept(self, h: float, update: tuple) -> None:
        body, e_theta, (vx, vy, w), exact = update
        c, s = math.cos(self.theta), math.sin(self.theta)
        world = np.column_stack((c * body[:, 0] - s * body[:, 1],
                                 s * body[:, 0] + c * body[:, 1]))
        self.e += world
        if not exact:
            heading = abs(float(e_theta[1]))
            self.sizes += (abs(world[1, 0]), abs(world[1, 1]), heading,
                           heading * abs(self.p[0]), heading * abs(self.p[1]))
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

    def terms(self) -> tuple[float, float, float]:
        """Per x, y, theta, the size of the terms now(signed=True) sums: each step's |error|
        and, for the heading's lever arm e_t (p - p_t), |e_t| (|p| + |p_t|) (a bound of its
        size, from two running sums)."""
        ex, ey, heading, mx, my = self.sizes
        return (ex + heading * abs(self.p[1]) + my, ey + heading * abs(self.p[0]) + mx,
                heading)


def pose_batch(names: list[str], inst) -> "PoseBatch | None":
    """The fixed-step masters' client for a PoseIntegrator whose vx, vy and w are linked
    (`names`: its linked Real inputs, in the order the master hands their values), else None."""
    if not all(n in names for n in _TWIST):
        return None
    return PoseBatch([names.index(n) for n in _TWIST], inst)


class PoseBatch:
    """The same error of one pose as PoseError's signed part, for the fixed-step masters'
    embedded pair (master/pair.py), many steps at once. Per step it is handed the held twist,
    its error (held - true mean over the step) and the true twist's change over the step,
    in arrays. The run's pose is the held twist stepped on SE(2) (what the PoseIntegrator
    does), the true one the true mean twist stepped the same way less the frame turning
    within the step, J (w dv - dw v) h^2 / 12 (docs/masters.md); their difference is summed
    step by step (each step's displacement against the other's, turned by the heading
    error: no difference of two large sums, and no linearisation in the heading error,
    which Jacobi's lag makes large), the running totals carried from batch to batch.

    The batch interface: `outputs` (the variables it covers), steps(h, held, error, change)
    -> the signed accumulated error of each output after each step, shape (steps, outputs).
    With `branch` t (`branches`: it takes one), the last t rows are another version of the t
    rows before them, carried on from the state before those (Jacobi's end with the parabola,
    master/pair_rows.py, in the same NumPy calls); the running totals are the first's."""

    branches = True

    def __init__(self, index: list[int], inst):
        self.index, self.name = np.array(index), inst.name
        # the twist's columns: a slice where they are side by side in order (no copy)
        self.twist = slice(index[0], index[0] + 3) \
            if list(index) == list(range(index[0], index[0] + 3)) else self.index
        self.outputs = _POSE
        self.theta = float(inst.value("theta0"))      # the run's heading
        self.e, self.heading = np.zeros(2), 0.0         # run - true: position, heading

    def steps(self, h: np.ndarray, held: np.ndarray, error: np.ndarray, change: np.ndarray,
              branch: int = 0) -> np.ndarray:
        iw = self.index[2]
        run, true = self._displacements(h, held, error, change)    # x + i y
        turned, before = self._turned(h, held[:, iw], branch)
        heading = self.heading + _branched(np.cumsum(h * error[:, iw]), branch)
        lag = _before(self.heading, heading, branch)
        # R(-heading error) turns the true step; R(the run's heading) turns both into the world
        e = complex(*self.e) + _branched(
            np.cumsum(np.exp(1j * before) * (run - np.exp(-1j * lag) * true)), branch)
        last = len(h) - 1 - branch
        self.theta, self.e, self.heading = float(turned[last]), np.array(
            [e[last].real, e[last].imag]), float(heading[last])
        return np.column_stack((e.real, e.imag, heading))

    def linear(self, h: np.ndarray, held: np.ndarray, error: np.ndarray, change: np.ndarray,
               branch: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The steps linearised in the error, instead of steps() where a loop feeds the error
        back (master/pair_loop.py): E_k+1 = A_k E_k + made_k + B_k (the held inputs' further
        error), E = (x, y, theta). A: a heading error turns the step's world displacement d
        (adds e_theta J d); made: the error the step makes from an exact start (as steps());
        B: an error of the twist moved h along the heading at mid-step. With a `branch`, as
        steps()."""
        ivx, ivy, iw = self.index
        w = held[:, iw]
        run, true = self._displacements(h, held, error, change)
        turned, before = self._turned(h, w, branch)
        c, s = np.cos(before), np.sin(before)
        # the run's step and its error (run - true), turned by the run's heading into the
        # world: rows (x, y) of R(before) (x, y), one per (step, error)
        steps = np.array((run, run - true))
        x, y = steps.real, steps.imag
        world = (c * x - s * y, s * x + c * y)
        rows = len(h)
        a = np.repeat(_EYE, rows, axis=0)
        a[:, 0, 2], a[:, 1, 2] = -world[1][0], world[0][0]
        made = np.empty((rows, 3))
        made[:, 0], made[:, 1], made[:, 2] = world[0][1], world[1][1], h * error[:, iw]
        mid = before + 0.5 * h * w
        c, s = h * np.cos(mid), h * np.sin(mid)
        b = np.zeros((rows, 3, held.shape[1]))
        b[:, 0, ivx] = b[:, 1, ivy] = c
        b[:, 1, ivx], b[:, 0, ivy], b[:, 2, iw] = s, -s, h
        self.theta = float(turned[rows - 1 - branch])
        return a, b, made

    def _turned(self, h: np.ndarray, w: np.ndarray, branch: int = 0
                ) -> tuple[np.ndarray, np.ndarray]:
        """The run's heading after each step and before it, from the heading it has now."""
        turned = self.theta + _branched(np.cumsum(h * w), branch)
        return turned, _before(self.theta, turned, branch)

    def _displacements(self, h, held, error, change) -> tuple:
        """Per step, the body-frame displacement (x + i y) of the run (the held twist on
        SE(2)) and of the truth (the true mean twist, less the frame turning within the step,
        J (w dv - dw v) h^2 / 12: docs/masters.md)."""
        both = np.empty((2, len(h), 3))                 # the run's twist, the true one
        both[0] = held[:, self.twist]
        np.subtract(both[0], error[:, self.twist], out=both[1])
        v, w = both[..., :2].view(complex)[..., 0], both[..., 2]    # vx + i vy, w
        dv = change[:, self.twist]
        turning = (w[1] * (dv[:, 0] + 1j * dv[:, 1]) - dv[:, 2] * v[1]) * (h * h / 12)
        moved = _displacement(h, v, w)
        return moved[0], moved[1] + 1j * turning


def _branched(sums: np.ndarray, t: int) -> np.ndarray:
    """Running sums of rows whose last t are another version of the t before them: those
    restarted from the sum before the t they stand for (PoseBatch's `branch`)."""
    if t:
        n = len(sums)
        sums[n - t:] -= sums[n - t - 1] - (sums[n - 2 * t - 1] if n > 2 * t else 0.0)
    return sums


def _before(start, after: np.ndarray, t: int) -> np.ndarray:
    """Per row, the value before it (`start` before the first), of rows `after` with a
    branch of t (_branched): its first row follows the row before the t it stands for."""
    out = np.concatenate(([start], after[:-1]))
    if t:
        n = len(after)
        out[n - t] = after[n - 2 * t - 1] if n > 2 * t else start
    return out


def _displacement(h, v, w) -> np.ndarray:
    """The body-frame displacement (x + i y) of a twist (v = vx + i vy, w) held over h on
    SE(2) (blocks/pose.pose_step's, for arrays): h v (e^(i phi) - 1) / (i phi), phi = w h,
    by its series where |phi| < 1e-6."""
    phi = w * h
    small = np.abs(phi) < 1e-6
    if not small.any():
        turn = _turn(phi)
    elif small.all():
        turn = _series(phi)
    else:
        turn = _turn(np.where(small, 1.0, phi))
        few = phi[small]
        turn[small] = _series(few) if len(few) > _FEW else [_series(x) for x in few.tolist()]
    return h * turn * v


def _series(phi):
    """(e^(i phi) - 1) / (i phi) by its series, of an array or a float (the same arithmetic)."""
    phi2 = phi * phi
    return (1.0 - phi2 / 6.0 + phi2 * phi2 / 120.0) + 1j * (phi / 2.0 - phi * phi2 / 24.0)


def _turn(phi: np.ndarray) -> np.ndarray:
    half = np.sin(0.5 * phi)
    return (np.sin(phi) + 2j * half * half) / phi
