"""The adaptive master (--tolerance) on a drive-train scenario against a fine fixed-step run of
the same model (docs/robot.md, Stability).

Runs the scenario's first STOP seconds under the adaptive master at TOL and prints the wall
time, steps taken and rejected, then the same window under the quadratic master at steps H
and H/2 (body.h_ref kept at the scenario's step: the same friction model, only finer). The
drive train is first order in the step (docs/robot.md), so the reference is 2 y(H/2) - y(H),
and |y(H) - y(H/2)| (the error of y(H/2)) says how far to trust it. Per output: the adaptive
run's error estimate (summary.json's "max" over the window and "end"), its distance from the
reference (the largest over the rows every `step_size` of the scenario, and at the end), and
the reference's own margin (the same two).

Run: .venv/bin/python bench/robot_tolerance.py scenarios/robot/hard_start.yaml 0.1 1e-3 1e-5
(scenario, STOP [s], TOL, H [s]); wall times on whatever else the machine runs.
"""
from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np

from mecanum_fmu import master
from mecanum_fmu.runner import prepare

NAMES = ("pose.x", "pose.y", "body.vx", "body.vy", "body.w", "motor1.w", "motor2.w",
         "motor1.V", "motor1.i")


def finer(graph, step: float):
    """The graph (its start values, h_ref among them) with the quadratic master at `step`."""
    exp = dataclasses.replace(graph.scenario.experiment, master="quadratic", step_size=step,
                              tolerance=None, relative_tolerance=None)
    return dataclasses.replace(graph, scenario=dataclasses.replace(graph.scenario,
                                                                   experiment=exp)), exp


def main(path: str, stop: float, tol: float, step: float) -> None:
    graph = prepare(path, tolerance=tol, stop_time=stop)
    start = time.perf_counter()
    results = master.simulate(graph, graph.scenario.experiment)
    wall = time.perf_counter() - start
    estimate = master.estimate_error(graph, results)["error_estimate"]
    print(f"{path}, {stop:g} s at --tolerance {tol:g}: {wall:.1f} s wall, "
          f"{results.steps_taken} steps taken, {results.steps_rejected} rejected")
    t = np.asarray(results.time)
    runs = []
    for h in (step, step / 2):
        ref_graph, ref_exp = finer(graph, h)
        start = time.perf_counter()
        fine = master.simulate(ref_graph, ref_exp)
        rows = np.searchsorted(np.asarray(fine.time), t - 1e-12)   # the adaptive run's rows
        runs.append({n: np.asarray(fine[n])[rows] for n in NAMES if n in results.names})
        print(f"  quadratic at h = {h:g} s (body.h_ref = "
              f"{ref_graph.instance('body').value('h_ref'):g} s): "
              f"{time.perf_counter() - start:.1f} s")
    for name in runs[0]:
        reference = 2 * runs[1][name] - runs[0][name]
        error = np.abs(np.asarray(results[name]) - reference)
        margin = np.abs(runs[0][name] - runs[1][name])
        e = estimate.get(name)
        told = ["none", "none"] if e is None else [e["max"], e["end"]]
        told = [v if isinstance(v, str) else f"{v:.3g}" for v in told]
        print(f"  {name}: estimate max {told[0]}, end {told[1]}; |adaptive - reference| max "
              f"{error.max():.3g}, end {error[-1]:.3g} (reference within {margin.max():.2g}, "
              f"{margin[-1]:.2g})")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]))
