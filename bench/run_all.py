"""`make bench`: the quick benchmarks, measured in one run on this machine, within a budget of
3 minutes; `make bench-long` (run_all.py --long): the long ones (other FMI hosts, the full
accuracy table, peak memory against run length up to 10^7 steps, 1,000 runs in one process,
the whole 1000-sample sweep).

Not tests: nothing here asserts a time; it prints ratios measured side by side, each
benchmark's time, the total and the budget. No benchmark writes a tracked file: the
modification times of git's tracked files are compared before and after, and any file written
is named at the end (exit code 1).
"""
import resource
import subprocess
import sys
import time
from pathlib import Path

import accuracy
import closed_loop_order
import endurance
import estimates
import loop_overhead
import memory
import other_hosts
import samples
import sweep
import table_lookup
import third_party
import turnaround
from mecanum_fmu.process import exit_now

ROOT = Path(__file__).resolve().parents[1]
BUDGET_S = {"bench": 180.0, "bench-long": None}      # make bench: under 3 minutes
QUICK = (
    ("accuracy per cost, quick (bench/accuracy.py --quick: the seed circle and the quiet/busy "
     "table, TOL 1e-2..1e-4)", lambda: accuracy.main(["--quick", "--scenario", "circle.yaml",
                                                     "--scenario", "profiles/quiet_then_busy.yaml"])),
    ("stepping-loop overhead (bench/loop_overhead.py)", loop_overhead.main),
    ("closed-loop convergence (bench/closed_loop_order.py)", closed_loop_order.main),
    ("sweeps on Dask: rates and per-run overhead (bench/sweep.py --runs 40 --no-study)",
     lambda: sweep.main(["--runs", "40", "--no-study"])),
    ("table lookup: 10^3 and 10^6 rows (bench/table_lookup.py 1000 1000000)",
     lambda: table_lookup.main(["1000", "1000000"])),
    ("command-line turnaround: plots and validate (bench/turnaround.py 3)",
     lambda: turnaround.main(3)),
)
LONG = (
    ("the same run in other FMI hosts (bench/other_hosts.py)", other_hosts.main),
    ("accuracy per cost, every scenario and tolerance (bench/accuracy.py)",
     lambda: accuracy.main([])),
    ("the error estimate against the truth, every scenario, fixed master and step "
     "(bench/estimates.py)", lambda: estimates.main([])),
    ("the adaptive master's own estimate against the truth (bench/estimates.py --adaptive)",
     lambda: estimates.main(["--adaptive"])),
    ("the closed loops' estimate against a run at 1/32 of the step (bench/estimates.py "
     "--loops)", lambda: estimates.main(["--loops"])),
    ("the estimate on third-party FMUs with a state: the measured response against the "
     "truth and Richardson (bench/third_party.py)", third_party.main),
    ("a loop closed through sampled sensors, per master (bench/samples.py)",
     lambda: samples.main([])),
    ("peak memory against run length (bench/memory.py)", memory.main),
    ("sweeps on Dask, the whole 1000-sample study (bench/sweep.py)", lambda: sweep.main([])),
    ("command-line turnaround, 7 repetitions (bench/turnaround.py)", turnaround.main),
    ("1,000 runs in one process (bench/endurance.py)", lambda: endurance.main([])),
)


def tracked_mtimes() -> dict[str, int]:
    """Each tracked file's modification time (empty outside a git work tree)."""
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True,
                             check=True).stdout.decode().split("\0")
    except (OSError, subprocess.CalledProcessError):
        return {}
    return {name: (ROOT / name).stat().st_mtime_ns for name in out
            if name and (ROOT / name).is_file()}


def cpu_seconds() -> float:
    """User + system time of this process and of its children that have ended."""
    usage = [resource.getrusage(who) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    return sum(u.ru_utime + u.ru_stime for u in usage)


def run(target: str, benches) -> int:
    """Run `benches` in turn, timing each; print the total against the budget (over it is said,
    not an error: the machine may be busy). Exit code 1 when a benchmark wrote a tracked file."""
    before = tracked_mtimes()
    start = time.perf_counter()
    code = 0
    for i, (title, bench) in enumerate(benches):
        print(f"{'' if i == 0 else chr(10)}== {title}", flush=True)
        tick = time.perf_counter()
        result = bench()
        if isinstance(result, int) and not isinstance(result, bool) and result != 0:
            code = result                           # endurance: its own verdict
        print(f"   ({time.perf_counter() - tick:.1f} s)", flush=True)
    total = time.perf_counter() - start
    budget = BUDGET_S[target]
    verdict = "" if budget is None else (
        f" (budget {budget:.0f} s: " + ("within it)" if total <= budget else "OVER it)"))
    print(f"\nmake {target}: {total:.1f} s in all{verdict}; {cpu_seconds():.1f} s of CPU time "
          "(this process and its children: about the wall time on an idle machine; on a shared "
          "one the wall time grows with its load)")
    after = tracked_mtimes()
    written = sorted(name for name, mtime in before.items() if after.get(name) != mtime)
    if written:
        print("a benchmark wrote tracked files: " + ", ".join(written))
        code = 1
    return code


if __name__ == "__main__":
    long = "--long" in sys.argv[1:]
    exit_now(run("bench-long" if long else "bench", LONG if long else QUICK))
    # exit_now: no interpreter shutdown with pythonfmu FMUs loaded
