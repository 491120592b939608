"""The original study's figures as PNGs, drawn without pyplot (docs/spec.md, The original
study and Expected results).

The panels themselves (one drawing function each, taking an Axes) are in panels.py;
`build_figures` gives every panel its own figure, `build_dashboard` puts them all in one, two a
row, each in a cell of its own (no panel's pixels cross another's). `write_plots` draws the
dashboard once and saves it and, cut from the same rendered pixels, one PNG per panel (drawing
every panel twice and laying out seven figures cost more than the simulation). It draws in two
stages that the plot worker runs at two times: `draft_dashboard`, every panel but those of the
ground truth, as soon as the results exist; `finish_dashboard`, the truth's panels into their
empty cells, once the truth exists. A panel with nothing to draw (its role is None or its
columns were not recorded) is left out.
"""
from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.axes import Axes
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
MAJOR_TICKS = 10                  # ticks made with the frame, per axis (more are made as needed)
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
        if PANELS[key].truth:           # drawn after the truth: make its ticks now
            _make_ticks(ax)
    # a fixed distance from the top edge (matplotlib's default is a fraction of the height),
    # clear of the first row's cells however tall the dashboard is
    fig.suptitle(_suptitle(results, keys, title), y=1 - SUPTITLE_FROM_TOP / height)
    return Frame(keys, fig)


def _make_ticks(ax: Axes) -> None:
    """Make the ticks a panel will need now: an axis makes each tick (five artists) when a
    draw first needs it, a tenth of drawing a panel."""
    ax.xaxis.get_major_ticks(MAJOR_TICKS)
    ax.yaxis.get_major_ticks(MAJOR_TICKS)


def _suptitle(results: Results, keys: list[str], title: str) -> str:
    head = f"{title} - " if title else ""
    return (f"{head}{results.master}, step {results.step_size:g} s"
            + ("" if keys else " (nothing to plot)"))


def _fitting(frame: Frame | None, results: Results, roles: Roles, title: str) -> Frame:
    """`frame` when it was made for these panels and this title, else a new one."""
    keys = available_panels(results, roles)
    if frame is None or frame.keys != keys or frame.figure.get_suptitle() != _suptitle(
            results, keys, title):
        frame = dashboard_frame(results, roles, title)
    return frame


def build_dashboard(results: Results, roles: Roles, truth: Truth | None,
                    title: str = "", frame: Frame | None = None) -> Figure:
    """All available panels in one figure, two columns, fixed margins; in `frame` when it was
    made for the same panels and title."""
    frame = _fitting(frame, results, roles, title)
    for ax, key in zip(frame.figure.axes, frame.keys):
        PANELS[key].draw(ax, results, roles, truth)
    return frame.figure


def panel_boxes(axes: list[Axes], pixels: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Pixel boxes (top, bottom, left, right; rows from the top) of each of the dashboard's
    `axes` as drawn: its grid cell (the axes plus the fixed room around it for its title,
    labels and tick labels, so neighbours never share pixels) trimmed to what is drawn in it,
    plus PAD."""
    height, width = pixels.shape[:2]
    ink = pixels.view(np.uint32)[..., 0] != np.uint32(0xFFFFFFFF)   # not opaque white
    boxes = []
    for ax in axes:
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


def _png(pixels: np.ndarray) -> bytes:
    """PNG bytes at zlib level 1: half the default level's time for files about 5 % larger."""
    from PIL import Image      # matplotlib's own PNG writer
    from PIL.PngImagePlugin import PngInfo
    info = PngInfo()
    info.add_text("Software", "mecanum_fmu (matplotlib)")
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(
        buffer, format="png", compress_level=1, pnginfo=info, dpi=(DPI, DPI))
    return buffer.getvalue()


@dataclass
class Draft:
    """A dashboard drawn but for the panels that show the ground truth (hidden until it
    exists), with the PNG bytes of the panels already final."""
    results: Results
    roles: Roles
    frame: Frame
    pngs: dict[str, bytes]


def draft_dashboard(results: Results, roles: Roles, title: str = "",
                    frame: Frame | None = None) -> Draft:
    """Stage one, as soon as the results exist (the plot worker draws it while the run
    integrates its ground truth): every panel that needs no truth drawn and cut out, the
    others hidden. Drawn in `frame` if it fits."""
    frame = _fitting(frame, results, roles, title)
    done = [(ax, key) for ax, key in zip(frame.figure.axes, frame.keys) if not PANELS[key].truth]
    with matplotlib.rc_context(DRAW_RC):
        for ax, key in zip(frame.figure.axes, frame.keys):
            if PANELS[key].truth:
                ax.set_visible(False)
            else:
                PANELS[key].draw(ax, results, roles, None)
        frame.figure.canvas.draw()
    return Draft(results, roles, frame, _cut(frame.figure, done))


def finish_dashboard(draft: Draft, truth: Truth | None) -> dict[str, bytes]:
    """Stage two: the truth's panels drawn into the draft, each in its own cell of the canvas
    (no panel crosses another's, so the pixels are those of one whole draw). The PNG bytes by
    name: the dashboard, then each panel in order."""
    fig, keys = draft.frame.figure, draft.frame.keys
    later = [(ax, key) for ax, key in zip(fig.axes, keys) if PANELS[key].truth]
    with matplotlib.rc_context(DRAW_RC):
        for ax, key in later:
            PANELS[key].draw(ax, draft.results, draft.roles, truth)
            ax.set_visible(True)
            fig.draw_artist(ax)
    pngs = draft.pngs | _cut(fig, later)
    pixels = np.asarray(fig.canvas.buffer_rgba())
    return {"dashboard": _png(pixels[..., :3]), **{key: pngs[key] for key in keys}}  # opaque


def _cut(fig: Figure, panels: list[tuple[Axes, str]]) -> dict[str, bytes]:
    """The PNG bytes of each of `panels` (axes, key), cut from the drawn canvas."""
    pixels = np.asarray(fig.canvas.buffer_rgba())
    boxes = panel_boxes([ax for ax, _ in panels], pixels)
    return {key: _png(pixels[top:bottom, left:right, :3])
            for (_, key), (top, bottom, left, right) in zip(panels, boxes)}


def save_pngs(pngs: dict[str, bytes], out_dir: Path | str) -> list[Path]:
    """Write <name>.png for each of `pngs` into out_dir (the first, the dashboard, last);
    the paths in the order given."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}.png" for name in pngs]
    for path, data in reversed(list(zip(paths, pngs.values()))):
        path.write_bytes(data)
    return paths


def write_plots(results: Results, roles: Roles, truth: Truth | None, out_dir: Path | str,
                title: str = "", frame: Frame | None = None) -> list[Path]:
    """Write dashboard.png and <panel>.png for each available panel; return the paths.

    The dashboard is drawn once (in `frame` if it fits); each panel's PNG is its part of the
    dashboard's pixels."""
    return save_pngs(finish_dashboard(draft_dashboard(results, roles, title, frame), truth),
                     out_dir)
