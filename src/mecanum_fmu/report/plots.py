"""The original study's figures as PNGs, drawn without pyplot (docs/spec.md, The original
study and Expected results).

The panels themselves (one drawing function each, taking an Axes) are in panels.py;
`build_figures` gives every panel its own figure, `build_dashboard` puts them all in one, two a
row (a panel never crosses the middle: report.halves draws the columns apart). `write_plots` draws the dashboard once and saves
it and, cut from the same rendered pixels, one PNG per panel (drawing every panel twice and laying
out seven figures cost more than the simulation). A panel with nothing to draw (its role is None
or its columns were not recorded) is left out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .truth import Truth
from ..models.catalog import Roles
from .panels import (MAX_POINTS, PANELS, Panel, available_panels,  # noqa: F401  (the API)
                     decimate_index, icr_world, panel_title)
from ..results import Results

_icr_world = icr_world            # the name the tests of the chassis and modes use
PANEL_SIZE = (6.0, 4.5)           # inches
DASHBOARD_SIZE = (12.0, 10.0)     # the least size; more rows of panels make it taller
ROW_HEIGHT = 3.4                  # inches per row of panels (two panels a row)
DPI = 100
MARGINS = dict(left=0.07, right=0.98, wspace=0.22)   # fixed: no layout engine on the run path
TITLE_ROOM = 0.4                  # inches above a dashboard panel for its title
LABEL_ROOM = 0.55                 # inches below it for tick labels and the x label
SUPTITLE_FROM_TOP = 0.2          # inches from the top edge to the top of the dashboard title
PAD = 6                           # pixels kept around a panel cut from the dashboard
# Text without FreeType's hinting: drawing the dashboard takes a quarter less time (its text is
# most of that), and at 100 dpi the glyphs look the same to the eye.
DRAW_RC = {"text.hinting": "no_hinting"}


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
        name = panel_title(key, roles)
        ax.set_title(f"{title}: {name}" if title else name)
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
        ax.set_title(panel_title(key, roles), y=1.0)      # a fixed y: no search for a free place
    # a fixed distance from the top edge (matplotlib's default is a fraction of the height),
    # clear of the first row's cells however tall the dashboard is
    fig.suptitle(_suptitle(results, keys, title), y=1 - SUPTITLE_FROM_TOP / height)
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
