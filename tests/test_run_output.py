"""Nothing lost, nothing crashes after the run starts (issue 13, the run-time and output half):
a failure after the stepping loop, output faults, non-finite values, bounded memory,
concurrency and signals. Exit codes: 2 bad input, 1 failed run, 130 Ctrl-C, 143 SIGTERM."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers import (ROOT, SPEC_END, child_env, cli_args, mount_tmpfs, read_csv, run_child,
                     run_main)

CIRCLE = ROOT / "scenarios" / "circle.yaml"
TIMEOUT = 180          # a safety net against a hung child, not a measurement


def variant(tmp_path: Path, name: str, **replace: str) -> Path:
    """The seed circle with some lines of its text replaced (old text -> new text)."""
    text = CIRCLE.read_text().replace("name: circle", f"name: {name}")
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def no_traceback(err: str) -> None:
    assert "Traceback" not in err, err[-3000:]


def leftovers(folder: Path) -> list[str]:
    """Temporary files or locks a run may leave in its output folder."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# --- 1. a failure after the stepping loop costs only itself -------------------------------------

def test_ground_truth_failure_keeps_the_results_and_reports_cleanly(tmp_path):
    """vx is defined only near the communication points (sqrt of a negative number between
    them): the FMUs never see the gap, the ground-truth solver does."""
    scenario = variant(tmp_path, "between", **{
        'vx_expr: "sin(t)"': 'vx_expr: "sqrt(0.001 - (t/0.05 - floor(t/0.05 + 0.5))**2)"'})
    (tmp_path / "tmp").mkdir()
    out = tmp_path / "out"
    proc = run_child("run", scenario, "--out", out, "--no-plots", env=child_env(tmp_path / "tmp"),
                     timeout=TIMEOUT)
    assert proc.returncode == 1, proc.stderr[-2000:]
    no_traceback(proc.stderr)
    assert proc.stderr.startswith("error: the ground truth could not be computed"), proc.stderr
    assert "math domain error" in proc.stderr
    assert f"kept: {out / 'results.csv'}" in proc.stderr
    header, data = read_csv(out / "results.csv")
    assert len(data) == 201 and data[-1, 0] == 10.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["steps"] == 200
    assert "math domain error" in summary["ground_truth_error"]
    assert "match" not in summary
    assert leftovers(out) == []
    assert list((tmp_path / "tmp").iterdir()) == []      # no FMU extraction left behind


def test_a_start_time_of_1e15_runs_and_matches_its_ground_truth(tmp_path, fmu_dir):
    """The float spacing at 1e15 s is 0.125 s: the ground truth integrates in time since the
    start. Time there takes only the values t0 + 0.125 k, so the commanded twist (sin t,
    cos t) is constant within 0.0625 s of each: its exact integral is the trapezoidal sum
    over the communication points, the reference for x and y here (w = 0). The trapezoidal
    master sums exactly that; the quadratic one would integrate the smooth sin t instead."""
    from mecanum_fmu.runner import prepare, run
    scenario = variant(tmp_path, "late", **{
        "start_time: 0.0": "start_time: 1.0e+15", "stop_time: 10.0": "stop_time: 1.00000000000001e+15",
        "step_size: 0.05 ": "step_size: 0.125 ", "master: quadratic": "master: trapezoidal"})
    outcome = run(prepare(scenario, fmu_dir=fmu_dir), tmp_path / "out", plots=False,
                  log=lambda line: None)
    t0 = 1.0e15
    t = t0 + 0.125 * np.arange(81)
    x_ref = float(np.trapezoid(np.sin(t), dx=0.125))
    y_ref = float(np.trapezoid(np.cos(t), dx=0.125))
    assert outcome.summary["reference_end_pose"]["x"] == pytest.approx(x_ref, abs=1e-6)
    assert outcome.summary["reference_end_pose"]["y"] == pytest.approx(y_ref, abs=1e-6)
    assert outcome.summary["match"] is True


