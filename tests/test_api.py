"""The Python API keeps the CLI's promises (issues 20, 23 and 24): every public entry point
checks its arguments and raises the project's own error naming the argument and the fix; a
call that fails leaves TMPDIR as it found it; a script that exits normally leaves nothing in
TMPDIR; parameters and scenario mappings are checked by the rules of a scenario file.

Reference values: the seed circle (docs/spec.md, The seed scenario: x = 1 - cos t,
y = sin t) and, for a wheel radius R' in Wheel2Center against R in Center2Wheel, the
kinematics of docs/spec.md (every body velocity is scaled by R'/R, so the path is too).
"""
from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

import pytest
import yaml

from helpers import ROOT, SPEC_END, child_env
from mecanum_fmu import master
from mecanum_fmu.errors import ArgumentError, MecanumError, ScenarioError
from mecanum_fmu.runner import prepare, run
from mecanum_fmu.scenario import Experiment, load_scenario_dict
from mecanum_fmu.sweep import cluster

CIRCLE = ROOT / "scenarios" / "circle.yaml"
NAN, INF = float("nan"), float("inf")


def tmp_entries() -> set[str]:
    return set(os.listdir(tempfile.gettempdir()))


def refused(call, *args, **kwargs) -> ScenarioError:
    """call(*args, **kwargs) must raise bad input (exit code 2) and leave TMPDIR as it was."""
    before = tmp_entries()
    with pytest.raises(MecanumError) as info:
        call(*args, **kwargs)
    assert isinstance(info.value, ScenarioError), repr(info.value)
    assert info.value.exit_code == 2
    assert tmp_entries() == before, "a failed call left something in TMPDIR"
    return info.value


@pytest.fixture(scope="module")
def graph(fmu_dir):
    return prepare(CIRCLE, stop_time=0.5, fmu_dir=fmu_dir, build=False)


class TestPrepareArguments:
    @pytest.mark.parametrize("kwargs, expect", [
        ({"step_size": 0}, "experiment.step_size (from the command line or prepare's "
                           "arguments): 0 must be > 0"),
        ({"step_size": -0.01}, "-0.01 must be > 0"),
        ({"step_size": NAN}, "argument step_size (--step-size): nan is not a finite number"),
        ({"step_size": INF}, "argument step_size (--step-size): inf is not a finite number"),
        ({"step_size": "0.1"}, "argument step_size (--step-size): expected a number of seconds"),
        ({"stop_time": -1.0}, "-1.0 must be after start_time 0.0"),
        ({"master_name": "quadratc"}, "unknown master 'quadratc'; did you mean 'quadratic'?"),
        ({"master_name": 3}, "argument master_name (--master): unknown master 3"),
        ({"parameters": ["w2c.R", 0.061]}, "argument parameters: expected a mapping"),
        ({"fmu_dir": 7}, "argument fmu_dir: expected a folder path"),
    ])
    def test_refused_naming_the_argument(self, kwargs, expect, fmu_dir):
        kwargs.setdefault("fmu_dir", fmu_dir)
        err = refused(prepare, CIRCLE, build=False, **kwargs)
        assert expect in str(err), str(err)

    @pytest.mark.parametrize("path", [None, 42, ["circle.yaml"]])
    def test_path_of_the_wrong_kind(self, path):
        err = refused(prepare, path)
        assert isinstance(err, ArgumentError) and isinstance(err, ValueError)
        assert "runner.prepare(): argument path: expected a scenario file path" in str(err)


