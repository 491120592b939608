"""The original study's figures as PNGs, drawn without pyplot (docs/spec.md, The original
study and Expected results).

One drawing function per panel, each taking an Axes; `build_figures` gives every panel its own
figure, `build_dashboard` puts them all in one. `write_plots` draws the dashboard once and saves
it and, cut from the same rendered pixels, one PNG per panel (drawing every panel twice and laying
out seven figures cost more than the simulation). A panel with nothing to draw (its role is None
or its columns were not recorded) is left out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .truth import Truth
from ..models.catalog import Roles
from ..results import Results

MAX_POINTS = 5000                 # more rows than this are decimated before drawing
PANEL_SIZE = (6.0, 4.5)           # inches
DASHBOARD_SIZE = (12.0, 10.0)     # the least size; more rows of panels make it taller
ROW_HEIGHT = 3.4                  # inches per row of panels (two panels a row)
DPI = 100
MARGINS = dict(left=0.07, right=0.98, wspace=0.22)   # fixed: no layout engine on the run path
TITLE_ROOM = 0.4                  # inches above a dashboard panel for its title
LABEL_ROOM = 0.55                 # inches below it for tick labels and the x label
PAD = 6                           # pixels kept around a panel cut from the dashboard
# Text without FreeType's hinting: drawing the dashboard takes a quarter less time (its text is
# most of that), and at 100 dpi the glyphs look the same to the eye.
DRAW_RC = {"text.hinting": "no_hinting"}
TWIST = ("vx", "vy", "w")
WHEELS = (("w1", "front-right"), ("w2", "front-left"), ("w3", "rear-left"), ("w4", "rear-right"))


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


def _draw_velocities(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Commanded twist vx, vy, w against time (the source's outputs)."""
    idx, t = _t(results)
    for var in TWIST:
        if name := _col(results, roles.source, var):
            ax.plot(t, results[name][idx], label=var)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vx, vy [m/s]; w [rad/s]")
    ax.grid(True)
    ax.legend()


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
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m] (right)")
    ax.set_ylabel("y [m] (forward)")
    ax.grid(True)
    ax.legend()


def _draw_vy(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The commanded forward speed vy against time."""
    idx, t = _t(results)
    ax.plot(t, results[f"{roles.source}.vy"][idx], label="vy")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vy [m/s]")
    ax.grid(True)
    ax.legend()


def _draw_wheels(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """The four wheel speeds from inverse kinematics."""
    idx, t = _t(results)
    # Rear wheels dashed: with w = 0, w1 = w3 and w2 = w4 (docs/spec.md, The seed scenario)
    # and the lines overlap.
    for i, (var, where) in enumerate(WHEELS):
        if name := _col(results, roles.inverse, var):
            ax.plot(t, results[name][idx], "--" if i >= 2 else "-", label=f"{var} {where}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel speed [rad/s]")
    ax.grid(True)
    ax.legend()


def _draw_twist(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Commanded (solid) against reconstructed (dashed) twist."""
    idx, t = _t(results)
    for i, var in enumerate(TWIST):
        cmd, rec = _col(results, roles.source, var), _col(results, roles.forward, var)
        if cmd:
            ax.plot(t, results[cmd][idx], "-", color=f"C{i}", lw=3, alpha=0.5,
                    label=f"{var} commanded")
        if rec:
            ax.plot(t, results[rec][idx], "--", color=f"C{i}", label=f"{var} reconstructed")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vx, vy [m/s]; w [rad/s]")
    ax.grid(True)
    ax.legend()


def _icr_world(results: Results, roles: Roles) -> tuple[np.ndarray, np.ndarray]:
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
    """Instantaneous centre of rotation in the world frame (where it exists) over the path."""
    x, y = results[f"{roles.pose}.x"], results[f"{roles.pose}.y"]
    idx = decimate_index(len(results.time))
    ax.plot(x[idx], y[idx], color="C0", lw=1.2, label="path")
    wx, wy = _icr_world(results, roles)
    # Near w = 0 the ICR runs off to infinity: show only what lies within one path size
    # (at least 0.5 m) of the path, so the path stays readable.
    span = max(float(np.ptp(x)), float(np.ptp(y)), 0.5)
    near = ((wx >= x.min() - span) & (wx <= x.max() + span)
            & (wy >= y.min() - span) & (wy <= y.max() + span))
    wx, wy = wx[near], wy[near]
    if len(wx):
        keep = decimate_index(len(wx))
        ax.plot(wx[keep], wy[keep], ".", color="C3", ms=3, label="ICR")
    else:
        ax.plot([], [], ".", color="C3", label="ICR (none: w = 0)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m] (right)")
    ax.set_ylabel("y [m] (forward)")
    ax.grid(True)
    ax.legend()


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
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m] (right)")
    ax.set_ylabel("y [m] (forward)")
    ax.grid(True)
    ax.legend()


