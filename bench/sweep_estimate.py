"""A sweep's runs against the same runs by master.simulate alone, in one process: what the
sweep worker adds per run (the error estimate above all, docs/masters.md) as a ratio of
medians. The runs are the first N variants of scenarios/sweeps/wheel_tolerance.yaml, made by
the worker's own run_batch, one run at a time; each variant run both ways back to back, which
goes first alternating, and the ratio the median of the runs' own ratios (a burst of load
elsewhere falls on both of a pair); the first run of each kind not timed. Twice:
with the default estimate (auto: the embedded pair) and with `experiment: {estimate: none}`.

Run: .venv/bin/python bench/sweep_estimate.py [--runs N] [--rounds R] [--study SWEEP_FILE]
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

from mecanum_fmu import master
from mecanum_fmu.models.catalog import find_roles
from mecanum_fmu.sweep.cluster import prepare_sweep
from mecanum_fmu.sweep.worker import run_batch, with_values

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "scenarios" / "sweeps" / "wheel_tolerance.yaml"


def main(argv=None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--study", default=str(STUDY.relative_to(ROOT)),
                        help="the sweep file (e.g. scenarios/robot/sweep_mu_kp.yaml: the drive "
                             "train's pair in every run)")
    args = parser.parse_args(argv)
    graph, batch, path_names = study(args.runs, ROOT / args.study)
    ratio = compare(graph, batch, path_names, args.rounds, "auto")
    scenario = graph.scenario
    off = dataclasses.replace(scenario, experiment=dataclasses.replace(scenario.experiment,
                                                                       estimate="none"))
    compare(dataclasses.replace(graph, scenario=off), batch, path_names, args.rounds, "none")
    return ratio


def compare(graph, batch, path_names, rounds: int, estimate: str) -> float:
    exp = graph.scenario.experiment
    run_batch(graph, batch[:1], path_names)                    # warm: unpack, instantiate
    master.simulate(with_values(graph, batch[0][1]), exp)
    alone, sweep = [], []
    for round_ in range(rounds):
        for i, (index, values) in enumerate(batch):
            taken = {}
            for kind in ("alone", "sweep") if (round_ + i) % 2 == 0 else ("sweep", "alone"):
                tick = time.perf_counter()
                if kind == "alone":
                    master.simulate(with_values(graph, values), exp)
                else:
                    run_batch(graph, [(index, values)], path_names)
                taken[kind] = time.perf_counter() - tick
            alone.append(taken["alone"])
            sweep.append(taken["sweep"])
    a, s = statistics.median(alone), statistics.median(sweep)
    paired = statistics.median(w / m for w, m in zip(sweep, alone))
    print(f"estimate {estimate}: {len(batch)} runs x {rounds} rounds: master.simulate alone "
          f"{a * 1e3:.1f} ms a run, the sweep worker's run {s * 1e3:.1f} ms: ratio {paired:.2f} "
          f"(median of the {len(alone)} runs' own ratios; of the medians {s / a:.2f})")
    return paired


def study(runs: int, path: Path = STUDY):
    """The compiled graph, the first `runs` (index, values) and the path names of the study
    (the pose's x and y, as the sweep's client asks for them)."""
    _, graph, planned = prepare_sweep(path)
    batch = [(r.index, r.values) for r in planned if r.problem is None][:runs]
    pose = find_roles(graph).pose
    return graph, batch, ((f"{pose}.x", f"{pose}.y") if pose else None)


if __name__ == "__main__":
    main()
