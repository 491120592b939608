"""Several chassis in one run (scenarios/chassis/compare.yaml): all paths in one figure.

    .venv/bin/python -m mecanum_fmu.report.chassis_compare [SCENARIO] [--out PNG]

A run with more than one PoseIntegrator has no single "the car": its Evaluation
(report.evaluation) holds every pose against its own ground truth, and this module draws them
together (a heading tick every second, so the holonomic chassis' free heading and the car's tied
one show).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .. import master
from ..errors import MecanumError, ScenarioError
from ..process import exit_now
from ..results import Results
from ..scenario.graph import Graph, compile_graph
from ..models.rebuild import build_bundled
from ..models.topology import topology
from ..scenario.document import read_scenario
from .evaluation import Evaluation, evaluate, report_lines
from .plots import new_figure

# wide solid, then dashed on top: identical paths (the two holonomic chassis) stay visible
STYLES = ({"lw": 5.0, "alpha": 0.5}, {"lw": 1.5, "ls": "--"}, {"lw": 2.0})
DEFAULT_SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "chassis" / "compare.yaml"


def compare_figure(results: Results, evaluation: Evaluation,
                   title: str = "One command, three chassis"):
    """One Agg figure: every pose's path, with a heading tick every second."""
    fig = new_figure((7.0, 6.0))
    ax = fig.add_subplot()
    t = results.time
    every = max(1, int(round(1.0 / results.step_size))) if results.step_size else 1
    for i, name in enumerate(p.pose for p in evaluation.poses):
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


def _load(path: str) -> Graph:
    """The scenario's checked graph, its bundled FMUs built when missing (as runner.prepare,
    which sits above this module, without its overrides). Raises ScenarioError."""
    scenario, problems = read_scenario(path)
    if problems:
        raise ScenarioError(problems)
    build_bundled(scenario)
    return compile_graph(scenario)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mecanum_fmu.report.chassis_compare",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(DEFAULT_SCENARIO))
    parser.add_argument("--out", default="results/compare/chassis_compare.png")
    args = parser.parse_args(argv)
    try:
        graph = _load(args.scenario)
        results = master.simulate(graph, graph.scenario.experiment)
    except MecanumError as err:     # bad input (2) or a failed run (1): the message says why
        print(err, file=sys.stderr)
        return 2 if isinstance(err, ScenarioError) else 1
    evaluation = evaluate(graph, results, topo=topology(graph))
    for line in report_lines(evaluation.summary()):
        print(line)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    compare_figure(results, evaluation, f"{graph.scenario.name}: one command, "
                   f"{len(evaluation.poses)} chassis").savefig(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    exit_now(main())