# --- 2. output faults ---------------------------------------------------------------------

@pytest.mark.parametrize("case", ["a file", "under a file", "too long"])
def test_an_unusable_output_folder_is_bad_input_before_simulating(tmp_path, capsys, fmu_dir,
                                                                 case):
    (tmp_path / "file").write_text("not a folder\n")
    out = {"a file": tmp_path / "file", "under a file": tmp_path / "file" / "sub",
           "too long": tmp_path / ("x" * 300)}[case]
    code, stdout, err = run_main(capsys, "run", CIRCLE, "--out", out, "--no-plots",
                                 "--fmu-dir", fmu_dir)
    assert code == 2, err
    no_traceback(err)
    lines = err.strip().splitlines()
    assert lines[0] == "error:" and len(lines) == 2, err
    assert str(out) in lines[1] and "--out" in lines[1]
    assert stdout == ""                               # nothing was simulated
    assert (tmp_path / "file").read_text() == "not a folder\n"


@pytest.fixture
def tmpfs(tmp_path):
    mounted = []

    def mount(name: str, options: str) -> Path:
        folder = tmp_path / name
        mount_tmpfs(folder, options)
        mounted.append(folder)
        return folder
    yield mount
    for folder in mounted:
        subprocess.run(["umount", str(folder)], check=False)


def test_a_read_only_folder_is_bad_input(tmpfs, capsys, fmu_dir):
    """Read-only for root too: a read-only file system."""
    readonly = tmpfs("ro", "ro,size=64k")
    code, stdout, err = run_main(capsys, "run", CIRCLE, "--out", readonly, "--no-plots",
                                 "--fmu-dir", fmu_dir)
    assert code == 2, err
    no_traceback(err)
    assert "cannot write into it" in err and "Read-only file system" in err
    assert stdout == ""


def test_a_full_disk_fails_cleanly_and_leaves_nothing_that_looks_complete(tmpfs, capsys,
                                                                         fmu_dir):
    """64 KiB: results.csv of the seed circle is about 50 KiB, 4 KiB more gets it full."""
    disk = tmpfs("full", "size=64k")
    out = disk / "out"
    out.mkdir()
    (disk / "ballast").write_bytes(b"\0" * 24 * 1024)
    code, stdout, err = run_main(capsys, "run", CIRCLE, "--out", out, "--no-plots",
                                 "--fmu-dir", fmu_dir)
    assert code == 1, err
    no_traceback(err)
    assert err.startswith(f"error: writing the results into {out} failed: "
                          "No space left on device"), err
    assert sorted(p.name for p in out.iterdir()) == []    # no CSV, no summary, no temp file


# --- 3. non-finite values stop the run ------------------------------------------------------

@pytest.mark.parametrize("geometry, expect", [
    ({"  L: 0.16 ": "  L: 1.0e+308 ", "  W: 0.12 ": "  W: 1.0e+308 "},
     "parameters.W: parameter W = 1e+308 makes L + W cot(alpha) = inf"),
    ({"  R: 0.06 ": "  R: 1.0e-320 "}, "parameters.R: parameter R = 1e-320 makes 1/R = inf")])
def test_geometry_that_overflows_is_bad_input(tmp_path, capsys, fmu_dir, geometry, expect):
    """Inside the parameter ranges, yet Center2Wheel's wheel speeds (docs/spec.md,
    Kinematics: (vx -+ vy -+ (L + W) w) / R) could not be finite on any step: the
    parameters alone decide it, so it is bad input (docs/spec.md, Parameters), refused
    before the run (exit 2), nothing written."""
    scenario = variant(tmp_path, "overflow", **geometry)
    out = tmp_path / "out"
    code, stdout, err = run_main(capsys, "run", scenario, "--out", out, "--no-plots",
                                 "--fmu-dir", fmu_dir)
    assert code == 2, err
    no_traceback(err)
    assert expect in err and "the kinematics overflow on the first step" in err, err
    assert not out.exists()


