"""The order of the drive train's coupling under a fixed-step master (docs/robot.md, The
coupling is first order).

Runs the scenario's first STOP seconds at its step h, h/2, h/4, h/8 and h/16 (the graph keeps
body.h_ref at the scenario's step: one friction model) and prints, per output, the differences
of the end values between successive halvings and their ratios: 2 for a first-order error, 4
for a second-order one.

Run: .venv/bin/python bench/robot_order.py scenarios/robot/circle.yaml 1.0 [master]
"""
from __future__ import annotations

import dataclasses
import sys

from mecanum_fmu import master
from mecanum_fmu.runner import prepare

NAMES = ("pose.x", "pose.y", "body.vy", "motor1.w", "motor1.V")


def main(path: str, stop: float, master_name: str = "quadratic") -> None:
    graph = prepare(path, master_name=master_name, stop_time=stop)
    h = graph.scenario.experiment.step_size
    ends = []
    for k in range(5):
        exp = dataclasses.replace(graph.scenario.experiment, step_size=h / 2 ** k)
        run = dataclasses.replace(graph, scenario=dataclasses.replace(graph.scenario,
                                                                      experiment=exp))
        results = master.simulate(run, exp, keep_rows=2)
        ends.append({n: results.final(n) for n in NAMES})
    print(f"{path}, {stop:g} s, {master_name}, h = {h:g} s ... h/16 (body.h_ref "
          f"{graph.instance('body').value('h_ref'):g} s)")
    for name in NAMES:
        d = [abs(ends[k][name] - ends[k + 1][name]) for k in range(4)]
        ratios = " ".join(f"{d[k] / d[k + 1]:.2f}" for k in range(3) if d[k + 1])
        print(f"  {name}: differences {' '.join(f'{x:.3g}' for x in d)}; ratios {ratios}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), *sys.argv[3:4])
