"""The dashboard's panels: one drawing function per panel, each taking an Axes, and the table of
panels (PANELS) with what each needs and its title.

A panel's `needs` and title depend only on the recorded column names and the roles (the plot
worker lays out the dashboard before the run ends); what a drawer finds in the data (no ICR,
no ground truth) it says in a note inside the panel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import matplotlib
from matplotlib import ticker
from matplotlib.axes import Axes
from matplotlib.artist import Artist
from matplotlib.lines import TICKLEFT, Line2D

from .against_recorded import position_errors, recorded_rows
from .truth import Truth
from ..models.catalog import Roles
from ..results import Results

MAX_POINTS = 5000                 # more rows than this are decimated before drawing
TWIST = ("vx", "vy", "w")
STEERING = ("v", "phi")
WHEELS = (("w1", "front-right"), ("w2", "front-left"), ("w3", "rear-left"), ("w4", "rear-right"))
OMNI_WHEELS = (("w1", "front-left"), ("w2", "rear-left"), ("w3", "rear-right"),
               ("w4", "front-right"))                       # docs/chassis.md
# Four wheel curves that stay apart where they coincide (with w = 0, w1 = w3 and w2 = w4,
# docs/spec.md, The seed scenario; driving straight ahead, all four): each drawn thinner and on
# top of the one before, wide pale solid, solid, dashed, dotted, so every curve shows.
WHEEL_STYLES = (dict(ls="-", lw=5.0, alpha=0.4, zorder=2),
                dict(ls="-", lw=2.5, alpha=0.8, zorder=3),
                dict(ls="--", lw=1.5, zorder=4),
                dict(ls=":", lw=2.0, zorder=5))
WORLD_LABELS = {"vx": "vX (world)", "vy": "vY (world)", "w": "ω"}
NO_ICR = "pure translation: no ICR (w = 0)"
FAR_ICR = "ICR farther than one path size from the path: not shown"
NO_TRUTH = "no ground truth for this graph"
ERROR_FLOOR = 1e-12     # errors below this (round-off, exact zeros) are drawn on it
MIN_SPAN = 0.2          # the least y range of a panel of values against time: no zoom into noise


def decimate_index(n: int, max_points: int = MAX_POINTS) -> np.ndarray:
    """Row indices to draw: every k-th row so that about max_points remain, always the last."""
    if n <= max_points:
        return np.arange(n)
    idx = np.arange(0, n, math.ceil(n / max_points))
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


def _col(results: Results, instance: str | None, var: str) -> str | None:
    """`instance.var` when that column was recorded, else None."""
    name = f"{instance}.{var}"
    return name if instance is not None and name in results.names else None


def _t(results: Results) -> tuple[np.ndarray, np.ndarray]:
    idx = decimate_index(len(results.time))
    return idx, results.time[idx]


def note(ax: Axes, text: str) -> None:
    """A boxed sentence in the middle of the panel: what the data leave out, and why."""
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=10,
            bbox=dict(boxstyle="round", facecolor="white", edgecolor="0.6"), zorder=10)


def _finish(ax: Axes, xlabel: str, ylabel: str, equal: bool = False) -> None:
    if equal:
        ax.set_aspect("equal", adjustable="datalim")
    elif ax.get_yscale() == "linear" and ax.get_lines():
        _least_span(ax)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True)
    if ax.get_lines():
        ax.legend()


def _least_span(ax: Axes) -> None:
    """At least MIN_SPAN of y range about the data: a constant (or round-off) stays flat."""
    ys = np.concatenate([np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()])
    ys = ys[np.isfinite(ys)]
    if len(ys) and float(np.ptp(ys)) < MIN_SPAN:
        mid = (float(ys.max()) + float(ys.min())) / 2
        ax.set_ylim(mid - MIN_SPAN / 2, mid + MIN_SPAN / 2)


# --------------------------------------------------------------------------- who drives what
def inputs(roles: Roles) -> tuple[str | None, tuple[str, ...]]:
    """The scenario's input block and its channels: a VelocitySource, else a SteeringSource."""
    if roles.source is not None:
        return roles.source, TWIST
    return roles.steering, STEERING


def commander(roles: Roles) -> str | None:
    """The block whose outputs are the commanded BODY twist: FieldToBody (its source speaks
    in the world frame), the VelocitySource, or the PathFollower."""
    return roles.frame or roles.source or roles.follower


