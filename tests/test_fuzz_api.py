"""Property-based fuzzing of the Python API and the sweep file (issue 23, item 5), with the
mutations of test_fuzz_scenarios: a mutated sweep file, a mutated scenario mapping with random
`parameters=`, and random experiment values for master.simulate. Each either passes its
checks or raises ScenarioError (ArgumentError is one) with located, short messages - never any
other exception - and a refused call leaves TMPDIR as it was."""
from __future__ import annotations

import copy
import functools
import math
import os
import tempfile
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import ROOT
from test_fuzz_scenarios import CIRCLE, keys, mutate, scalars, values
from mecanum_fmu.scenario.arguments import check_simulate
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.runner import prepare
from mecanum_fmu.scenario.document import MAPPING_LABEL, Experiment
from mecanum_fmu.sweep.cluster import prepare_sweep

FMUS = ROOT / "fmus"
SWEEP = {"name": "fuzz", "scenario": str(ROOT / "scenarios" / "circle.yaml"),
         "experiment": {"step_size": 0.05},
         "grid": {"source.w_expr": ["0", "0.5"]},
         "random": {"samples": 3, "seed": 1, "w2c.dR1": {"normal": [0.0, 0.0003]},
                    "w2c.R": {"uniform": [0.05, 0.07]}}}
FUZZ = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large])
parameter_keys = st.sampled_from(["w2c.R", "c2w.L", "R", "source.vx_expr", "w3c.R", "w2c.",
                                  ".R", "pose.x0", "w2c.w1"]) | keys


def assert_located(err: ScenarioError, files: set[str]) -> None:
    assert err.problems
    for problem in err.problems:
        assert problem.file in files, problem
        assert problem.message
        assert len(str(problem)) < 2000, str(problem)[:300]


@FUZZ
@given(data=st.data())
def test_a_sweep_file_loads_or_raises_scenario_error(tmp_path_factory, data):
    doc = copy.deepcopy(SWEEP)
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        doc = mutate(data, doc)
    path = tmp_path_factory.mktemp("sweep") / "fuzzed.yaml"
    path.write_text(yaml.safe_dump(doc, allow_unicode=True), encoding="utf-8")
    try:
        _, _, runs = prepare_sweep(path, FMUS)
    except ScenarioError as err:
        scenario = doc.get("scenario") if isinstance(doc, dict) else None
        assert_located(err, {str(path), "sweep()", str(scenario)})
    else:
        assert all(run.index == i for i, run in enumerate(runs))


@FUZZ
@given(data=st.data())
def test_a_mapping_with_parameters_prepares_or_raises_scenario_error(data):
    doc = copy.deepcopy(CIRCLE)
    for _ in range(data.draw(st.integers(0, 3), label="mutations")):
        doc = mutate(data, doc)
    parameters = data.draw(st.dictionaries(parameter_keys, values, max_size=4))
    before = set(os.listdir(tempfile.gettempdir()))
    try:
        prepare(doc, fmu_dir=FMUS, build=False, parameters=parameters or None)
    except ScenarioError as err:        # a root mutated into a string is a file's path
        path = {str(Path(doc))} if isinstance(doc, str) else set()
        assert_located(err, {MAPPING_LABEL, "runner.prepare()", str(ROOT / "fmus")} | path
                       | {str(p) for p in FMUS.glob("*.fmu")})
    assert set(os.listdir(tempfile.gettempdir())) == before


@functools.cache
def circle_graph():
    """The circle, prepared once for every example: check_simulate only reads the graph (its
    FMU files are still checked at each call)."""
    return prepare(ROOT / "scenarios" / "circle.yaml", fmu_dir=FMUS, build=False)


times = scalars | st.floats(-1e3, 1e3) | st.sampled_from([0.0, -0.0, 1e-300, 5e-324, math.inf])


@settings(FUZZ, max_examples=200)
@given(start=times, stop=times, step=times, master=st.sampled_from(
    ["quadratic", "jacobi", "Jacobi", "", None, 3]), keep_rows=scalars)
def test_simulate_arguments_pass_or_raise_argument_error(start, stop, step, master, keep_rows):
    graph = circle_graph()
    try:
        check_simulate(graph, Experiment(start, stop, step, master), None, None, keep_rows)
    except ScenarioError as err:
        assert_located(err, {"master.simulate()"})
    else:   # what passes is a run the master can do
        assert all(isinstance(v, float) or isinstance(v, int) for v in (start, stop, step))
        assert math.isfinite(step) and step > 0 and stop > start
        assert keep_rows is None or (isinstance(keep_rows, int) and keep_rows >= 1)
