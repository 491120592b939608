"""A sweep's figures: end-point scatter, error histogram, overlaid (subsampled) paths."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..graph import Graph
from ..models.catalog import find_roles
from ..report.ground_truth import ground_truth
from ..report.plots import new_figure
from ..storage import atomic_path
from .spec import Run, Sweep
from .worker import RunResult

MAX_PATHS = 200          # paths overlaid (every k-th ok run)


def _save(fig: Figure, path: Path) -> Path:
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")
    fig.clear()
    return path


def write_sweep_plots(out_dir: Path, sweep: Sweep, graph: Graph, runs: list[Run],
                      results: dict[int, RunResult], errors: dict[int, dict]) -> list[Path]:
    roles = find_roles(graph)
    ok = [results[r.index] for r in runs if r.index in results and results[r.index].status == "ok"]
    if roles.pose is None or not ok:
        return []
    truth = None
    if roles.source is not None:
        exp = graph.scenario.experiment
        truth = ground_truth(graph, np.linspace(exp.start_time, exp.stop_time, 501))
    paths = [_scatter(out_dir, sweep, roles.pose, ok, truth),
             _paths(out_dir, sweep, ok, truth)]
    if errors:
        paths.append(_histogram(out_dir, sweep, errors))
    return paths


def _scatter(out_dir, sweep, pose, ok, truth) -> Path:
    fig = new_figure((6.0, 5.0))
    ax = fig.add_subplot()
    xy = np.array([[r.ends[f"{pose}.x"], r.ends[f"{pose}.y"]] for r in ok])
    ax.scatter(xy[:, 0], xy[:, 1], s=6, alpha=0.5, label=f"co-simulation end points ({len(ok)})")
    mean = xy.mean(axis=0)
    ax.plot(*mean, "k+", ms=14, mew=2, label=f"mean ({mean[0]:.4f}, {mean[1]:.4f})")
    if truth is not None:
        ax.plot(truth.x[-1], truth.y[-1], "r*", ms=14,
                label=f"ground truth, nominal command ({truth.x[-1]:.4f}, {truth.y[-1]:.4f})")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{sweep.name}: end points")
    return _save(fig, out_dir / "end_points.png")


def _histogram(out_dir, sweep, errors) -> Path:
    fig = new_figure((6.0, 5.0))
    ax = fig.add_subplot()
    e = np.array([v["error.position"] for v in errors.values()])
    ax.hist(e * 1000.0, bins=min(50, max(5, len(e) // 10)))
    ax.set_xlabel("end-point error |e| vs ground truth [mm]")
    ax.set_ylabel("runs")
    ax.set_title(f"{sweep.name}: end-point error (mean {e.mean() * 1000:.2f} mm, "
                 f"max {e.max() * 1000:.2f} mm)")
    ax.grid(True, alpha=0.3)
    return _save(fig, out_dir / "error_histogram.png")


def _paths(out_dir, sweep, ok, truth) -> Path:
    fig = new_figure((6.0, 5.0))
    ax = fig.add_subplot()
    shown = [r for r in ok if r.path is not None]
    for r in shown[::max(1, len(shown) // MAX_PATHS)]:
        ax.plot(r.path[:, 0], r.path[:, 1], lw=0.6, alpha=0.3, color="tab:blue")
    if truth is not None:
        ax.plot(truth.x, truth.y, color="0.3", lw=1.5, ls="--", label="ground truth")
        ax.legend(fontsize=8)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{sweep.name}: paths (up to {MAX_PATHS} overlaid)")
    return _save(fig, out_dir / "paths.png")
