"""`run --animate`: the chassis driving along its path, as an animated GIF (no pyplot).

Each frame draws, in the world frame (docs/spec.md, Pose integration), the chassis as a
2L x 2W rectangle (L along body X, left-right; W along body Y, front-rear) at the recorded pose,
its four wheels with an arrow along the body +Y of each wheel scaled by that wheel's rim speed
R*wi, the path so far and the ground-truth path; a legend below the view names each wheel's
arrow colour. Frames are decimated to at most `max_frames`,
played at FPS.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon

from .evaluation import Evaluation
from .truth import Truth
from ..models.catalog import Roles
from ..results import Results
from .panels import WHEELS
from .plots import new_figure

FPS = 20
MAX_FRAMES = 100
FIG_SIZE = (5.0, 5.8)           # inches: the square view and the legend below it
DPI = 80                        # -> 400 x 464 pixels
WHEEL_POS = ((1, 1), (-1, 1), (-1, -1), (1, -1))   # (sign of X, sign of Y) of wheels 1..4
WHEEL_COLORS = ("C3", "C1", "C2", "C4")
ARROWS = "arrows: wheel rim speed R·wi, along body +y"
MOVING = "moving"               # the gid of the artists each frame draws again


def frame_indices(n: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """At most max_frames row indices spread evenly over n rows, first and last included."""
    if n <= 0:
        return np.arange(0)
    count = max(1, min(n, int(max_frames)))
    if count == 1:
        return np.array([n - 1])
    return np.unique(np.round(np.linspace(0, n - 1, count)).astype(int))


def _to_world(points: np.ndarray, x: float, y: float, theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.column_stack((x + c * points[:, 0] - s * points[:, 1],
                            y + s * points[:, 0] + c * points[:, 1]))


def write_animation(results: Results, evaluation: Evaluation, path: Path | str,
                    max_frames: int = MAX_FRAMES) -> Path:
    """Write the animated GIF of the run and its Evaluation (roles, truth, the chassis'
    geometry) to path and return it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, update, n = build_scene(results, evaluation.roles, evaluation.truth,
                                 evaluation.geometry)
    frames = _frames(fig, update, frame_indices(n, max_frames))
    fig.clear()
    frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:],
                   duration=int(1000 / FPS), loop=0)
    return path


def _frames(fig, update, indices: np.ndarray) -> list:
    """The frames as images (blitting): the layout and the still parts (axes, ticks, grid,
    legend, ground truth) are drawn once; each frame restores them and draws only the
    artists that move (_scene gives them the gid MOVING), in their z-order."""
    from PIL import Image          # Pillow: matplotlib's own dependency
    update(int(indices[0]))
    canvas = fig.canvas
    canvas.draw()                  # the constrained layout, with every artist in it: it
    canvas.draw()                  # settles on the second draw
    fig.set_layout_engine("none")  # kept for every frame
    moving = sorted((a for ax in fig.axes for a in ax.get_children() if a.get_gid() == MOVING),
                    key=lambda a: a.get_zorder())
    for artist in moving:
        artist.set_animated(True)
    canvas.draw()
    still = canvas.copy_from_bbox(fig.bbox)
    frames = []
    for i in indices:
        canvas.restore_region(still)
        update(int(i))
        for artist in moving:
            fig.draw_artist(artist)
        # opaque: RGB, which Pillow turns into a GIF's palette better (as PillowWriter does)
        frames.append(Image.fromarray(np.array(canvas.buffer_rgba())).convert("RGB"))
    return frames


def build_scene(results: Results, roles: Roles, truth: Truth | None,
                params: Mapping[str, float]):
    """The animation's figure, update(i) that shows row i, and the number of rows. params:
    alpha, L, W, R of the kinematics (the Evaluation's geometry, models.modes.geometry_of)."""
    x, y, theta, rim = _track(results, roles, params["R"])
    fig = new_figure(FIG_SIZE, dpi=DPI)
    ax = fig.add_subplot()
    _set_view(ax, x, y, truth, params["L"], params["W"])
    update = _scene(ax, results, (x, y, theta, rim), truth, params)
    _legend(ax, roles.inverse is not None)
    return fig, update, len(x)


def _legend(ax, wheels: bool) -> None:
    """Below the view: the paths, and what each wheel's arrow is (its colour, the wheel)."""
    handles, labels = ax.get_legend_handles_labels()
    if wheels:
        for (var, where), color in zip(WHEELS, WHEEL_COLORS):
            handles.append(Line2D([], [], color=color, lw=2.5))
            labels.append(f"{var} {where}")
    ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3,
              fontsize=8, title=ARROWS if wheels else None, title_fontsize=8, frameon=False)