def _draw_tracking_error(ax: Axes, results: Results, roles: Roles, truth: Truth | None) -> None:
    """Closed loop: distance to the reference position and heading error, log scale."""
    if truth is None or not len(truth.x):
        return
    idx, t = _t(results)
    p = roles.pose
    dist = np.hypot(results[f"{p}.x"] - truth.x, results[f"{p}.y"] - truth.y)
    # exact zeros (the start, a heading that never leaves its reference) have no log: not drawn
    ax.semilogy(t, np.where(dist[idx] > 0, dist[idx], np.nan), label="position error [m]")
    if _col(results, p, "theta"):
        dth = results[f"{p}.theta"] - truth.theta
        dth = np.abs(np.arctan2(np.sin(dth), np.cos(dth)))
        ax.semilogy(t, np.where(dth[idx] > 0, dth[idx], np.nan), label="heading error [rad]")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tracking error")
    ax.grid(True, which="both")
    ax.legend()


Drawer = Callable[[Axes, Results, Roles, Truth | None], None]


@dataclass(frozen=True)
class Panel:
    title: str
    needs: Callable[[Results, Roles], bool]      # True when the panel has something to draw
    draw: Drawer


PANELS: dict[str, Panel] = {
    "velocities": Panel("Input velocities",
                        lambda r, ro: any(_col(r, ro.source, v) for v in TWIST), _draw_velocities),
    "path": Panel("Path: simulated vs ground truth",
                  lambda r, ro: bool(_col(r, ro.pose, "x") and _col(r, ro.pose, "y")), _draw_path),
    "vy": Panel("Vy(t)", lambda r, ro: bool(_col(r, ro.source, "vy")), _draw_vy),
    "wheels": Panel("Wheel speeds",
                    lambda r, ro: any(_col(r, ro.inverse, w) for w, _ in WHEELS), _draw_wheels),
    "twist": Panel("Commanded vs reconstructed twist",
                   lambda r, ro: any(_col(r, ro.source, v) and _col(r, ro.forward, v)
                                     for v in TWIST), _draw_twist),
    "icr": Panel("Instantaneous centre of rotation (world frame)",
                 lambda r, ro: bool(_col(r, ro.pose, "x") and _col(r, ro.pose, "y")
                                    and all(_col(r, ro.forward, v)
                                            for v in ("icr_x", "icr_y", "has_icr"))), _draw_icr),
    # only when a PathFollower closes the loop (its reference is the ground truth)
    "tracking": Panel("Reference path vs actual path",
                      lambda r, ro: bool(ro.follower and _col(r, ro.pose, "x")
                                         and _col(r, ro.pose, "y")), _draw_tracking_path),
    "tracking_error": Panel("Tracking error",
                            lambda r, ro: bool(ro.follower and _col(r, ro.pose, "x")
                                               and _col(r, ro.pose, "y")), _draw_tracking_error),
}


def available_panels(results: Results, roles: Roles) -> list[str]:
    """Keys of the panels that have data, in PANELS order (none for an empty run)."""
    if len(results.time) == 0:
        return []
    return [key for key, panel in PANELS.items() if panel.needs(results, roles)]


