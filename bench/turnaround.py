"""Turnaround of the command line, as a user waits for it: `run` with and without plots and
`validate`, each a fresh `python -m mecanum_fmu` process on the seed circle.

Prints medians of interleaved repetitions (the three commands take turns, so a change in the
machine's load hits all three), the ratios

    plots cost     = (t(run) - t(run --no-plots)) / t(run --no-plots)
    validate share = t(validate) / t(run --no-plots)

the same ratios in CPU seconds (user + sys of the process and its children, the plotting worker
included: what the plots cost the machine rather than the user), the load average before and
after, and the modules `validate` imports (it should need neither matplotlib nor scipy).

Then, in this process (CPU seconds: less sensitive to the machine's load than the wall ratio),
the seed circle's dashboard drawn as the plot worker draws it: the frame and the draft (every
panel but the ground truth's) while the run integrates its truth, the rest after the truth.
Only "after the truth" is on the critical path when a core is free.
Run: make bench   (or: .venv/bin/python bench/turnaround.py [repetitions])
"""
from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "circle.yaml"
HEAVY = ("matplotlib", "scipy", "PIL", "pythonfmu")     # worth knowing whether validate loads them


def _command(kind: str, out: Path) -> list[str]:
    base = [sys.executable, "-m", "mecanum_fmu"]
    if kind == "validate":
        return base + ["validate", str(SCENARIO)]
    extra = ["--no-plots"] if kind == "run --no-plots" else []
    return base + ["run", str(SCENARIO), "--out", str(out), "-q"] + extra


def _timed(cmd: list[str]) -> tuple[float, float]:
    """Wall and CPU (user + sys, children included) seconds of one command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    tick = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, cwd=ROOT)
    wall = time.perf_counter() - tick
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def validate_imports() -> list[str]:
    """Top-level packages `validate` imports (from python -X importtime)."""
    proc = subprocess.run([sys.executable, "-X", "importtime"] + _command("validate", ROOT)[1:],
                          check=True, capture_output=True, text=True, cwd=ROOT)
    names = {line.rsplit("|", 1)[1].strip().split(".")[0]
             for line in proc.stderr.splitlines() if line.startswith("import time:")}
    names.discard("imported package")     # the header line
    return sorted(names)


def draw_times(reps: int) -> dict[str, float]:
    """Median CPU seconds of the dashboard's stages in this process (the worker's order)."""
    from mecanum_fmu.report import plots      # startup: matplotlib, for this part only
    from mecanum_fmu.runner import prepare, run
    stages = ("frame", "draft", "after the truth")
    cpu: dict[str, list[float]] = {k: [] for k in stages}
    with tempfile.TemporaryDirectory() as tmp:
        outcome = run(prepare(SCENARIO), Path(tmp) / "run", plots=False)
        results, roles, truth = outcome.results, outcome.evaluation.roles, outcome.truth
        for _ in range(reps):
            marks = [time.process_time()]
            frame = plots.dashboard_frame(results, roles, "circle")
            marks.append(time.process_time())
            draft = plots.draft_dashboard(results, roles, "circle", frame)
            marks.append(time.process_time())
            plots.save_pngs(plots.finish_dashboard(draft, truth), Path(tmp) / "plots")
            marks.append(time.process_time())
            for kind, start, end in zip(stages, marks, marks[1:]):
                cpu[kind].append(end - start)
    times = {k: statistics.median(v) for k, v in cpu.items()}
    print(f"  in-process dashboard (cpu s, median of {reps}): frame {times['frame']:.3f}, draft "
          f"{times['draft']:.3f}, after the truth {times['after the truth']:.3f}; whole "
          f"{sum(times.values()):.3f}; load average {os.getloadavg()[0]:.2f}")
    return times


def main(reps: int = 7) -> dict[str, float]:
    kinds = ("run --no-plots", "run", "validate")
    walls: dict[str, list[float]] = {k: [] for k in kinds}
    cpus: dict[str, list[float]] = {k: [] for k in kinds}
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        _timed(_command("run", Path(tmp)))        # warm the disk cache and the built FMUs
        for _ in range(reps):
            for kind in kinds:
                wall, cpu = _timed(_command(kind, Path(tmp)))
                walls[kind].append(wall)
                cpus[kind].append(cpu)
    wall = {k: statistics.median(v) for k, v in walls.items()}
    cpu = {k: statistics.median(v) for k, v in cpus.items()}
    print(f"seed circle, fresh process each, median of {reps} interleaved repetitions, "
          f"{os.cpu_count()} cores, load average {load:.2f} before, {os.getloadavg()[0]:.2f} after")
    for kind in kinds:
        print(f"  {kind:<16} wall {wall[kind]:6.3f} s (min {min(walls[kind]):.3f}, max "
              f"{max(walls[kind]):.3f})   cpu {cpu[kind]:6.3f} s")
    base, cbase = wall["run --no-plots"], cpu["run --no-plots"]
    ratios = {"plots cost": (wall["run"] - base) / base, "validate share": wall["validate"] / base}
    print(f"  plots cost     (run - run --no-plots) / run --no-plots: {ratios['plots cost']:.2f} "
          f"wall, {(cpu['run'] - cbase) / cbase:.2f} cpu")
    print(f"  validate share validate / run --no-plots:               "
          f"{ratios['validate share']:.2f} wall, {cpu['validate'] / cbase:.2f} cpu")
    imports = validate_imports()
    heavy = [name for name in HEAVY if name in imports]
    print(f"  validate imports {len(imports)} top-level packages; of {', '.join(HEAVY)}: "
          f"{', '.join(heavy) or 'none'}")
    print("    " + " ".join(n for n in imports if not n.startswith("_")))
    draw_times(reps)
    return ratios


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7)
