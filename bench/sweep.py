"""Sweeps on Dask, measured in one run: runs/s with 1 and 2 local workers (the same runs, both
clusters warmed up first, so FMU unpacking and instantiation are not timed; best of 3
interleaved rounds), the per-run overhead on a worker next to its stepping loop (the seed circle, 200
steps), and the whole 1000-sample scenarios/sweeps/wheel_tolerance.yaml as `sweep` runs it.

Run: make bench (40 runs a round, no whole study), make bench-long (all of it), or
.venv/bin/python bench/sweep.py [--runs N] [--no-study]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mecanum_fmu.sweep.cluster import cluster, prepare_sweep, run_on, run_sweep

import sweep_estimate     # bench/: the sweep worker's run against master.simulate alone

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "scenarios" / "sweeps" / "wheel_tolerance.yaml"


def rates(graph, runs, rounds: int = 3) -> tuple[float, float, list]:
    """Best runs/s of `runs` on warmed-up LocalClusters of 1 and of 2 worker processes, over
    `rounds` interleaved rounds (the machine is shared: best-of filters out other load)."""
    with cluster(1, None) as one, cluster(2, None) as two:
        best = {1: 0.0, 2: 0.0}
        rows: list = []
        for client, n, _ in (one, two):
            run_on(client, n, graph, runs[:n * 2])          # warm-up: every worker set up
        for _ in range(rounds):
            for client, n, _ in (one, two):
                tick = time.perf_counter()
                done, _ = run_on(client, n, graph, runs)
                best[n] = max(best[n], len(done) / (time.perf_counter() - tick))
                if n == 2:
                    rows += list(done.values())
    return best[1], best[2], rows


SPIN = "import time\nt = time.perf_counter()\nx = 0\nfor i in range(5_000_000): x += i\n" \
       "print(time.perf_counter() - t)"


def machine_parallelism() -> float:
    """How much faster 2 plain CPU-bound processes get through 2 jobs than 1 process, right
    now: the most 2 workers can gain on this (shared) machine."""
    def spin(n: int) -> float:
        tick = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-c", SPIN], stdout=subprocess.DEVNULL)
                 for _ in range(n)]
        for p in procs:
            p.wait()
        return time.perf_counter() - tick
    return 2 * spin(1) / spin(2)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=120, help="runs per timed round")
    parser.add_argument("--no-study", action="store_true",
                        help="leave out the whole 1000-sample study (make bench-long runs it)")
    args = parser.parse_args(argv)
    _, graph, runs = prepare_sweep(STUDY)
    runs = runs[:args.runs]
    before = machine_parallelism()
    one, two, rows = rates(graph, runs)
    after = machine_parallelism()
    print(f"wheel_tolerance runs (circle, 200 steps): {len(runs)} runs per round, warmed-up "
          "LocalClusters, best of 3 interleaved rounds")
    print(f"  1 worker    {one:7.2f} runs/s")
    print(f"  2 workers   {two:7.2f} runs/s   {two / one:.2f}x 1 worker (target >= 1.7x)")
    print(f"  (the machine, same moment: 2 plain CPU-bound processes do {before:.2f}x / "
          f"{after:.2f}x the work of 1, before / after; 2.0x on 2 idle cores)")
    loop = statistics.median(r.loop_seconds for r in rows)
    total = statistics.median(r.seconds for r in rows)
    print(f"  per run on a worker (median): {1000 * total:.2f} ms, stepping loop "
          f"{1000 * loop:.2f} ms, overhead {1000 * (total - loop):.2f} ms = "
          f"{(total - loop) / loop:.2f}x the loop (target <= 2x)")
    graph_e, batch, path_names = sweep_estimate.study(20)
    ratio = sweep_estimate.compare(graph_e, batch, path_names, 3, "auto")
    print(f"  a sweep run (its error estimate included) / master.simulate alone: {ratio:.2f}x "
          "(target <= 1.2x; bench/sweep_estimate.py: with and without the estimate)")
    measured = {"one": one, "two": two, "machine": (before, after),
                "overhead": (total - loop) / loop, "estimate": ratio}
    if not args.no_study:
        measured["whole"] = whole_study()
    return measured


def whole_study() -> float:
    """The 1000-sample wheel_tolerance as `sweep` runs it, plots included; its wall time."""
    with tempfile.TemporaryDirectory(prefix="mecanum_bench_sweep_") as out:
        tick = time.perf_counter()
        summary = run_sweep(STUDY, out, plots=True, log=lambda line: None)
        whole = time.perf_counter() - tick
    print(f"1000-sample wheel_tolerance (`sweep`, {summary['workers']} local workers, plots): "
          f"{whole:.1f} s in all, cluster start {summary['startup_s']:.1f} s, runs "
          f"{summary['wall_time_s']:.1f} s ({summary['runs_per_s']:.1f} runs/s)")
    ep, err = summary["end_point"], summary["error_position"]
    print(f"  end points: sd x {1000 * ep['sd'][0]:.1f} mm, sd y {1000 * ep['sd'][1]:.1f} mm, "
          f"max from mean {1000 * ep['max_from_mean']:.1f} mm; error vs ground truth: mean "
          f"{1000 * err['mean']:.1f} mm, sd {1000 * err['sd']:.1f} mm, max {1000 * err['max']:.1f} mm")
    return whole

if __name__ == "__main__":       # a guard Dask's worker processes need (they re-import main)
    from mecanum_fmu.process import exit_now
    main()
    exit_now(0)