def _track(results: Results, roles: Roles, R: float):
    """x, y, theta of the pose and the four wheels' rim speeds R*wi [m/s], per recorded row."""
    n = len(results.time)
    pose = roles.pose
    cols = [f"{pose}.{k}" for k in ("x", "y", "theta")]
    if pose is None or n == 0 or not all(c in results.names for c in cols[:2]):
        raise ValueError("nothing to animate: the run has no recorded pose (x, y)")
    x, y = results[cols[0]], results[cols[1]]
    theta = results[cols[2]] if cols[2] in results.names else np.zeros(n)
    wheels = np.zeros((n, 4))
    for j in range(4):
        name = f"{roles.inverse}.w{j + 1}"
        if roles.inverse is not None and name in results.names:
            wheels[:, j] = results[name]
    return x, y, theta, R * wheels


def _set_view(ax, x, y, truth: Truth | None, L: float, W: float) -> None:
    """A fixed square view: everything the car and the ground truth visit, plus the chassis
    and its arrows."""
    xs, ys = [x], [y]
    if truth is not None and len(truth.x):
        xs.append(truth.x)
        ys.append(truth.y)
        ax.plot(truth.x, truth.y, color="0.75", lw=3, label="ground truth")
    reach = math.hypot(L, W) + 1.5 * W + 0.05
    lo_x, hi_x = min(map(np.min, xs)) - reach, max(map(np.max, xs)) + reach
    lo_y, hi_y = min(map(np.min, ys)) - reach, max(map(np.max, ys)) + reach
    half = max(hi_x - lo_x, hi_y - lo_y) / 2
    cx, cy = (lo_x + hi_x) / 2, (lo_y + hi_y) / 2
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - half, cy + half)
    ax.set_aspect("equal")
    ax.grid(True, lw=0.5)
    ax.set_xlabel("x [m] (right)")
    ax.set_ylabel("y [m] (forward)")


def _scene(ax, results: Results, track, truth: Truth | None, params: Mapping):
    """Add the path, chassis, wheels and arrows to ax; return update(i) for frame i."""
    x, y, theta, rim = track
    L, W, R = params["L"], params["W"], params["R"]
    peak = float(np.max(np.abs(rim))) if rim.size else 0.0
    scale = 1.5 * W / peak if peak > 0 else 0.0               # fastest wheel: arrow 1.5 W long
    trail, = ax.plot([], [], color="C0", lw=1.2, label="path")
    body_pts = np.array([[L, W], [-L, W], [-L, -W], [L, -W]])
    body = Polygon(body_pts, closed=True, facecolor="C0", alpha=0.25, edgecolor="C0", lw=1.5)
    ax.add_patch(body)
    nose_pts = np.array([[0.0, 0.0], [0.0, W]])              # centre -> front edge: heading
    nose, = ax.plot([], [], color="C0", lw=1.5)
    wl, ww = 0.5 * R, 0.25 * min(L, W)                        # wheel drawn 2*wl long, 2*ww wide
    wheel_shape = np.array([[ww, wl], [-ww, wl], [-ww, -wl], [ww, -wl]])
    wheel_patches = [ax.add_patch(Polygon(wheel_shape, closed=True, facecolor="0.3",
                                          edgecolor="k", lw=0.5)) for _ in WHEEL_POS]
    centres = np.array([[sx * L, sy * W] for sx, sy in WHEEL_POS])
    arrows = ax.quiver(np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4),
                       color=WHEEL_COLORS, angles="xy", scale_units="xy", scale=1.0,
                       width=0.008, zorder=5)
    title = ax.set_title("")
    for artist in (trail, body, nose, *wheel_patches, arrows, title):
        artist.set_gid(MOVING)              # drawn per frame over the still parts (_frames)

    def update(i: int) -> None:
        px, py, th = float(x[i]), float(y[i]), float(theta[i])
        body.set_xy(_to_world(body_pts, px, py, th))
        nose.set_data(*_to_world(nose_pts, px, py, th).T)
        trail.set_data(x[:i + 1], y[:i + 1])
        for j, patch in enumerate(wheel_patches):
            patch.set_xy(_to_world(wheel_shape + centres[j], px, py, th))
        c, s = math.cos(th), math.sin(th)
        length = scale * rim[i]                               # along body +Y of each wheel
        arrows.set_offsets(_to_world(centres, px, py, th))
        arrows.set_UVC(-s * length, c * length)
        title.set_text(f"t = {results.time[i]:.2f} s")
    return update