class TestSimulateArguments:
    @pytest.mark.parametrize("experiment, expect", [
        (Experiment(0.0, 1.0, 0.0, "quadratic"), "experiment.step_size: 0.0 must be > 0"),
        (Experiment(0.0, 1.0, -0.1, "quadratic"), "experiment.step_size: -0.1 must be > 0"),
        (Experiment(0.0, 1.0, NAN, "quadratic"), "experiment.step_size: nan is not a finite"),
        (Experiment(0.0, 1.0, INF, "quadratic"), "experiment.step_size: inf is not a finite"),
        (Experiment(0.0, 1.0, "0.1", "quadratic"), "experiment.step_size: expected a number"),
        (Experiment(2.0, 1.0, 0.1, "quadratic"), "experiment.stop_time: 1.0 must be after "
                                                 "start_time 2.0"),
        (Experiment(0.0, 1.0, 0.1, "jacobl"), "unknown master 'jacobl'; did you mean 'jacobi'?"),
        (None, "argument experiment: expected an Experiment, got None; pass "
               "graph.scenario.experiment"),
    ])
    def test_experiment(self, graph, experiment, expect):
        err = refused(master.simulate, graph, experiment)
        assert str(err).startswith("master.simulate(): argument experiment"), str(err)
        assert expect in str(err), str(err)

    def test_graph_none(self, graph):
        err = refused(master.simulate, None, graph.scenario.experiment)
        assert "master.simulate(): argument graph: expected a Graph, got None" in str(err)
        assert "runner.prepare(" in str(err)          # the fix

    @pytest.mark.parametrize("keep_rows", [0, -5, 2.5, True, "10"])
    def test_keep_rows(self, graph, keep_rows):
        err = refused(master.simulate, graph, graph.scenario.experiment, keep_rows=keep_rows)
        assert "argument keep_rows" in str(err) and ">= 1, or None" in str(err), str(err)

    def test_callbacks(self, graph):
        err = refused(master.simulate, graph, graph.scenario.experiment, progress=5, sink="x")
        assert "argument progress: expected a function or None, got 5" in str(err)
        assert "argument sink: expected a function or None, got 'x'" in str(err)

    def test_keep_rows_one_is_a_row_count(self, graph):
        results = master.simulate(graph, graph.scenario.experiment, keep_rows=1)
        assert results.time[-1] == 0.5          # the exact last row is always kept


class TestRunAndSweepArguments:
    def test_run(self, graph, tmp_path):
        out = tmp_path / "out"
        for kwargs, expect in [({"keep_rows": 0}, "argument keep_rows"),
                               ({"log": 5}, "argument log: expected a function or None"),
                               ({"progress": 1}, "argument progress")]:
            err = refused(run, graph, out, plots=False, **kwargs)
            assert str(err).startswith("runner.run(): ") and expect in str(err), str(err)
        err = refused(run, None, out, plots=False)
        assert "runner.run(): argument graph: expected a Graph, got None" in str(err)
        err = refused(run, graph, 5, plots=False)
        assert "argument out_dir: expected a folder path, got 5" in str(err)
        assert not out.exists()

    @pytest.mark.parametrize("kwargs, expect", [
        ({"workers": 0}, "argument workers: 0 is not a worker count"),
        ({"workers": -2}, "argument workers: -2 is not a worker count"),
        ({"workers": 2.0}, "argument workers: 2.0 is not a worker count"),
        ({"scheduler": 8786}, "argument scheduler: expected an address like"),
        ({"workers": 2, "scheduler": "tcp://localhost:8786"}, "give one of the two"),
    ])
    def test_sweep_execute(self, graph, kwargs, expect):
        err = refused(cluster.execute, graph, [], **kwargs)
        assert str(err).startswith("sweep.execute(): ") and expect in str(err), str(err)

    def test_sweep_execute_graph_and_runs(self, graph):
        assert "argument graph" in str(refused(cluster.execute, None, []))
        assert "argument runs" in str(refused(cluster.execute, graph, "runs"))

    def test_sweep_file(self, tmp_path):
        err = refused(cluster.prepare_sweep, None)
        assert "sweep(): argument path: expected a sweep file path" in str(err)
        err = refused(cluster.run_sweep, tmp_path / "s.yaml", tmp_path / "out", workers=0)
        assert "workers: 0 is not a worker count" in str(err) and not (tmp_path / "out").exists()


class TestFmuChangedSincePrepare:
    """The FMUs are copied so that one can be deleted or replaced after prepare()."""

    @pytest.fixture
    def own_fmus(self, built_fmus, tmp_path):
        folder = tmp_path / "fmus"
        folder.mkdir()
        for name in ("VelocitySource", "Center2Wheel", "Wheel2Center", "PoseIntegrator"):
            shutil.copy(built_fmus[name], folder)
        return folder

    def test_deleted(self, own_fmus):
        graph = prepare(CIRCLE, stop_time=0.5, fmu_dir=own_fmus, build=False)
        (own_fmus / "Wheel2Center.fmu").unlink()
        err = refused(master.simulate, graph, graph.scenario.experiment)
        assert (f"the FMU {own_fmus / 'Wheel2Center.fmu'} of component 'w2c' is gone or "
                "unreadable since prepare() read it; call prepare() again") in str(err)

    def test_replaced_by_another_model(self, own_fmus, built_fmus):
        graph = prepare(CIRCLE, stop_time=0.5, fmu_dir=own_fmus, build=False)
        shutil.copy(built_fmus["Bicycle"], own_fmus / "Wheel2Center.fmu")
        err = refused(master.simulate, graph, graph.scenario.experiment)
        assert "of component 'w2c' was replaced by another model (GUID" in str(err)
        assert "call prepare() again" in str(err)