def new_figure(size: tuple[float, float], layout: str | None = "constrained",
               dpi: int = DPI) -> Figure:
    """A figure on the Agg canvas (no pyplot): the project's one way to make one."""
    fig = Figure(figsize=size, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def build_figures(results: Results, roles: Roles, truth: Truth | None,
                  title: str = "") -> dict[str, Figure]:
    """One figure per available panel, keyed by panel name."""
    figures: dict[str, Figure] = {}
    for key in available_panels(results, roles):
        fig = new_figure(PANEL_SIZE)
        ax = fig.add_subplot()
        PANELS[key].draw(ax, results, roles, truth)
        ax.set_title(f"{title}: {PANELS[key].title}" if title else PANELS[key].title)
        figures[key] = fig
    return figures


def _margins(height: float, rows: int) -> dict[str, float]:
    """Fixed subplot margins for `rows` rows in a dashboard `height` inches tall: room on top
    for the title, below for the last row's labels, between rows for both."""
    top, bottom, gap = 0.8, LABEL_ROOM, TITLE_ROOM + LABEL_ROOM
    axes_height = (height - top - bottom - (rows - 1) * gap) / rows
    return dict(MARGINS, top=1 - top / height, bottom=bottom / height, hspace=gap / axes_height)


@dataclass
class Frame:
    """A dashboard without data: the axes of `keys` with their titles, and the figure title."""
    keys: list[str]
    figure: Figure


def dashboard_frame(results: Results, roles: Roles, title: str = "") -> Frame:
    """The frame for `results`' panels. It needs only the column names and the run's settings,
    so the plot worker can build (and draw once) the frame of a run before the run ends."""
    keys = available_panels(results, roles)
    rows = max(1, math.ceil(len(keys) / 2))
    height = max(DASHBOARD_SIZE[1], ROW_HEIGHT * rows)
    fig = new_figure((DASHBOARD_SIZE[0], height), layout=None)
    fig.subplots_adjust(**_margins(height, rows))
    for i, key in enumerate(keys):
        ax = fig.add_subplot(rows, 2, i + 1)
        ax.set_title(PANELS[key].title, y=1.0)      # a fixed y: no search for a free place
    fig.suptitle(_suptitle(results, keys, title))
    return Frame(keys, fig)


def _suptitle(results: Results, keys: list[str], title: str) -> str:
    head = f"{title} - " if title else ""
    return (f"{head}{results.master}, step {results.step_size:g} s"
            + ("" if keys else " (nothing to plot)"))


def build_dashboard(results: Results, roles: Roles, truth: Truth | None,
                    title: str = "", frame: Frame | None = None) -> Figure:
    """All available panels in one figure, two columns, fixed margins; in `frame` when it was
    made for the same panels and title."""
    keys = available_panels(results, roles)
    if frame is None or frame.keys != keys or frame.figure.get_suptitle() != _suptitle(
            results, keys, title):
        frame = dashboard_frame(results, roles, title)
    for ax, key in zip(frame.figure.axes, frame.keys):
        PANELS[key].draw(ax, results, roles, truth)
    return frame.figure


def panel_boxes(fig: Figure, pixels: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Pixel boxes (top, bottom, left, right; rows from the top) of each panel of a drawn
    dashboard: its grid cell (the axes plus the fixed room around it for its title, labels and
    tick labels, so neighbours never share pixels) trimmed to what is drawn in it, plus PAD."""
    height, width = pixels.shape[:2]
    ink = pixels.view(np.uint32)[..., 0] != np.uint32(0xFFFFFFFF)   # not opaque white
    boxes = []
    for ax in fig.axes:
        pos = ax.get_position()                       # figure fraction, y up
        top = int(height * (1 - pos.y1) - TITLE_ROOM * DPI)
        bottom = int(height * (1 - pos.y0) + LABEL_ROOM * DPI)
        left = 0 if pos.x0 < 0.5 else int(width / 2)
        right = int(width / 2) if pos.x0 < 0.5 else width
        top, bottom = max(top, 0), min(bottom, height)
        cell = ink[top:bottom, left:right]
        rows, cols = np.flatnonzero(cell.any(axis=1)), np.flatnonzero(cell.any(axis=0))
        if len(rows) == 0:
            boxes.append((top, bottom, left, right))
            continue
        boxes.append((max(top + rows[0] - PAD, top), min(top + rows[-1] + 1 + PAD, bottom),
                      max(left + cols[0] - PAD, left), min(left + cols[-1] + 1 + PAD, right)))
    return boxes


def _save_png(pixels: np.ndarray, path: Path) -> None:
    """At zlib level 1: half the default level's time for files about 5 % larger."""
    from PIL import Image      # matplotlib's own PNG writer
    from PIL.PngImagePlugin import PngInfo
    info = PngInfo()
    info.add_text("Software", "mecanum_fmu (matplotlib)")
    Image.fromarray(pixels).save(
        path, format="png", compress_level=1, pnginfo=info, dpi=(DPI, DPI))


def write_plots(results: Results, roles: Roles, truth: Truth | None, out_dir: Path | str,
                title: str = "", frame: Frame | None = None) -> list[Path]:
    """Write dashboard.png and <panel>.png for each available panel; return the paths.

    The dashboard is drawn once (in `frame` if it fits); each panel's PNG is its part of the
    dashboard's pixels."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    keys = available_panels(results, roles)
    with matplotlib.rc_context(DRAW_RC):
        fig = build_dashboard(results, roles, truth, title, frame)
        _draw_and_save(fig, keys, out_dir)
    return [out_dir / "dashboard.png"] + [out_dir / f"{k}.png" for k in keys]


def _draw_and_save(fig: Figure, keys: list[str], out_dir: Path) -> None:
    """Draw once; each panel's PNG is cut from the dashboard's pixels."""
    fig.canvas.draw()
    pixels = np.asarray(fig.canvas.buffer_rgba())
    for key, (top, bottom, left, right) in zip(keys, panel_boxes(fig, pixels)):
        _save_png(pixels[top:bottom, left:right, :3], out_dir / f"{key}.png")
    _save_png(pixels[..., :3], out_dir / "dashboard.png")     # opaque: no alpha channel
