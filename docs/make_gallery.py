"""Make the README gallery: docs/img/modes.png (every scenario in scenarios/modes/) and
docs/img/circle.gif (the seed study, animated).

    .venv/bin/python docs/make_gallery.py
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

MODES = ("forward", "backward", "left", "right", "diagonal", "spin_ccw", "spin_cw",
         "showcase", "figure_eight")
IMG = ROOT / "docs" / "img"


def chassis(ax, x, y, theta, L, W, **style):
    c, s = math.cos(theta), math.sin(theta)
    pts = np.array([[L, W], [-L, W], [-L, -W], [L, -W]])
    world = np.column_stack((x + c * pts[:, 0] - s * pts[:, 1], y + s * pts[:, 0] + c * pts[:, 1]))
    ax.add_patch(Polygon(world, closed=True, fill=False, **style))
    ax.plot([x, x - s * W], [y, y + c * W], color=style.get("edgecolor", "k"), lw=1)


def main() -> None:
    IMG.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(12, 10), dpi=80, layout="constrained")
    FigureCanvasAgg(fig)
    with tempfile.TemporaryDirectory() as tmp:
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
    for path in (IMG / "modes.png", gif):
        print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KiB)")


if __name__ == "__main__":
    main()