def wheels_of(roles: Roles) -> tuple[str | None, tuple]:
    if roles.inverse is not None:
        return roles.inverse, WHEELS
    return roles.omni_inverse, OMNI_WHEELS


def forward_of(roles: Roles) -> str | None:
    """The forward kinematics of the same chassis as wheels_of (a graph of several chassis,
    scenarios/chassis/compare.yaml, does not mix the mecanum wheels with the omni twist)."""
    return roles.forward or (roles.omni_forward if roles.inverse is None else None)


def truth_at(truth: Truth, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth's x, y, theta at the recorded times (it is thinned for long runs)."""
    if len(truth.time) == len(times) and np.array_equal(truth.time, times):
        return truth.x, truth.y, truth.theta
    return tuple(np.interp(times, truth.time, v) for v in (truth.x, truth.y, truth.theta))


# --------------------------------------------------------------------------- drawers
def _draw_velocities(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The scenario's input channels against time (world-frame names behind a FieldToBody)."""
    idx, t = _t(results)
    block, channels = inputs(roles)
    for var in channels:
        if name := _col(results, block, var):
            ax.plot(t, results[name][idx], label=WORLD_LABELS[var] if roles.frame else var)
    if channels == STEERING:
        _finish(ax, "t [s]", "v [m/s]; phi [rad]")
    elif roles.frame:
        _finish(ax, "t [s]", "vX, vY [m/s] (world); ω [rad/s]")
    else:
        _finish(ax, "t [s]", "vx, vy [m/s]; w [rad/s]")


def _draw_path(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Simulated path over the ground-truth path, start and end marked, equal axes."""
    if truth is not None and len(truth.x):
        ti = decimate_index(len(truth.x))
        ax.plot(truth.x[ti], truth.y[ti], color="0.6", lw=3, label="ground truth")
    idx = decimate_index(len(results.time))
    x, y = results[f"{roles.pose}.x"], results[f"{roles.pose}.y"]
    ax.plot(x[idx], y[idx], color="C0", lw=1.2, label="simulated")
    ax.plot([x[0]], [y[0]], "o", color="C2", label="start")
    ax.plot([x[-1]], [y[-1]], "s", color="C3", label="end")
    if truth is not None and len(truth.x):
        ax.plot([truth.x[-1]], [truth.y[-1]], "x", color="k", label="ground-truth end")
    _finish(ax, "x [m] (right)", "y [m] (forward)", equal=True)


def _draw_vy(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The commanded forward speed vy against time (vY, world frame, behind a FieldToBody)."""
    idx, t = _t(results)
    label = WORLD_LABELS["vy"] if roles.frame else "vy"
    ax.plot(t, results[f"{roles.source}.vy"][idx], label=label)
    _finish(ax, "t [s]", "vY [m/s] (world)" if roles.frame else "vy [m/s]")


def _draw_wheels(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The four wheel speeds from inverse kinematics, each in a style of its own."""
    idx, t = _t(results)
    block, wheels = wheels_of(roles)
    for (var, where), style in zip(wheels, WHEEL_STYLES):
        if name := _col(results, block, var):
            ax.plot(t, results[name][idx], label=f"{var} {where}", **style)
    _finish(ax, "t [s]", "wheel speed [rad/s]")


def _draw_twist(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Commanded (wide, pale) against reconstructed (dashed) body twist."""
    idx, t = _t(results)
    command, forward = commander(roles), forward_of(roles)
    for i, var in enumerate(TWIST):
        cmd, rec = _col(results, command, var), _col(results, forward, var)
        if cmd:
            ax.plot(t, results[cmd][idx], "-", color=f"C{i}", lw=3, alpha=0.5,
                    label=f"{var} commanded")
        if rec:
            ax.plot(t, results[rec][idx], "--" if command else "-", color=f"C{i}",
                    label=f"{var} reconstructed" if command else var)
    _finish(ax, "t [s]", "vx, vy [m/s]; w [rad/s] (body)")


def _draw_theta(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The heading against time, over the ground truth's (or the reference's)."""
    idx, t = _t(results)
    if truth is not None and len(truth.x):
        ti = decimate_index(len(truth.time))
        ax.plot(truth.time[ti], truth.theta[ti], color="0.6", lw=3,
                label="reference" if roles.follower else "ground truth")
    theta = results[f"{roles.pose}.theta"]
    end = round(float(theta[-1]), 3) + 0.0        # + 0.0: no "-0.000" for a round-off below 0
    ax.plot(t, theta[idx], color="C0", lw=1.2,
            label=f"simulated (end {end:.3f} rad = {math.degrees(end):.1f}°)")
    _finish(ax, "t [s]", "θ [rad]")


def icr_world(results: Results, roles: Roles) -> tuple[np.ndarray, np.ndarray]:
    """The ICR (forward block's icr_x, icr_y, body frame) in the world frame, rows with has_icr."""
    p, f = roles.pose, roles.forward
    th = results[f"{p}.theta"] if _col(results, p, "theta") else np.zeros(len(results.time))
    bx, by = results[f"{f}.icr_x"], results[f"{f}.icr_y"]
    c, s = np.cos(th), np.sin(th)
    wx = results[f"{p}.x"] + c * bx - s * by
    wy = results[f"{p}.y"] + s * bx + c * by
    has = np.asarray(results[f"{f}.has_icr"], dtype=bool)
    return wx[has], wy[has]


def _draw_icr(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Instantaneous centre of rotation in the world frame (where it exists) over the path;
    a note when there is none (w = 0 throughout) or it lies far off."""
    x, y = results[f"{roles.pose}.x"], results[f"{roles.pose}.y"]
    idx = decimate_index(len(results.time))
    ax.plot(x[idx], y[idx], color="C0", lw=1.2, label="path")
    wx, wy = icr_world(results, roles)
    # Near w = 0 the ICR runs off to infinity: show only what lies within one path size
    # (at least 0.5 m) of the path, so the path stays readable.
    span = max(float(np.ptp(x)), float(np.ptp(y)), 0.5)
    near = ((wx >= x.min() - span) & (wx <= x.max() + span)
            & (wy >= y.min() - span) & (wy <= y.max() + span))
    if len(wx) == 0:
        note(ax, NO_ICR)
    elif not near.any():
        note(ax, FAR_ICR)
    else:
        keep = decimate_index(int(near.sum()))
        ax.plot(wx[near][keep], wy[near][keep], ".", color="C3", ms=3, label="ICR")
    _finish(ax, "x [m] (right)", "y [m] (forward)", equal=True)


def _draw_tracking_path(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Closed loop: the reference path (the follower's x_ref, y_ref) against the actual path."""
    if truth is not None and len(truth.x):
        ti = decimate_index(len(truth.x))
        ax.plot(truth.x[ti], truth.y[ti], color="0.6", lw=3, label="reference")
        ax.plot([truth.x[0]], [truth.y[0]], "x", color="k", label="reference start")
    idx = decimate_index(len(results.time))
    x, y = results[f"{roles.pose}.x"], results[f"{roles.pose}.y"]
    ax.plot(x[idx], y[idx], color="C0", lw=1.2, label="actual")
    ax.plot([x[0]], [y[0]], "o", color="C2", label="actual start")
    ax.plot([x[-1]], [y[-1]], "s", color="C3", label="actual end")
    _finish(ax, "x [m] (right)", "y [m] (forward)", equal=True)


def _draw_error(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Distance to the ground truth (closed loop: the reference) and heading error, log scale."""
    if truth is None or not len(truth.x):
        note(ax, NO_TRUTH)
        return
    idx, t = _t(results)
    p, what = roles.pose, "reference" if roles.follower else "ground truth"
    tx, ty, tth = truth_at(truth, results.time)
    errors = {f"distance to {what} [m]": np.hypot(results[f"{p}.x"] - tx, results[f"{p}.y"] - ty)}
    if _col(results, p, "theta"):
        dth = results[f"{p}.theta"] - tth
        errors["heading error [rad]"] = np.abs(np.arctan2(np.sin(dth), np.cos(dth)))
    ax.set_yscale("log")
    for (label, e), style in zip(errors.items(), ("-", "--")):
        e = e[idx]
        ax.plot(t, np.maximum(e, ERROR_FLOOR), style, label=f"{label}, end {e[-1]:.2e}")
    if all(np.max(e) <= ERROR_FLOOR for e in errors.values()):
        note(ax, f"every error at or below {ERROR_FLOOR:g} (round-off)")
    # plain "1e-04" tick labels: matplotlib's 10^-4 is mathtext, an eighth of the dashboard's
    # drawing time
    ax.yaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:.0e}"))
    ax.add_artist(MinorLogTicks(ax))
    _finish(ax, "t [s]", f"error (log scale, floor {ERROR_FLOOR:g})")


def _draw_belief(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The true path (the PoseIntegrator) and the robot's belief (the Odometry)."""
    idx = decimate_index(len(results.time))
    for inst, label, style in ((roles.pose, "true", dict(color="C0", lw=2.0)),
                               (roles.odometry, "believed (odometry)",
                                dict(color="C1", lw=1.2, ls="--"))):
        x, y = results[f"{inst}.x"], results[f"{inst}.y"]
        ax.plot(x[idx], y[idx], label=label, **style)
        ax.plot([x[-1]], [y[-1]], "s", color=style["color"], label=f"{label} end")
    ax.plot([results[f"{roles.pose}.x"][0]], [results[f"{roles.pose}.y"][0]], "o", color="C2",
            label="start")
    _finish(ax, "x [m] (right)", "y [m] (forward)", equal=True)


def _draw_recorded(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Each recorded pose (the scenario's `recorded:`) dashed, the simulated one solid."""
    idx = decimate_index(len(results.time))
    for pose, text in roles.recorded:
        rec = recorded_rows(text)
        ax.plot(rec["x"], rec["y"], "--", lw=2.5, alpha=0.6, label=f"{pose}: recorded")
        ax.plot(results[f"{pose}.x"][idx], results[f"{pose}.y"][idx], lw=1.2,
                label=f"{pose}: simulated")
    _finish(ax, "x [m] (right)", "y [m] (forward)", equal=True)


def _draw_recorded_error(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """|simulated - recorded position| at the recorded times, log scale."""
    for pose, text in roles.recorded:
        errors = position_errors(results, pose, recorded_rows(text))
        if errors is not None:
            ax.plot(errors["time"], np.maximum(errors["position"], 1e-12),
                    label=f"{pose}, end {errors['position'][-1]:.2e} m")
    ax.set_yscale("log")
    _finish(ax, "t [s]", "|position error| [m]")


def belief_drift(results: Results, roles: Roles) -> tuple[np.ndarray, np.ndarray]:
    """(distance, heading difference) between the believed and the true pose at every row."""
    b, p = roles.odometry, roles.pose
    distance = np.hypot(results[f"{b}.x"] - results[f"{p}.x"], results[f"{b}.y"] - results[f"{p}.y"])
    dth = np.zeros_like(distance)
    if _col(results, b, "theta") and _col(results, p, "theta"):
        dth = results[f"{b}.theta"] - results[f"{p}.theta"]
        dth = np.arctan2(np.sin(dth), np.cos(dth))
    return distance, dth


def _draw_drift(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """How far the belief is from the truth, against time: position (left axis), heading."""
    idx, t = _t(results)
    distance, dth = belief_drift(results, roles)
    ax.plot(t, distance[idx] * 1e3, color="C3",
            label=f"position: |believed - true| [mm], end {distance[-1] * 1e3:.3g}")
    ax.plot(t, dth[idx] * 1e3, color="C4", ls="--",
            label=f"heading: believed - true [mrad], end {dth[-1] * 1e3:.3g}")
    _finish(ax, "t [s]", "drift [mm] and [mrad]")


class MinorLogTicks(Artist):
    """The minor tick marks of a log y axis as one line of markers, in the places and look
    of matplotlib's own (the same pixels): those are a Tick of five artists each (72 on the
    seed circle's error panel), and making and drawing them took 40 % of drawing the panel."""

    def __init__(self, ax: Axes):
        super().__init__()
        rc = matplotlib.rcParams
        self._marks = Line2D([], [], linestyle="none", marker=TICKLEFT, color=rc["ytick.color"],
                             markersize=rc["ytick.minor.size"], clip_on=False,
                             markeredgewidth=rc["ytick.minor.width"],
                             transform=ax.get_yaxis_transform("tick1"))
        self._locator = ax.yaxis.get_minor_locator()      # bound to the axis: its view
        ax.yaxis.set_minor_locator(ticker.NullLocator())
        self.set_zorder(ax.yaxis.get_zorder() + 0.01)     # just after the axis' own ticks

    def draw(self, renderer) -> None:
        """Place the marks where the axis would have put its minor ticks: in view, not on a
        major tick (the axis's own rule, in log10 units with its tolerance)."""
        low, high = np.log10(sorted(self.axes.get_ylim()))
        locs = np.asarray(self._locator(), dtype=float)
        at = np.log10(locs)
        majors = np.log10(self.axes.yaxis.get_majorticklocs())
        tol = (high - low) * 1e-5
        keep = ((at >= low - tol) & (at <= high + tol)
                & ~np.isclose(at[:, None], majors[None, :], atol=tol, rtol=0).any(axis=1))
        self._marks.set_data(np.zeros(int(keep.sum())), locs[keep])
        self._marks.set_figure(self.figure)
        self._marks.draw(renderer)


# ------------------------------------------------- the drive train (docs/robot.md)
def motors_of(results: Results) -> list[str]:
    """The DCMotor instances of the run, wheel order: those that recorded V and V_clamp."""
    return sorted(n[:-2] for n in results.names
                  if n.endswith(".V") and f"{n[:-2]}.V_clamp" in results.names)


def bodies_of(results: Results) -> list[str]:
    """The MecanumDynamics instances: those that recorded slip1."""
    return [n[:-6] for n in results.names if n.endswith(".slip1")]


def _draw_motor_speeds(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Commanded (the inverse kinematics, wide and pale) against actual wheel speed."""
    idx, t = _t(results)
    block, wheels = wheels_of(roles)
    for k, (motor, (var, where)) in enumerate(zip(motors_of(results), wheels)):
        if cmd := _col(results, block, var):
            ax.plot(t, results[cmd][idx], "-", color=f"C{k}", lw=3, alpha=0.4,
                    label=f"{var} commanded")
        ax.plot(t, results[f"{motor}.w"][idx], "--", color=f"C{k}", label=f"{motor} {where}")
    _finish(ax, "t [s]", "wheel speed [rad/s]")


def _draw_against_limit(ax: Axes, results: Results, var: str, limit: str, label: str) -> None:
    idx, t = _t(results)
    for k, motor in enumerate(motors_of(results)):
        ax.plot(t, results[f"{motor}.{var}"][idx], color=f"C{k}", label=motor,
                **WHEEL_STYLES[k % len(WHEEL_STYLES)])
    clamp = max(float(np.max(results[f"{m}.{limit}"])) for m in motors_of(results))
    for sign in (1.0, -1.0):
        ax.axhline(sign * clamp, color="k", ls=":", lw=1.5,
                   label=f"±{limit} = {clamp:g}" if sign > 0 else None)
    _finish(ax, "t [s]", label)


def _draw_voltage(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    _draw_against_limit(ax, results, "V", "V_clamp", "armature voltage V [V]")


def _draw_current(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    _draw_against_limit(ax, results, "i", "i_clamp", "armature current i [A]")


def _draw_slip(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Each contact's sliding speed along its roller axis; the body's eps shaded."""
    idx, t = _t(results)
    for body in bodies_of(results):
        for (var, where), style in zip(WHEELS, WHEEL_STYLES):
            k = var[1]
            ax.plot(t, results[f"{body}.slip{k}"][idx], label=f"slip{k} {where}", **style)
        if f"{body}.eps" in results.names:
            eps = results[f"{body}.eps"][idx]
            ax.fill_between(t, -eps, eps, color="0.85", zorder=1, label="|slip| < eps")
    _finish(ax, "t [s]", "slip along the roller axis [m/s]")


# --------------------------------------------------------------------------- the table
Drawer = Callable[[Axes, Results, Roles, Truth | None], None]


@dataclass(frozen=True)
class Panel:
    title: str
    needs: Callable[[Results, Roles], bool]      # True when the panel has something to draw
    draw: Drawer
    truth: bool = False     # it shows the ground truth: drawn once that exists (plots.Draft)


def _has_pose(r: Results, ro: Roles) -> bool:
    return bool(_col(r, ro.pose, "x") and _col(r, ro.pose, "y"))


def _has_belief(r: Results, ro: Roles) -> bool:
    return bool(_col(r, ro.odometry, "x") and _col(r, ro.odometry, "y"))


def _has_recorded(r: Results, ro: Roles) -> bool:
    return any(_col(r, pose, "x") and _col(r, pose, "y") for pose, _ in ro.recorded)


def _has_inputs(r: Results, ro: Roles) -> bool:
    block, channels = inputs(ro)
    return any(_col(r, block, v) for v in channels)


# In this order on the dashboard, two a row: the path and its error first, the ICR last.
PANELS: dict[str, Panel] = {
    "path": Panel("Path: simulated vs ground truth",
                  lambda r, ro: _has_pose(r, ro) and not ro.follower, _draw_path, truth=True),
    "error": Panel("Error vs ground truth",
                   lambda r, ro: _has_pose(r, ro) and not ro.follower and _has_inputs(r, ro),
                   _draw_error, truth=True),
    # only when a PathFollower closes the loop (its reference is the ground truth)
    "tracking": Panel("Reference path vs actual path",
                      lambda r, ro: bool(ro.follower) and _has_pose(r, ro), _draw_tracking_path,
                      truth=True),
    "tracking_error": Panel("Tracking error",
                            lambda r, ro: bool(ro.follower) and _has_pose(r, ro), _draw_error,
                            truth=True),
    # only with an Odometry beside the pose (docs/robot.md): what the robot believes
    "belief": Panel("True path vs believed path (odometry)",
                    lambda r, ro: _has_pose(r, ro) and _has_belief(r, ro), _draw_belief),
    "drift": Panel("Drift of the belief against time",
                   lambda r, ro: _has_pose(r, ro) and _has_belief(r, ro), _draw_drift),
    # only when the scenario names a recording (`recorded:`, docs/bags.md): recorded.png's two
    "recorded_path": Panel("Recorded against simulated", _has_recorded, _draw_recorded),
    "recorded_error": Panel("Simulated minus recorded", _has_recorded, _draw_recorded_error),
    "velocities": Panel("Input velocities", _has_inputs, _draw_velocities),
    "vy": Panel("Vy(t)", lambda r, ro: bool(_col(r, ro.source, "vy")), _draw_vy),
    "wheels": Panel("Wheel speeds",
                    lambda r, ro: any(_col(r, wheels_of(ro)[0], w) for w, _ in WHEELS),
                    _draw_wheels),
    "twist": Panel("Commanded vs reconstructed twist",
                   lambda r, ro: any(_col(r, forward_of(ro), v) for v in TWIST), _draw_twist),
    "theta": Panel("Heading θ(t)", lambda r, ro: bool(_col(r, ro.pose, "theta")), _draw_theta,
                   truth=True),
    # a drive train (DCMotor, MecanumDynamics): what the motors and the floor allowed
    "motor_speeds": Panel("Wheel speed: commanded vs actual", lambda r, ro: bool(motors_of(r)),
                          _draw_motor_speeds),
    "voltage": Panel("Motor voltage vs its clamp", lambda r, ro: bool(motors_of(r)),
                     _draw_voltage),
    "current": Panel("Motor current vs its limit", lambda r, ro: bool(motors_of(r)),
                     _draw_current),
    "slip": Panel("Slip per wheel", lambda r, ro: bool(bodies_of(r)), _draw_slip),
    "icr": Panel("Instantaneous centre of rotation (world frame)",
                 lambda r, ro: _has_pose(r, ro) and all(_col(r, ro.forward, v)
                                                        for v in ("icr_x", "icr_y", "has_icr")),
                 _draw_icr),
}


def panel_title(key: str, roles: Roles) -> str:
    """The panel's title for this graph: world-frame inputs, steering inputs and a twist with
    nothing commanded say so."""
    if roles.frame and key == "velocities":
        return "Input velocities (world frame)"
    if roles.frame and key == "vy":
        return "vY(t) (world frame)"
    if key == "velocities" and roles.source is None:
        return "Input speed and steering angle"
    if key == "twist" and commander(roles) is None:
        return "Body twist"
    return PANELS[key].title


def available_panels(results: Results, roles: Roles) -> list[str]:
    """Keys of the panels that have data, in PANELS order (none for an empty run)."""
    if len(results.time) == 0:
        return []
    return [key for key, panel in PANELS.items() if panel.needs(results, roles)]
