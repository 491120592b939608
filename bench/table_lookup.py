"""Table lookup cost against the table's length: a 200-step run (h = 0.01 s) in the middle of a
1 kHz velocity table of 10^3 ... 10^6 rows.

Per size: `load` (prepare: read, check and hand the text to the FMU), `run` (run(): the FMU
parses the table at initialization, the stepping loop, the ground truth, results.csv), and the
stepping loop alone per step. A lookup is a bisection (O(log n)); the one O(n) cost is the
parse, once in the loader, once in the FMU and once for the ground truth. Timings are of this
machine under its current load: compare the rows with each other.

    PYTHONPATH=src python bench/table_lookup.py            # 10^3 ... 10^6 rows
    PYTHONPATH=src python bench/table_lookup.py 100000     # chosen sizes
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

SIZES = (1_000, 10_000, 100_000, 1_000_000)
RATE_HZ, STEPS, STEP = 1000, 200, 0.01

SCENARIO = """\
name: table_lookup
experiment: {{start_time: {start!r}, stop_time: {stop!r}, step_size: {step!r}, master: quadratic}}
components:
  source: {{fmu: VelocitySource, parameters: {{table: table.csv, interpolation: linear}}}}
  c2w:    {{fmu: Center2Wheel}}
  w2c:    {{fmu: Wheel2Center}}
  pose:   {{fmu: PoseIntegrator}}
connections:
  - [source.vx, c2w.vx]
  - [source.vy, c2w.vy]
  - [source.w,  c2w.w]
  - [c2w.w1, w2c.w1]
  - [c2w.w2, w2c.w2]
  - [c2w.w3, w2c.w3]
  - [c2w.w4, w2c.w4]
  - [w2c.vx, pose.vx]
  - [w2c.vy, pose.vy]
  - [w2c.w,  pose.w]
"""


def write_case(folder: Path, rows: int) -> Path:
    """A table of `rows` rows at RATE_HZ and a scenario running STEPS steps in its middle."""
    with open(folder / "table.csv", "w") as f:
        f.write("time,vx,vy,w\n")
        for k in range(rows):
            t = k / RATE_HZ
            f.write(f"{t!r},{0.2 * math.sin(0.5 * t):.6f},{0.3 * math.cos(0.2 * t):.6f},"
                    f"{0.1 * math.sin(0.3 * t):.6f}\n")
    start = round(rows / RATE_HZ / 2, 3)
    path = folder / "table_lookup.yaml"
    path.write_text(SCENARIO.format(start=start, stop=round(start + STEPS * STEP, 3),
                                    step=STEP))
    return path


def measure(rows: int) -> tuple[float, float, float, int]:
    """(load s, run s, stepping loop us per step, table bytes) of one size."""
    from mecanum_fmu.runner import prepare, run
    with tempfile.TemporaryDirectory(prefix="table_lookup_") as tmp:
        path = write_case(Path(tmp), rows)
        size = (Path(tmp) / "table.csv").stat().st_size
        t0 = time.perf_counter()
        graph = prepare(path)
        t1 = time.perf_counter()
        outcome = run(graph, Path(tmp) / "out", plots=False, log=lambda line: None)
        t2 = time.perf_counter()
        loop = outcome.summary["wall_time_s"] / outcome.summary["steps"] * 1e6
    return t1 - t0, t2 - t1, loop, size


def main(argv: list[str] | None = None) -> None:
    sizes = [int(a) for a in (argv or [])] or list(SIZES)
    print(f"{STEPS} steps of {STEP} s in the middle of a {RATE_HZ} Hz table, quadratic master")
    print("     rows      MB   load [s]   run [s]   stepping loop [us/step]")
    for rows in sizes:
        load, total, loop, size = measure(rows)
        print(f"{rows:>9,}  {size / 1e6:6.1f}  {load:9.2f}  {total:8.2f}   {loop:8.0f}")


if __name__ == "__main__":
    from mecanum_fmu.process import exit_now
    main(sys.argv[1:])
    exit_now(0)       # no interpreter shutdown with pythonfmu FMUs loaded
