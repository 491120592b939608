"""Several chassis in one run (scenarios/chassis/compare.yaml): each pose against its own
ground truth, and all paths in one figure.

    python -m mecanum_fmu.report.chassis_compare [SCENARIO] [--out PNG]

A run with more than one PoseIntegrator has no single "the car": `run` reports every pose with
`pose_summaries`, and this module draws them together (chassis outline every second, as a
heading tick, so the holonomic chassis' free heading and the car's tied one show).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from .chassis_truth import pose_truth
from ..graph import Graph
from ..results import Results

# wide solid, then dashed on top: identical paths (the two holonomic chassis) stay visible
STYLES = ({"lw": 5.0, "alpha": 0.5}, {"lw": 1.5, "ls": "--"}, {"lw": 2.0})
DEFAULT_SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "chassis" / "compare.yaml"


def pose_names(graph: Graph) -> list[str]:
    """The PoseIntegrator instances, in the scenario's order."""
    return [c.name for c in graph.scenario.components
            if graph.instance(c.name).model_name == "PoseIntegrator"]


def pose_summaries(graph: Graph, results: Results) -> dict[str, dict]:
    """pose instance -> end pose, ground-truth end and error (where there is a ground truth);
    empty unless the run has two or more PoseIntegrators and recorded rows."""
    names = pose_names(graph)
    if len(names) < 2 or len(results.time) == 0:
        return {}
    out = {}
    for name in names:
        cols = [f"{name}.{k}" for k in ("x", "y", "theta")]
        if not all(c in results.names for c in cols):
            continue
        end = dict(zip(("x", "y", "theta"), (results.final(c) for c in cols)))
        entry = {"end_pose": end}
        truth = pose_truth(graph, graph.instance(name), results.time)
        if truth is not None:
            ref = dict(zip(("x", "y", "theta"), truth.end))
            entry["reference_end_pose"] = ref
            entry["position_error"] = math.hypot(end["x"] - ref["x"], end["y"] - ref["y"])
            entry["match"] = (round(end["x"], 3) == round(ref["x"], 3)
                              and round(end["y"], 3) == round(ref["y"], 3))
        out[name] = entry
    return out


def pose_report_lines(poses: dict[str, dict]) -> list[str]:
    lines = []
    for name, p in poses.items():
        end = p["end_pose"]
        line = f"{name}: end x = {end['x']:.3f}, y = {end['y']:.3f}, theta = {end['theta']:.3f}"
        if "reference_end_pose" in p:
            line += (f"; ground truth x = {p['reference_end_pose']['x']:.3f}, "
                     f"y = {p['reference_end_pose']['y']:.3f}; |e| = {p['position_error']:.3e} m, "
                     + ("match" if p["match"] else "no match"))
        lines.append(line)
    return lines


def compare_figure(graph: Graph, results: Results, title: str = "One command, three chassis"):
    """One Agg figure: every pose's path, with a heading tick every second."""
    from .plots import new_figure      # here: summaries need no matplotlib
    fig = new_figure((7.0, 6.0))
    ax = fig.add_subplot()
    t = results.time
    every = max(1, int(round(1.0 / results.step_size))) if results.step_size else 1
    for i, name in enumerate(pose_names(graph)):
        x, y, th = (np.asarray(results[f"{name}.{k}"]) for k in ("x", "y", "theta"))
        label = name.removesuffix("_pose").replace("_", " ")
        style = STYLES[i % len(STYLES)]
        ax.plot(x, y, color=f"C{i}", label=label, **style)
        k = np.arange(0, len(t), every)
        # body +Y (forward) in the world frame is (-sin theta, cos theta); arrows 0.25 m long
        ax.quiver(x[k], y[k], -np.sin(th[k]), np.cos(th[k]), color=f"C{i}", angles="xy",
                  scale_units="xy", scale=4.0, width=0.004, alpha=0.8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m] (right)")
    ax.set_ylabel("y [m] (forward)")
    ax.grid(True)
    ax.legend(title="arrows: body forward (+Y) every 1 s")
    ax.set_title(title)
    return fig


def main(argv: list[str] | None = None) -> int:
    from .. import master
    from ..runner import prepare
    parser = argparse.ArgumentParser(prog="python -m mecanum_fmu.report.chassis_compare",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(DEFAULT_SCENARIO))
    parser.add_argument("--out", default="results/compare/chassis_compare.png")
    args = parser.parse_args(argv)
    graph = prepare(args.scenario)
    results = master.simulate(graph, graph.scenario.experiment)
    for line in pose_report_lines(pose_summaries(graph, results)):
        print(line)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    compare_figure(graph, results, f"{graph.scenario.name}: one command, "
                   f"{len(pose_names(graph))} chassis").savefig(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    code = main()
    from ..master import exit_now
    exit_now(code)
