"""Peak memory (RSS) of a CLI run against its length: results stream to disk, so it is flat.

The seed circle (gauss-seidel, no plots) over 0-10 s with 10^5, 10^6 and 10^7 steps, each in a
fresh child process (`python -m mecanum_fmu run ...`); the peak RSS of each child is read with
resource.getrusage(RUSAGE_CHILDREN) in a wrapper process of its own. 10^7 steps take a few
minutes. results.csv of 10^7 rows is about 2.5 GB: written into a temporary folder, removed.
The longest is run once more with --estimate none: the error estimate's coarser runs keep only
the rows they compare, so the peak with the estimate stays within 1.2x of the peak without.
Run: make bench   (or: .venv/bin/python bench/memory.py [steps ...])
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STEPS = (10**5, 10**6, 10**7)

WRAPPER = r"""
import json, resource, subprocess, sys
code = subprocess.run(sys.argv[1:]).returncode
print(json.dumps({"code": code,
                  "peak_kib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}))
"""


def peak_rss(steps: int, estimate: str = "auto") -> tuple[float, float]:
    """(peak RSS in MiB, wall seconds) of one CLI run of `steps` steps."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "mecanum_fmu", "run", str(ROOT / "scenarios" / "circle.yaml"),
               "--master", "gauss-seidel", "--step-size", repr(10.0 / steps), "--no-plots",
               "--estimate", estimate, "-q", "--out", out]
        tick = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", WRAPPER, *cmd], capture_output=True,
                              text=True, check=True)
        wall = time.perf_counter() - tick
        report = json.loads(proc.stdout.strip().splitlines()[-1])
        if report["code"] != 0:
            raise RuntimeError(f"the run of {steps} steps failed: {proc.stderr[-2000:]}")
        with open(Path(out) / "results.csv", "rb") as fh:
            rows = sum(1 for _ in fh) - 1
        if rows != steps + 1:
            raise RuntimeError(f"{rows} rows for {steps} steps")
    return report["peak_kib"] / 1024, wall


def main(steps_list=STEPS) -> dict:
    print("seed circle, gauss-seidel, --no-plots, 0-10 s; peak RSS of the CLI process")
    peaks = {}
    for steps in steps_list:
        peak, wall = peak_rss(steps)
        peaks[steps] = peak
        print(f"  {steps:>10,} steps  peak RSS {peak:7.1f} MiB  ({wall:6.1f} s)", flush=True)
    first = peaks[min(peaks)]
    print(f"  largest / smallest peak: {max(peaks.values()) / first:.2f}x "
          f"for {max(peaks) // min(peaks)}x the steps")
    bare, wall = peak_rss(max(peaks), "none")
    print(f"  {max(peaks):>10,} steps  peak RSS {bare:7.1f} MiB  ({wall:6.1f} s), --estimate none")
    print(f"  with the estimate / without: {peaks[max(peaks)] / bare:.2f}x")
    return peaks


if __name__ == "__main__":
    main([int(float(a)) for a in sys.argv[1:]] or STEPS)
