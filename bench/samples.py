"""The fixed-step masters on a loop closed through sampled sensors (docs/masters.md, "Samples"):
per master, how far the true pose of scenarios/robot/belief_track_circle.yaml (the follower
fed the encoders' odometry, sampled every 10 ms) is from the same run at 1/16 of the
scenario's step, at 1x, 1/2 and 1/4 of it, with the scenario's encoders and with ideal ones
(cpr 0, no noise: a smooth model, whose ratios show the order), and the stepping time.

Run: .venv/bin/python bench/samples.py [--stop SECONDS]
"""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from mecanum_fmu import master
from mecanum_fmu.runner import prepare

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "robot" / "belief_track_circle.yaml"
MASTERS = ("quadratic", "trapezoidal", "gauss-seidel", "jacobi")
DIVIDE = (1, 2, 4, 16)
IDEAL = {"cpr": 0, "sigma": 0.0}


def runs(master_name: str, stop: float, parameters: dict | None) -> dict:
    """divide -> (the pose's x, y at the scenario's own communication points, seconds)."""
    out = {}
    for d in DIVIDE:
        graph = prepare(SCENARIO, master_name=master_name, parameters=parameters)
        exp = graph.scenario.experiment
        exp = dataclasses.replace(exp, step_size=exp.step_size / d, stop_time=stop,
                                  estimate="none")
        res = master.simulate(graph, exp)
        rows = slice(None, None, d)
        out[d] = (np.column_stack((res["pose.x"][rows], res["pose.y"][rows])), res.wall_time)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=10.0)
    stop = parser.parse_args(argv).stop
    print(f"{SCENARIO.name}, 0 .. {stop:g} s: the true pose's largest distance from the run at "
          f"1/{DIVIDE[-1]} of the step, at the step / 2 / 4 (ratios), and the run's seconds")
    for label, parameters in (("encoders", None), ("ideal", IDEAL)):
        for name in MASTERS:
            found = runs(name, stop, parameters)
            ref = found[DIVIDE[-1]][0]
            far = [float(np.max(np.hypot(*(found[d][0] - ref).T))) for d in DIVIDE[:-1]]
            ratios = "  ".join(f"{a / b:5.2f}" if b > 0 else "  inf" for a, b in zip(far, far[1:]))
            print(f"  {label:8s} {name:12s} " + "  ".join(f"{x:.2e}" for x in far)
                  + f"   ratios {ratios}   {found[1][1]:.2f} s")


if __name__ == "__main__":
    main()