def test_a_value_that_overflows_mid_run_stops_at_that_step(tmp_path, fmu_dir):
    """w = 1e308 t. Wheel2Center's w sums the four wheel speeds +-k w / R (docs/spec.md,
    Kinematics; k = L + W cot(alpha) = 0.28 for the seed): 4 k / R = 18.67, so the sum
    overflows once 18.67e308 t > 1.80e308, at the first t > 0.0963: t = 0.1 (Center2Wheel's
    own speeds, 4.67e308 t, stay finite until t = 0.385). The API raises the same error,
    with the rows before that step."""
    from mecanum_fmu import master
    from mecanum_fmu.errors import SimulationError
    from mecanum_fmu.runner import prepare
    scenario = variant(tmp_path, "grow", **{'w_expr: "0"': 'w_expr: "1e308*t"',
                                            "master: quadratic": "master: gauss-seidel"})
    graph = prepare(scenario, fmu_dir=fmu_dir)
    with pytest.raises(SimulationError) as caught:
        master.simulate(graph, graph.scenario.experiment)
    err = caught.value
    assert err.component == "w2c" and err.time == pytest.approx(0.1)
    assert "output w = inf" in str(err)
    assert err.results.complete is False
    assert err.results.time[-1] == pytest.approx(0.05)
    assert np.all(np.isfinite(np.array(err.results.data.tolist(), dtype=float)))


# --- 4. bounded memory ----------------------------------------------------------------------

def test_chunks_and_kept_rows_are_the_rows_of_the_in_memory_run(fmu_dir):
    """The sink gets every row, in order; keep_rows keeps evenly spaced rows plus the exact
    last one: both against the default in-memory run (every row)."""
    import dataclasses
    from mecanum_fmu import master
    from mecanum_fmu.master.recorder import CHUNK_ROWS
    from mecanum_fmu.runner import prepare
    graph = prepare(CIRCLE, fmu_dir=fmu_dir)
    exp = dataclasses.replace(graph.scenario.experiment, step_size=1e-3, stop_time=9.9995)
    full = master.simulate(graph, exp)                 # 10,000 steps, the last one short
    assert len(full.time) == 10_001 and full.time[-1] == 9.9995
    chunks = []
    kept = master.simulate(graph, exp, sink=chunks.append, keep_rows=300)
    assert [len(c) for c in chunks[:-1]] == [CHUNK_ROWS] * (len(chunks) - 1)
    assert np.concatenate(chunks).tobytes() == full.data.tobytes()
    stride = 34                                        # ceil(10,001 / 300)
    expected = np.concatenate([full.data[::stride], full.data[-1:]])
    assert kept.data.tobytes() == expected.tobytes()
    assert kept.steps == full.steps == 10_000


STREAM_CHILD = r"""
import json, os, resource, sys
from mecanum_fmu import runner
def peak_kib():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
scenario, out, steps = sys.argv[1], sys.argv[2], int(sys.argv[3])
small = runner.prepare(scenario, master_name="gauss-seidel", step_size=10.0 / 1000)
runner.run(small, out + "/warm", plots=False, log=lambda line: None)
before = peak_kib()
big = runner.prepare(scenario, master_name="gauss-seidel", step_size=10.0 / steps)
outcome = runner.run(big, out + "/big", plots=False, log=lambda line: None)
print(json.dumps({"before": before, "after": peak_kib(), "kept": len(outcome.results.time)}))
sys.stdout.flush()
os._exit(0)
"""


@pytest.mark.heavy(7)
def test_a_long_run_streams_its_rows_to_disk(tmp_path):
    """50,000 steps. Recording them in memory as before this change (the buffers, the
    structured copy, the CSV rows) grew the peak by 95 MiB for 120,000 steps (measured on the
    earlier code), ~40 MiB for these; streamed, it grows by ~4 MiB (the chunks)."""
    steps = 50_000
    proc = subprocess.run([sys.executable, "-c", STREAM_CHILD, str(CIRCLE), str(tmp_path),
                           str(steps)], capture_output=True, text=True, timeout=TIMEOUT,
                          env=child_env())
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(proc.stdout)
    assert report["after"] - report["before"] < 12 * 1024, report
    assert report["kept"] <= 10_002
    with open(tmp_path / "big" / "results.csv") as fh:
        rows = sum(1 for _ in fh)
    assert rows == steps + 2                       # the header, t0 and every step


