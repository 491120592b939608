"""Make the pictures in docs/img:

- one dashboard of each kind (DASHBOARDS: open loop, closed loop, omni field-oriented, car-like,
  a piecewise mode) and the closed-loop figure eight's two tracking panels;
- modes.png (every scenario in scenarios/modes/) and circle.gif (the seed study, animated);
- the sweep figures (SWEEPS: the 1000-sample wheel_tolerance, and a two-point grid of it that
  shows a colour, a ground truth and a mean per grid point).

    .venv/bin/python docs/make_gallery.py [dashboards] [modes] [sweeps]   # default: all
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mecanum_fmu import runner  # noqa: E402
from mecanum_fmu.report.animation import write_animation  # noqa: E402
from mecanum_fmu.models.modes import graph_geometry  # noqa: E402
from mecanum_fmu.sweep.cluster import run_sweep  # noqa: E402

MODES = ("forward", "backward", "left", "right", "diagonal", "spin_ccw", "spin_cw",
         "showcase", "figure_eight")
IMG = ROOT / "docs" / "img"
# docs/img name -> (scenario under scenarios/, the run's file to copy)
DASHBOARDS = {
    "circle_dashboard.png": ("circle.yaml", "dashboard.png"),
    "closed_loop_dashboard.png": ("closed_loop/track_figure_eight.yaml", "dashboard.png"),
    "figure_eight_tracking.png": ("closed_loop/track_figure_eight.yaml", "tracking.png"),
    "figure_eight_tracking_error.png": ("closed_loop/track_figure_eight.yaml",
                                        "tracking_error.png"),
    "omni_field_dashboard.png": ("chassis/omni_field_circle.yaml", "dashboard.png"),
    "bicycle_dashboard.png": ("chassis/bicycle_circle.yaml", "dashboard.png"),
    "showcase_dashboard.png": ("modes/showcase.yaml", "dashboard.png"),
    "belief_track_circle_dashboard.png": ("robot/belief_track_circle.yaml", "dashboard.png"),
    "belief_drive_track_circle_dashboard.png": ("robot/belief_drive_track_circle.yaml",
                                                "dashboard.png"),
}
SWEEP_FILES = ("end_points.png", "paths.png", "error_histogram.png")
GRID = """name: wheel_tolerance_grid
scenario: {scenario}
grid:
  source.w_expr: ["0", "0.3"]
random:
  samples: 200
  seed: 1
  w2c.dR1: {{normal: [0.0, 0.0003]}}
  w2c.dR2: {{normal: [0.0, 0.0003]}}
  w2c.dR3: {{normal: [0.0, 0.0003]}}
  w2c.dR4: {{normal: [0.0, 0.0003]}}
"""


def chassis(ax, x, y, theta, L, W, **style):
    c, s = math.cos(theta), math.sin(theta)
    pts = np.array([[L, W], [-L, W], [-L, -W], [L, -W]])
    world = np.column_stack((x + c * pts[:, 0] - s * pts[:, 1], y + s * pts[:, 0] + c * pts[:, 1]))
    ax.add_patch(Polygon(world, closed=True, fill=False, **style))
    ax.plot([x, x - s * W], [y, y + c * W], color=style.get("edgecolor", "k"), lw=1)


def _copy(src: Path, dest: Path) -> Path:
    """A PNG re-encoded at zlib's best (the run writes them fast, not small)."""
    from PIL import Image      # matplotlib's own PNG writer
    with Image.open(src) as image:
        image.save(dest, format="png", optimize=True)
    return dest


def dashboards(tmp: Path) -> list[Path]:
    """Run each scenario of DASHBOARDS once, with plots, and copy its pictures."""
    runs: dict[str, Path] = {}
    written = []
    for name, (scenario, file) in DASHBOARDS.items():
        if scenario not in runs:
            runs[scenario] = Path(tmp) / scenario.replace("/", "_")
            runner.run(runner.prepare(ROOT / "scenarios" / scenario), runs[scenario],
                       log=lambda line: None)
        written.append(_copy(runs[scenario] / file, IMG / name))
    return written


def sweeps(tmp: Path) -> list[Path]:
    """The wheel_tolerance study and a two-point grid of it: their figures, prefixed."""
    grid = Path(tmp) / "wheel_tolerance_grid.yaml"
    grid.write_text(GRID.format(scenario=ROOT / "scenarios" / "circle.yaml"))
    written = []
    for path in (ROOT / "scenarios" / "sweeps" / "wheel_tolerance.yaml", grid):
        out = Path(tmp) / path.stem
        run_sweep(path, out, log=lambda line: None)
        for file in SWEEP_FILES:
            written.append(_copy(out / file, IMG / f"{path.stem}_{file}"))
    return written


def modes(tmp: Path) -> list[Path]:
    """modes.png and circle.gif."""
    fig = Figure(figsize=(12, 10), dpi=80, layout="constrained")
    FigureCanvasAgg(fig)
    for i, key in enumerate(MODES):
        graph = runner.prepare(ROOT / "scenarios" / "modes" / f"{key}.yaml")
        out = runner.run(graph, Path(tmp) / key, plots=False, log=lambda line: None)
        res, g = out.results, graph_geometry(graph)
        x, y, th = res["pose.x"], res["pose.y"], res["pose.theta"]
        ax = fig.add_subplot(3, 3, i + 1)
        ax.plot(x, y, color="C0", lw=2)
        chassis(ax, x[0], y[0], th[0], g["L"], g["W"], edgecolor="C2", lw=1.5)
        chassis(ax, x[-1], y[-1], th[-1], g["L"], g["W"], edgecolor="C3", lw=1.5)
        name = key
        if key.startswith("spin"):   # the car stays put: say how far it turned
            name += f" (theta {math.degrees(th[-1] - th[0]):+.0f} deg)"
        ax.set_aspect("equal", adjustable="datalim")
        ax.margins(0.25)
        ax.grid(True, lw=0.5)
        signs = out.summary.get("wheel_signs", "")
        ax.set_title(f"{name}\n{signs}" if signs else f"{name}\n(piecewise / varying twist)",
                     fontsize=10)
        ax.set_xlabel("x [m] (right)")
        ax.set_ylabel("y [m] (forward)")
    fig.suptitle("scenarios/modes/: paths (start green, end red; the tick marks the front)")
    fig.savefig(IMG / "modes.png")

    graph = runner.prepare(ROOT / "scenarios" / "circle.yaml")
    out = runner.run(graph, Path(tmp) / "circle", plots=False, log=lambda line: None)
    gif = write_animation(out.results, out.evaluation, IMG / "circle.gif")
    return [IMG / "modes.png", gif]


def main(parts: list[str]) -> None:
    IMG.mkdir(parents=True, exist_ok=True)
    makers = {"dashboards": dashboards, "modes": modes, "sweeps": sweeps}
    with tempfile.TemporaryDirectory() as tmp:
        for part in parts or list(makers):
            for path in makers[part](Path(tmp)):
                print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KiB)")


if __name__ == "__main__":
    main(sys.argv[1:])
