"""A sweep's figures: end-point scatter, error histogram, overlaid (subsampled) paths.

Each grid point has its own colour, its own ground truth (the scenario with that point's grid
values; the random parameters at their nominal values) and its own mean; a sweep without a grid
is one point. Titles stay short; the numbers go in the legends.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from ..scenario.graph import Graph
from ..models.catalog import find_roles
from ..report.ground_truth import ground_truth
from ..report.truth import Truth
from ..report.plots import new_figure
from ..storage import atomic_path
from .spec import Run, Sweep
from .worker import RunResult, with_values

MAX_PATHS = 200          # paths overlaid in all (every k-th ok run of each grid point)
TRUTH_POINTS = 501       # samples of each grid point's ground-truth path
FIG_SIZE = (6.0, 5.0)


@dataclass
class Point:
    """One grid point: its label, colour, ok runs (with their run indices) and ground truth."""
    label: str
    color: tuple
    runs: list[tuple[int, RunResult]]
    truth: Truth | None


def _save(fig: Figure, path: Path) -> Path:
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")
    fig.clear()
    return path


def write_sweep_plots(out_dir: Path, sweep: Sweep, graph: Graph, runs: list[Run],
                      results: dict[int, RunResult], errors: dict[int, dict]) -> list[Path]:
    roles = find_roles(graph)
    points = grid_points(sweep, graph, runs, results)
    if roles.pose is None or not any(p.runs for p in points):
        return []
    paths = [_scatter(out_dir, sweep, roles.pose, points), _paths(out_dir, sweep, points)]
    if errors:
        paths.append(_histogram(out_dir, sweep, points, errors))
    return paths


def grid_points(sweep: Sweep, graph: Graph, runs: list[Run],
                results: dict[int, RunResult]) -> list[Point]:
    """The sweep's grid points in run order, each with its ok runs and its ground truth."""
    refs = [ref for ref, _ in sweep.grid]
    found: dict[tuple, list] = {}
    for run in runs:
        row = results.get(run.index)
        runs_here = found.setdefault(tuple(run.values[ref] for ref in refs), [])
        if row is not None and row.status == "ok":
            runs_here.append((run.index, row))
    exp = graph.scenario.experiment
    times = np.linspace(exp.start_time, exp.stop_time, TRUTH_POINTS)
    has_truth = find_roles(graph).source is not None
    colors = _colors(len(found))
    points = []
    for (values, runs_here), color in zip(found.items(), colors):
        label = ", ".join(f"{ref}={value}" for ref, value in zip(refs, values)) or "all runs"
        truth = (ground_truth(with_values(graph, dict(zip(refs, values))), times)
                 if has_truth else None)
        points.append(Point(label, color, runs_here, truth))
    return points


def _colors(n: int) -> list[tuple]:
    """Tableau colours for up to ten grid points, a viridis ramp for more."""
    if n <= 10:
        return [colormaps["tab10"](i) for i in range(n)]
    return [colormaps["viridis"](i / (n - 1)) for i in range(n)]


def _scatter(out_dir, sweep, pose, points: list[Point]) -> Path:
    fig = new_figure(FIG_SIZE)
    ax = fig.add_subplot()
    for p in points:
        if not p.runs:
            continue
        xy = np.array([[r.ends[f"{pose}.x"], r.ends[f"{pose}.y"]] for _, r in p.runs])
        ax.scatter(xy[:, 0], xy[:, 1], s=6, alpha=0.5, color=p.color,
                   label=f"{p.label}: {len(xy)} end points")
        mean = xy.mean(axis=0)
        ax.plot(*mean, "+", color="k", ms=14, mew=2, label=f"mean ({mean[0]:.4f}, {mean[1]:.4f})")
        if p.truth is not None:
            ax.plot(p.truth.x[-1], p.truth.y[-1], "*", color=p.color, mec="k", ms=14,
                    label=f"ground truth ({p.truth.x[-1]:.4f}, {p.truth.y[-1]:.4f})")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(f"{sweep.name}: end points")
    return _save(fig, out_dir / "end_points.png")


def _histogram(out_dir, sweep, points: list[Point], errors: dict[int, dict]) -> Path:
    fig = new_figure(FIG_SIZE)
    ax = fig.add_subplot()
    per_point = [(p, np.array([errors[i]["error.position"] for i, _ in p.runs if i in errors]))
                 for p in points]
    per_point = [(p, e * 1000.0) for p, e in per_point if len(e)]
    every = np.concatenate([e for _, e in per_point])
    bins = np.histogram_bin_edges(every, bins=min(50, max(5, len(every) // 10)))
    for p, e in per_point:
        ax.hist(e, bins=bins, color=p.color, alpha=0.6 if len(per_point) > 1 else 1.0,
                label=f"{p.label}: mean {e.mean():.2f} mm, max {e.max():.2f} mm")
    ax.set_xlabel("end-point error |e| vs ground truth [mm]")
    ax.set_ylabel("runs")
    ax.set_title(f"{sweep.name}: end-point error")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    return _save(fig, out_dir / "error_histogram.png")


def _paths(out_dir, sweep, points: list[Point]) -> Path:
    fig = new_figure(FIG_SIZE)
    ax = fig.add_subplot()
    each = max(1, MAX_PATHS // max(1, len(points)))
    for p in points:
        have = [r for _, r in p.runs if r.path is not None]
        shown = have[::max(1, -(-len(have) // each))]
        for k, r in enumerate(shown):
            ax.plot(r.path[:, 0], r.path[:, 1], lw=0.6, alpha=0.3, color=p.color,
                    label=f"{p.label}: {len(shown)} of {len(have)} runs" if k == 0 else None)
        if p.truth is not None:
            ax.plot(p.truth.x, p.truth.y, color="k", lw=1.2, ls="--",
                    label="ground truth" if p is points[0] else None)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    legend = ax.legend(fontsize=7, loc="lower left")     # not "best": slow over many paths
    for handle in legend.legend_handles:                 # legend lines opaque, readable
        handle.set_alpha(1.0)
        handle.set_linewidth(max(handle.get_linewidth(), 1.5))
    ax.set_title(f"{sweep.name}: paths (up to {MAX_PATHS} overlaid)")
    return _save(fig, out_dir / "paths.png")