class TestScriptingApi:
    def test_parameters_are_set(self, fmu_dir):
        graph = prepare(CIRCLE, fmu_dir=fmu_dir, build=False,
                        parameters={"w2c.R": 0.061, "L": 0.2})
        c2w, w2c = graph.instance("c2w"), graph.instance("w2c")
        assert w2c.start_values["R"] == 0.061 and c2w.start_values["R"] == 0.06
        assert w2c.start_values["L"] == 0.2 and c2w.start_values["L"] == 0.2

    def test_a_wheel_radius_scales_the_path(self, fmu_dir):
        """docs/spec.md, Kinematics: Center2Wheel turns the commanded twist into w_i with its
        R, Wheel2Center back with its R' (w = 0 here, so L and W drop out): every body
        velocity, hence the path, is scaled by R'/R."""
        plain = prepare(CIRCLE, fmu_dir=fmu_dir, build=False)
        scaled = prepare(CIRCLE, fmu_dir=fmu_dir, build=False, parameters={"w2c.R": 0.061})
        a = master.simulate(plain, plain.scenario.experiment)
        b = master.simulate(scaled, scaled.scenario.experiment)
        ratio = 0.061 / 0.06
        for name, end in zip(("pose.x", "pose.y"), SPEC_END):
            assert b.final(name) == pytest.approx(a.final(name) * ratio, rel=1e-9)
            assert b.final(name) == pytest.approx(end * ratio, abs=1e-3)

    def test_bad_parameters_are_reported_with_the_file_rules(self, fmu_dir):
        err = refused(prepare, CIRCLE, fmu_dir=fmu_dir, build=False, parameters={
            "w3c.R": 1.0, "w2c.R": -1.0, "w2c.Rr": 2.0, "x": [1], "a.": 1})
        text = str(err)
        assert "parameters['w3c.R'] (an argument, not in the file): no component 'w3c'; did " \
               "you mean 'w2c'?" in text
        assert "components.w2c.parameters.R: parameter R = -1.0 m must be > 0" in text
        assert "Wheel2Center has no parameter 'Rr'; did you mean 'R'?" in text
        assert "parameters.x: expected a number, true/false or text, got a list" in text
        assert "parameters['a.'] (an argument, not in the file): expected 'instance.parameter'" \
               in text
        assert len(err.problems) == 5

    def test_a_scenario_mapping_runs_as_its_file(self, fmu_dir):
        doc = yaml.safe_load(CIRCLE.read_text())
        from_file = prepare(CIRCLE, fmu_dir=fmu_dir, build=False, stop_time=2.0)
        from_dict = prepare(doc, fmu_dir=fmu_dir, build=False, stop_time=2.0)
        assert from_dict.scenario.name == "circle"
        a = master.simulate(from_file, from_file.scenario.experiment)
        b = master.simulate(from_dict, from_dict.scenario.experiment)
        assert a.data.tobytes() == b.data.tobytes()
        assert b.final("pose.x") == pytest.approx(1 - math.cos(2.0), abs=1e-3)

    def test_a_bad_mapping_is_bad_input(self):
        err = refused(load_scenario_dict, {"components": {"a b": {"fmu": 3}}, "typo": 1})
        assert "<scenario mapping>: top level: unknown key 'typo'" in str(err)
        assert "instance name 'a b' must be an identifier" in str(err)
        assert "is empty" in str(refused(load_scenario_dict, None))

    def test_readme_example_runs_as_written(self, tmp_path):
        """The README's `From Python` block, in a fresh folder holding scenarios/circle.yaml:
        exit 0, its files written, nothing left in TMPDIR."""
        block = readme_python_block()
        assert "prepare(" in block and "parameters=" in block
        (tmp_path / "scenarios").mkdir()
        shutil.copy(CIRCLE, tmp_path / "scenarios")
        (tmp_path / "tmp").mkdir()
        proc = subprocess.run([sys.executable, "-c", block], cwd=tmp_path, capture_output=True,
                              text=True, timeout=300, env=child_env(tmp_path / "tmp"))
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert (tmp_path / "results" / "sweep_0" / "results.csv").is_file()
        assert os.listdir(tmp_path / "tmp") == []


