"""The fixed-step masters at jumps: per scenario whose input jumps on communication points, per
master, the end-position error against the ground truth at the scenario's own step, and
whether the end point matches (3 decimals). The scenarios: modes/showcase (segments), every
modes/*.yaml, three chassis driven by one segments source (SEGMENTS_COMPARE below), and the
closed loop on a recorded path (the follower's feed-forward jumps at every row).

Run: .venv/bin/python bench/jumps.py [--only SUBSTRING]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mecanum_fmu import master
from mecanum_fmu.models.topology import topology
from mecanum_fmu.report.evaluation import evaluate
from mecanum_fmu.runner import prepare

ROOT = Path(__file__).resolve().parent.parent
MASTERS = ("quadratic", "trapezoidal", "gauss-seidel", "jacobi")
SEGMENTS = [{"duration": 1}, {"duration": 2, "vy": 0.3}, {"duration": 1.5, "vx": -0.3, "w": 0.4},
            {"duration": 2, "vx": 0.2, "vy": 0.1, "w": -0.6}, {"duration": 1}]


def segments_compare() -> dict:
    """Mecanum, omni and a second mecanum of another size on one segments source, ending
    in the fourth segment, moving and turning (no cancellation at rest)."""
    chassis = {"mecanum": ("Center2Wheel", "Wheel2Center", {"L": 0.16, "W": 0.12, "R": 0.06}),
               "omni": ("OmniCenter2Wheel", "OmniWheel2Center", {"L": 0.2, "R": 0.05}),
               "big": ("Center2Wheel", "Wheel2Center", {"L": 0.3, "W": 0.25, "R": 0.1})}
    components = {"command": {"fmu": "VelocitySource", "segments": SEGMENTS}}
    connections = []
    for name, (c2w, w2c, geometry) in chassis.items():
        components[f"{name}_c2w"] = {"fmu": c2w, "parameters": geometry}
        components[f"{name}_w2c"] = {"fmu": w2c, "parameters": geometry}
        components[f"{name}_pose"] = {"fmu": "PoseIntegrator"}
        connections += [[f"command.{v}", f"{name}_c2w.{v}"] for v in ("vx", "vy", "w")]
        connections += [[f"{name}_c2w.w{i}", f"{name}_w2c.w{i}"] for i in range(1, 5)]
        connections += [[f"{name}_w2c.{v}", f"{name}_pose.{v}"] for v in ("vx", "vy", "w")]
    return {"name": "segments_compare",
            "experiment": {"start_time": 0.0, "stop_time": 6.0, "step_size": 0.01},
            "components": components, "connections": connections}


def showcase_moving() -> dict:
    """modes/showcase stopped in its diagonal segment, at 10.5 s: the end is no rest."""
    import yaml
    doc = yaml.safe_load((ROOT / "scenarios/modes/showcase.yaml").read_text())
    doc["experiment"]["stop_time"] = 10.5
    return doc


def scenarios() -> dict:
    found = {"modes/" + p.stem: p for p in sorted((ROOT / "scenarios/modes").glob("*.yaml"))}
    found["modes/showcase to 10.5 s"] = showcase_moving()
    found["segments_compare"] = segments_compare()
    found["closed_loop/recorded_path"] = ROOT / "scenarios/closed_loop/recorded_path.yaml"
    return found


def end_errors(scenario, master_name: str) -> list[tuple[str, float, bool]]:
    graph = prepare(scenario, master_name=master_name)
    results = master.simulate(graph, graph.scenario.experiment)
    evaluation = evaluate(graph, results, topo=topology(graph))
    return [(p.pose, p.error["position"], p.match) for p in evaluation.poses]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="")
    args = parser.parse_args(argv)
    print(f"{'scenario':28s} {'pose':13s} " + " ".join(f"{m:>20s}" for m in MASTERS))
    for name, scenario in scenarios().items():
        if args.only not in name:
            continue
        per_master = [end_errors(scenario, m) for m in MASTERS]
        for i, (pose, _, _) in enumerate(per_master[0]):
            cells = [f"{e[i][1]:13.2e} {'match' if e[i][2] else 'NO':>6s}" for e in per_master]
            print(f"{name:28s} {pose:13s} " + " ".join(f"{c:>20s}" for c in cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
