"""Endurance: the seed circle, a few steps, run 1,000 times in one Python process through the
Python API (runner.prepare + master.simulate each time, as a parameter sweep would; --full:
runner.run, which also writes results.csv and summary.json and integrates the ground truth).

Prints the resident set size (VmRSS) after run 1, 100 and the last, their ratio and the runs
per second. Exit 1 if RSS grew by more than --max-growth (10 %) between run 100 and the last
run, or if any run's end point differs from the first run's.
Run: PYTHONPATH=src python bench/endurance.py [--runs 1000] [--full]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from mecanum_fmu import master
from mecanum_fmu.process import exit_now
from mecanum_fmu.runner import prepare, run

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "circle.yaml"


def rss_mib() -> float:
    """This process's resident set size (VmRSS) in MiB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--stop-time", type=float, default=0.5, help="s (h = 0.05: 10 steps)")
    parser.add_argument("--max-growth", type=float, default=0.1,
                        help="allowed RSS growth between run 100 and the last (0.1 = 10 %%)")
    parser.add_argument("--full", action="store_true",
                        help="runner.run (write results.csv and summary.json) instead of "
                             "master.simulate")
    args = parser.parse_args(argv)
    checkpoints = sorted({1, min(100, args.runs), args.runs})

    out_dir = Path(tempfile.mkdtemp(prefix="mecanum_endurance_"))
    rss: dict[int, float] = {}
    first = None
    differing = 0
    tick = time.perf_counter()
    for i in range(1, args.runs + 1):
        graph = prepare(SCENARIO, stop_time=args.stop_time)
        if args.full:
            results = run(graph, out_dir, plots=False, log=lambda line: None).results
        else:
            results = master.simulate(graph, graph.scenario.experiment)
        data = results.data.tobytes()
        if first is None:
            first, end = data, (results.final("pose.x"), results.final("pose.y"))
            steps = results.steps
        elif data != first:
            differing += 1
        if i in checkpoints:
            rss[i] = rss_mib()
    wall = time.perf_counter() - tick

    mid = checkpoints[1] if len(checkpoints) > 2 else checkpoints[0]
    growth = rss[args.runs] / rss[mid]
    api = "runner.prepare + runner.run (no plots)" if args.full else \
        "runner.prepare + master.simulate"
    print(f"seed circle, {steps} steps per run, {api}, {args.runs} runs in one process")
    for i in checkpoints:
        print(f"  RSS after run {i:>{len(str(args.runs))}}: {rss[i]:8.1f} MiB")
    print(f"  RSS({args.runs})/RSS({mid}): {growth:.3f}")
    print(f"  {args.runs / wall:.1f} runs/s ({1e3 * wall / args.runs:.1f} ms per run, "
          f"{wall:.1f} s in all)")
    print(f"  end point of run 1: x = {end[0]!r}, y = {end[1]!r}; runs whose results differ "
          f"from run 1: {differing}")
    ok = growth <= 1 + args.max_growth and differing == 0
    print(f"rule: exit 1 if RSS({args.runs}) > {1 + args.max_growth:g} x RSS({mid}) "
          f"or any run's results differ from run 1 -> {'ok' if ok else 'FAILED'}")
    for leftover in out_dir.iterdir():
        leftover.unlink()
    out_dir.rmdir()
    return 0 if ok else 1


if __name__ == "__main__":
    exit_now(main())     # no interpreter shutdown with pythonfmu FMUs loaded