def readme_python_block() -> str:
    text = (ROOT / "README.md").read_text()
    section = text[text.index("### From Python"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


SCRIPT = r"""
import os, sys
from mecanum_fmu import master
from mecanum_fmu.runner import prepare, run
graph = prepare(sys.argv[1], stop_time=1.0)
first = master.simulate(graph, graph.scenario.experiment)
if sys.argv[2] == "notebook":
    entries = len(os.listdir(os.environ["TMPDIR"]))
    master.release_instances(remove_extractions=True)
    print(entries, len(os.listdir(os.environ["TMPDIR"])))
    again = master.simulate(graph, graph.scenario.experiment)
    print(again.data.tobytes() == first.data.tobytes(), len(os.listdir(os.environ["TMPDIR"])))
else:
    run(graph, sys.argv[3], plots=False, log=lambda line: None)
"""


class TestCleanUp:
    def test_scripts_that_exit_normally_leave_tmpdir_clean(self, tmp_path):
        """Three plain processes (the report's measure runs 20): exit 0 and nothing left."""
        for i in range(3):
            tmp = tmp_path / f"tmp{i}"
            tmp.mkdir()
            proc = subprocess.run([sys.executable, "-c", SCRIPT, str(CIRCLE), "script",
                                   str(tmp_path / f"out{i}")], capture_output=True, text=True,
                                  timeout=300, env=child_env(tmp))
            assert proc.returncode == 0, proc.stderr[-2000:]
            assert os.listdir(tmp) == [], f"run {i} left {os.listdir(tmp)}"
            assert (tmp_path / f"out{i}" / "results.csv").is_file()

    def test_a_notebook_cleans_up_and_goes_on(self, tmp_path):
        proc = subprocess.run([sys.executable, "-c", SCRIPT, str(CIRCLE), "notebook"],
                              capture_output=True, text=True, timeout=300,
                              env=child_env(tmp_path))
        assert proc.returncode == 0, proc.stderr[-2000:]
        during, after_release = proc.stdout.splitlines()[0].split()
        assert int(during) == 4 and int(after_release) == 0      # one folder per FMU
        same, again = proc.stdout.splitlines()[1].split()
        assert same == "True" and int(again) == 4
        assert os.listdir(tmp_path) == []                      # and none at exit


SWEEP = """\
name: typos
scenario: circle.yaml
random:
  samples: 3
  w2c.dR1: {normall: [0.0, 0.001]}
  w2c.dR9: {normal: [0.0, 0.001]}
  w3c.R: {uniform: [0.05, 0.07]}
"""


def test_a_sweep_reports_every_problem_at_once(tmp_path, fmu_dir):
    shutil.copy(CIRCLE, tmp_path)
    (tmp_path / "typos.yaml").write_text(SWEEP)
    err = refused(cluster.prepare_sweep, tmp_path / "typos.yaml", fmu_dir)
    text = str(err)
    assert "random.w2c.dR1: unknown distribution 'normall'; did you mean 'normal'?" in text
    assert "random.w2c.dR9: Wheel2Center instance 'w2c' has no parameter 'dR9'; did you " \
           "mean 'dR4'?" in text
    assert "random.w3c.R: unknown instance 'w3c'; did you mean 'w2c'?" in text
    assert len(err.problems) == 3


def test_overflow_through_the_inputs_is_a_failed_run_naming_the_step(tmp_path, fmu_dir):
    """docs/spec.md, Parameters: a 1e308 velocity is fine alone and overflows in Center2Wheel
    (1e308 / R): a failed run (exit 1) naming the component, the variable and t = 0."""
    graph = prepare(CIRCLE, fmu_dir=fmu_dir, build=False,
                    parameters={"source.vx_expr": "1e308"})
    with pytest.raises(MecanumError) as info:
        master.simulate(graph, graph.scenario.experiment)
    assert info.value.exit_code == 1
    assert re.match(r"component 'c2w', t = 0 s: output w\d = -?inf is not a finite number",
                    str(info.value)), str(info.value)