# --- 5. concurrency and signals -------------------------------------------------------------

def _wait_for(predicate, what: str, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + TIMEOUT
    while not predicate():
        if proc.poll() is not None:
            pytest.fail(f"the run ended before {what}: {proc.communicate()[1][-2000:]}")
        if time.monotonic() > deadline:
            pytest.fail(f"no {what} after {TIMEOUT} s")
        time.sleep(0.05)


def test_a_second_run_into_the_same_folder_is_refused_and_sigterm_keeps_the_rows(tmp_path):
    """A long run streams into out; a second run into out is refused (exit 2) and leaves the
    first one's files alone; SIGTERM then stops the first: exit 143, the rows kept, the
    summary says complete: false, no lock, temporary file or extraction left."""
    (tmp_path / "tmp").mkdir()
    env = child_env(tmp_path / "tmp")
    out = tmp_path / "out"
    long_run = ["--master", "gauss-seidel", "--step-size", "1e-3", "--stop-time", "1000"]
    first = subprocess.Popen(cli_args("run", CIRCLE, "--out", out, "--no-plots", *long_run),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        partial = out / ".results.csv.part"
        _wait_for(lambda: partial.exists() and partial.stat().st_size > 100_000,
                  "rows streamed", first)
        second = run_child("run", CIRCLE, "--out", out, "--no-plots", env=env, timeout=TIMEOUT)
        assert second.returncode == 2, second.stderr
        no_traceback(second.stderr)
        assert f"another run is writing into {out}" in second.stderr
        assert partial.exists() and first.poll() is None
        first.send_signal(signal.SIGTERM)
        stdout, err = first.communicate(timeout=TIMEOUT)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    assert first.returncode == 143, err[-2000:]
    no_traceback(err)
    match = re.search(r"terminated \(SIGTERM\) at t = ([0-9.eE+-]+) s", err)
    assert match, err
    header, data = read_csv(out / "results.csv")
    assert len(data) > 4096 and data[-1, 0] < 1000.0
    assert np.allclose(data[:, 0], np.arange(len(data)) * 1e-3, atol=1e-9, rtol=0)
    assert np.allclose(data[:, header.index("source.vx")], np.sin(data[:, 0]), atol=1e-12)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["steps"] == len(data) - 1
    assert summary["end_time"] == data[-1, 0]
    assert leftovers(out) == []
    assert list((tmp_path / "tmp").iterdir()) == []


def test_ctrl_c_while_the_tables_are_written_finishes_them_first(tmp_path, capsys, fmu_dir,
                                                                monkeypatch):
    """Ctrl-C arrives as the summary is being written: the write completes (no truncated
    file), then the run stops with 130; results.csv and summary.json are whole."""
    from mecanum_fmu import output
    real_write = output.OutputFolder.write_json

    def write_json_interrupted(self, data, name="summary.json"):
        os.kill(os.getpid(), signal.SIGINT)
        return real_write(self, data, name)
    monkeypatch.setattr(output.OutputFolder, "write_json", write_json_interrupted)
    out = tmp_path / "out"
    code, stdout, err = run_main(capsys, "run", CIRCLE, "--out", out, "--no-plots",
                                 "--fmu-dir", fmu_dir)
    assert code == 130, err
    no_traceback(err)
    header, data = read_csv(out / "results.csv")
    assert len(data) == 201 and data[-1, 0] == 10.0
    assert data[-1, header.index("pose.x")] == pytest.approx(SPEC_END[0], abs=1e-3)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["steps"] == 200
    assert leftovers(out) == []
