"""Behaviour is kept across refactors: results.csv of every scenario under every master is
byte-identical to the hashes recorded before the architecture refactor (tests/data/).

A hash changes only when the numbers change; a deliberate change of behaviour records new
hashes with `python tests/test_byte_identity.py --record` and says why in its commit."""
import functools
import hashlib
import json
import sys
from pathlib import Path
from unittest import mock

import pytest

ROOT = Path(__file__).resolve().parents[1]
HASHES = ROOT / "tests" / "data" / "results_sha256.json"
RECORDED = json.loads(HASHES.read_text())


# A scenario's first MAX_STEPS steps are hashed (the drive train's 10 s at 1e-3 s would cost
# the suite minutes; any change of behaviour shows in its first 2 s as well)
MAX_STEPS = 2000
# Not recorded under the adaptive master: the drive train's circles, whose fast motors
# (~220/s) under held inputs keep its steps near 1.6e-4 s at the default tolerance 1e-4 (the
# 2 s hashed would cost the suite ~30 s each; the hard start, 1 s in ~300 steps, is recorded;
# docs/robot.md, Stability), and the sampled sensors (Encoder, Gyro, Odometry), whose
# samples must land on communication points while the adaptive steps do not (the run
# stops: "the tolerance needs a step of ..."; docs/robot.md)
NO_ADAPTIVE = tuple(f"scenarios/robot/{name}.yaml" for name in (
    "circle", "track_circle", "belief_drive_track_circle",
    "belief_drive_track_gyro", "belief_open_circle", "belief_track_circle", "belief_track_gyro"))


def _digest(key: str, out: Path) -> str:
    """results.csv's hash. The run's error estimate (the graph stepped again at two coarser
    steps) and its ground truth (an ODE solve at rtol 1e-10) are for summary.json, made after
    results.csv is written and not part of it: the estimate is turned off (estimate: none)
    and the truth left out (evaluate's with_truth=False, as for a failed run), where the two
    were half and a third of each run's time (tests/test_estimate.py and test_evaluation.py
    check them)."""
    from mecanum_fmu import runner
    scenario, master_name = key.split("::")
    graph = runner.prepare(ROOT / scenario, master_name=master_name, estimate="none")
    exp = graph.scenario.experiment
    if (exp.stop_time - exp.start_time) / exp.step_size > MAX_STEPS:
        graph = runner.prepare(ROOT / scenario, master_name=master_name, estimate="none",
                               stop_time=exp.start_time + MAX_STEPS * exp.step_size)
    ends_only = functools.partial(runner.evaluate, with_truth=False)
    with mock.patch.object(runner, "evaluate", ends_only):
        runner.run(graph, out, plots=False, log=lambda line: None)
    return hashlib.sha256((out / "results.csv").read_bytes()).hexdigest()


@pytest.mark.parametrize("key", sorted(RECORDED))
def test_results_csv_is_byte_identical(key, tmp_path):
    assert _digest(key, tmp_path) == RECORDED[key]


def scenario_files() -> list[Path]:
    """Every scenario under scenarios/ (sweep files, which name a scenario, are not ones)."""
    import yaml
    return sorted(p for p in (ROOT / "scenarios").glob("**/*.yaml")
                  if "components" in (yaml.safe_load(p.read_text()) or {}))


def test_every_scenario_is_covered():
    """A scenario added later gets a hash too (record it), so nothing escapes the check."""
    on_disk = {p.relative_to(ROOT).as_posix() for p in scenario_files()}
    assert {k.split("::")[0] for k in RECORDED} == on_disk


# The numbers may not depend on the CPU. NumPy's OpenBLAS picks its kernels by CPU (FMA,
# AVX-512 or neither) and each orders and fuses a matrix product's sums its own way: the
# masters' holds and the adaptive master's rows use elementwise arithmetic only. Prescott's
# kernel runs on any x86-64 (it is also what a CPU without AVX gets); a child run under it must
# give the recorded bytes, which test_results_csv_is_byte_identical holds this CPU's own
# kernel to (the same run: estimate none, and results.csv is written before the truth).
@pytest.mark.parametrize("scenario,name", [("modes/figure_eight.yaml", "quadratic"),
                                           ("circle.yaml", "adaptive")])
def test_results_do_not_depend_on_the_blas_kernel(scenario, name, tmp_path, fmu_dir):
    from helpers import child_env, run_child
    key = f"scenarios/{scenario}::{name}"
    proc = run_child("run", ROOT / "scenarios" / scenario, "--master", name, "--no-plots",
                     "--estimate", "none", "--quiet", "--out", tmp_path, "--fmu-dir", fmu_dir,
                     env=child_env(OPENBLAS_CORETYPE="Prescott"))
    assert proc.returncode == 0, proc.stderr
    assert hashlib.sha256((tmp_path / "results.csv").read_bytes()).hexdigest() == RECORDED[key]


if __name__ == "__main__" and sys.argv[1:] == ["--record"]:
    import tempfile
    from mecanum_fmu.masters import MASTERS
    from mecanum_fmu.process import exit_now
    hashes = dict(RECORDED)       # recorded hashes stay: only new scenarios are added
    for path in scenario_files():
        for name in MASTERS:
            key = f"{path.relative_to(ROOT).as_posix()}::{name}"
            if key in hashes or (name == "adaptive" and key.split("::")[0] in NO_ADAPTIVE):
                continue
            with tempfile.TemporaryDirectory() as out:
                hashes[key] = _digest(key, Path(out))
    HASHES.write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")
    exit_now(0)
