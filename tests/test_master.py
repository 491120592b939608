"""The co-simulation master: step order, lag of each master, Integer/Boolean transfer,
failures, clean-up, recording and the trapezoidal fall-back."""
import json
import os
import re
import shutil
import signal
import threading
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from helpers import ROOT, chain_scenario, read_csv, run_child, run_main, test_fmus, write_scenario
from mecanum_fmu import cli, master, runner
from mecanum_fmu.errors import Interrupted

H = 0.05
R, C, K = 0.06, 1.0, 0.16 + 0.12      # docs/spec.md, Kinematics, alpha = 45 deg: c = 1, k = L + W*c


@pytest.fixture(scope="session")
def fmus(tmp_path_factory):
    return test_fmus(tmp_path_factory)


def simulate(path, **overrides):
    graph = runner.prepare(path, **overrides)
    return graph, master.simulate(graph, graph.scenario.experiment)


RECORD = ["source.vx", "source.vy", "c2w.w1", "w2c.vx"]


# --- Gauss-Seidel vs Jacobi -------------------------------------------------------------------

def test_gauss_seidel_has_no_lag_through_feedthrough_blocks(tmp_path):
    _, res = simulate(chain_scenario(tmp_path, "gs", master="gauss-seidel", outputs=RECORD))
    t = res.time
    assert np.allclose(res["source.vx"], np.sin(t), atol=1e-12, rtol=0)
    assert np.allclose(res["w2c.vx"], res["source.vx"], atol=1e-12, rtol=0)
    w1 = (-C * res["source.vx"] + res["source.vy"]) / R          # spec, Inverse kinematics, w = 0
    assert np.allclose(res["c2w.w1"], w1, atol=1e-9, rtol=0)


def test_jacobi_lags_one_step_per_feedthrough_block(tmp_path):
    _, res = simulate(chain_scenario(tmp_path, "jac", master="jacobi", outputs=RECORD))
    vx, vy = res["source.vx"], res["source.vy"]
    assert np.allclose(vx, np.sin(res.time), atol=1e-12, rtol=0)
    # c2w sees the source of the step before; w2c sees c2w of the step before
    w1_of_previous = (-C * vx[:-1] + vy[:-1]) / R
    assert np.allclose(res["c2w.w1"][1:], w1_of_previous, atol=1e-9, rtol=0)
    assert np.allclose(res["w2c.vx"][2:], vx[:-2], atol=1e-12, rtol=0)
    # and so it is not the unlagged signal
    assert np.max(np.abs(res["w2c.vx"][2:] - vx[2:])) > 0.05


# --- step order -------------------------------------------------------------------------------

@pytest.mark.parametrize("master_name", ["gauss-seidel", "trapezoidal"])
def test_reverse_declaration_still_steps_in_dependency_order(tmp_path, master_name):
    outputs = RECORD + ["c2w.w2", "w2c.vy", "pose.x", "pose.y", "pose.theta"]
    forward = chain_scenario(tmp_path, "fwd", master=master_name, outputs=outputs)
    backward = chain_scenario(tmp_path, "bwd", master=master_name, outputs=outputs,
                              order=("pose", "w2c", "c2w", "source"))
    g_fwd, r_fwd = simulate(forward)
    g_bwd, r_bwd = simulate(backward)
    assert [i.name for i in g_bwd.instances] == ["source", "c2w", "w2c", "pose"]
    assert [i.name for i in g_fwd.instances] == ["source", "c2w", "w2c", "pose"]
    assert r_fwd.names == r_bwd.names == tuple(outputs)
    assert r_fwd.data.dtype == r_bwd.data.dtype
    assert r_fwd.data.tobytes() == r_bwd.data.tobytes()
    # no lag either way (a wrong order would show as a one-step lag)
    assert np.allclose(r_bwd["w2c.vx"], r_bwd["source.vx"], atol=1e-12, rtol=0)


# --- third-party FMUs with Integer and Boolean ports -----------------------------------------

def counter_scenario(tmp_path, fmus, master_name="gauss-seidel"):
    pt = fmus["mtest_passthrough"]
    return write_scenario(tmp_path, f"ints_{master_name}", f"""\
name: ints
experiment: {{start_time: 0.0, stop_time: 1.0, step_size: 0.1, master: {master_name}}}
components:           # declared against the data flow on purpose
  second: {{fmu: {pt}}}
  first: {{fmu: {pt}}}
  counter: {{fmu: {fmus["mtest_counter"]}}}
  source: {{fmu: VelocitySource}}
connections:
  - [counter.counter, first.n_in]
  - [counter.flag, first.b_in]
  - [source.vx, first.u_in]
  - [first.n_out, second.n_in]
  - [first.b_out, second.b_in]
  - [first.u_out, second.u_in]
""")


def test_integer_and_boolean_values_pass_through_without_lag(tmp_path, fmus):
    graph, res = simulate(counter_scenario(tmp_path, fmus))
    order = [i.name for i in graph.instances]
    assert order.index("counter") < order.index("first") < order.index("second")
    assert order.index("source") < order.index("first")
    steps = np.arange(11)
    assert res["counter.counter"].tolist() == steps.tolist()
    assert res["counter.flag"].tolist() == (steps % 2 == 0).tolist()
    for name in ("first", "second"):
        assert res[f"{name}.n_out"].tolist() == steps.tolist()
        assert res[f"{name}.b_out"].tolist() == (steps % 2 == 0).tolist()
        assert np.allclose(res[f"{name}.u_out"], np.sin(res.time), atol=1e-12, rtol=0)
    assert res.data.dtype["counter.counter"] == np.dtype(np.int32)
    assert res.data.dtype["second.n_out"] == np.dtype(np.int32)
    assert res.data.dtype["counter.flag"] == np.dtype(bool)
    assert res.data.dtype["second.b_out"] == np.dtype(bool)
    assert res.data.dtype["second.u_out"] == np.dtype(np.float64)


def test_integer_and_boolean_columns_in_the_csv(tmp_path, fmus, capsys):
    out = tmp_path / "out"
    assert cli.main(["run", str(counter_scenario(tmp_path, fmus)), "--out", str(out),
                     "--no-plots", "-q"]) == 0
    lines = (out / "results.csv").read_text().splitlines()
    header = lines[0].split(",")
    last = dict(zip(header, lines[-1].split(",")))
    assert last["counter.counter"] == "10" and last["second.n_out"] == "10"
    assert last["counter.flag"] == "1" and last["second.b_out"] == "1"
    third = dict(zip(header, lines[2].split(",")))       # t = 0.1: one step, odd
    assert third["counter.flag"] == "0" and third["second.n_out"] == "1"


def test_trapezoidal_holds_inputs_of_fmus_without_declared_dependencies(tmp_path, fmus):
    path = counter_scenario(tmp_path, fmus, "trapezoidal")
    _, trap = simulate(path)
    _, gs = simulate(path, master_name="gauss-seidel")
    assert trap.master == "trapezoidal"
    assert trap.data.tobytes() == gs.data.tobytes()
    # first.acc integrates u_in held at its t_k+1 value: a right Riemann sum of sin
    t = trap.time
    right_sum = np.concatenate([[0.0], np.cumsum(np.sin(t[1:]) * np.diff(t))])
    assert np.allclose(trap["first.acc"], right_sum, atol=1e-12, rtol=0)
    trapezoid = np.concatenate([[0.0], np.cumsum(0.5 * (np.sin(t[1:]) + np.sin(t[:-1]))
                                                 * np.diff(t))])
    assert np.max(np.abs(trap["first.acc"] - trapezoid)) > 1e-3


# --- failures ---------------------------------------------------------------------------------

def failing_scenario(tmp_path, fmus, name, **params):
    parameters = ", ".join(f"{k}: {json.dumps(v)}" for k, v in params.items())
    return write_scenario(tmp_path, name, f"""\
name: {name}
experiment: {{start_time: 0.0, stop_time: 10.0, step_size: 0.1, master: gauss-seidel}}
components:
  source: {{fmu: VelocitySource}}
  breaker: {{fmu: {fmus["mtest_failing"]}, parameters: {{{parameters}}}}}
  pose: {{fmu: PoseIntegrator}}
connections:
  - [source.vx, pose.vx]
  - [source.vy, pose.vy]
  - [source.w, pose.w]
""")


def run_cli(path, out, capsys):
    return run_main(capsys, "run", path, "--out", out, "--no-plots")


def test_step_failure_keeps_rows_up_to_the_failure(tmp_path, fmus, capsys):
    out = tmp_path / "out"
    code, _, err = run_cli(failing_scenario(tmp_path, fmus, "fails", mode=0), out, capsys)
    assert code == 1
    assert "breaker" in err
    when = float(re.search(r"t = ([0-9.eE+-]+) s", err).group(1))
    assert 4.9 <= when <= 5.1
    header, data = read_csv(out / "results.csv")
    time = data[:, 0]
    assert 4.9 <= time[-1] <= 5.0 + 0.1
    assert np.allclose(time, np.arange(len(time)) * 0.1, atol=1e-9, rtol=0)
    # the rows that were kept are right: the circle (docs/spec.md, The seed scenario) and
    # breaker.y = t
    assert np.allclose(data[:, header.index("breaker.y")], time, atol=1e-9, rtol=0)
    # gauss-seidel: pose holds the source's t_k+1 value over each step (w = 0, so pose.y is
    # exactly the right Riemann sum of cos)
    right_sum = np.concatenate([[0.0], np.cumsum(0.1 * np.cos(time[1:]))])
    assert np.allclose(data[:, header.index("pose.y")], right_sum, atol=1e-9, rtol=0)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False
    assert summary["steps"] == len(time) - 1


def run_in_fresh_process(path, out):
    """`python -m mecanum_fmu run` in a child process: a pythonfmu slave that raises leaves
    the interpreter that loaded it liable to crash later (see the xfail below)."""
    return run_child("run", path, "--out", out, "--no-plots", timeout=60)


def test_initialization_failure_is_reported(tmp_path, fmus):
    out = tmp_path / "out"
    proc = run_in_fresh_process(failing_scenario(tmp_path, fmus, "init", fail_init=True), out)
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "breaker" in proc.stderr
    assert "initializ" in proc.stderr.lower()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False


def test_a_run_after_a_failure_works(tmp_path, fmus, capsys):
    failing = failing_scenario(tmp_path, fmus, "fails_first", mode=0, fail_at=2.0)
    assert run_cli(failing, tmp_path / "a", capsys)[0] == 1
    fine = failing_scenario(tmp_path, fmus, "fine", mode=0, fail_at=100.0)
    code, _, err = run_cli(fine, tmp_path / "b", capsys)
    assert code == 0, err
    header, data = read_csv(tmp_path / "b" / "results.csv")
    assert data[-1, 0] == 10.0
    assert np.allclose(data[:, header.index("breaker.y")], data[:, 0], atol=1e-9, rtol=0)
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["complete"] is True
    code, _, err = run_cli(ROOT / "scenarios" / "circle.yaml", tmp_path / "c", capsys)
    assert code == 0, err


def _pooled(name):
    return master.RUNTIME.kept_components(name)


def test_instances_are_reset_and_reused_and_can_be_released(tmp_path):
    graph = runner.prepare(chain_scenario(tmp_path, "reuse", master="trapezoidal"))
    master.release_instances()
    first = master.simulate(graph, graph.scenario.experiment)
    kept = {i.name: _pooled(i.name) for i in graph.instances}
    assert all(len(v) == 1 for v in kept.values()), kept     # terminated and pooled, not freed
    again = master.simulate(graph, graph.scenario.experiment)
    # the same instances ran again (after fmi2Reset) and gave the same bytes
    assert {i.name: _pooled(i.name) for i in graph.instances} == kept
    assert again.data.tobytes() == first.data.tobytes()
    assert master.release_instances() >= 4 and not any(_pooled(i.name) for i in graph.instances)
    fresh = master.simulate(graph, graph.scenario.experiment)
    assert fresh.data.tobytes() == first.data.tobytes()


def _same_module_other_script(built_fmus, folder):
    """VelocitySource.fmu with another default vx_expr in its slave script, under the same
    module name (what two third-party pythonfmu FMUs built from a `model.py` each are)."""
    import zipfile
    from mecanum_fmu.storage import zip_bytes
    with zipfile.ZipFile(built_fmus["VelocitySource"]) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}
        module = zf.read("resources/slavemodule.txt").decode().strip()
    script = f"resources/{module}.py"
    assert members[script].count(b'"sin(t)", "cos(t)", "0"') == 1
    members[script] = members[script].replace(b'"sin(t)", "cos(t)", "0"', b'"2.5", "cos(t)", "0"')
    other = folder / "Other.fmu"
    other.write_bytes(zip_bytes(members))
    return other


def test_two_fmus_with_one_slave_module_name_each_run_their_own_script(tmp_path, built_fmus):
    """pythonfmu imports the slave script by its module name, and a process holds one module
    per name: each FMU still runs its own script, fresh or reset, in any order."""
    other = _same_module_other_script(built_fmus, tmp_path)
    graphs = {}
    for name, fmu in (("own", built_fmus["VelocitySource"]), ("other", other)):
        graphs[name] = runner.prepare(write_scenario(tmp_path, name, f"""\
name: {name}
experiment: {{start_time: 0.0, stop_time: 1.0, step_size: 0.1, master: gauss-seidel}}
components:
  source: {{fmu: {fmu}}}
"""))
    for name in ("own", "other", "own", "other"):      # the second time: kept and reset
        res = master.simulate(graphs[name], graphs[name].scenario.experiment)
        expected = np.sin(res.time) if name == "own" else np.full(len(res.time), 2.5)
        assert np.allclose(res["source.vx"], expected, atol=1e-12, rtol=0), name


def test_an_instance_that_failed_is_not_reused(tmp_path, fmus, capsys):
    master.release_instances()
    assert run_cli(failing_scenario(tmp_path, fmus, "fails_pool", mode=0, fail_at=1.0),
                   tmp_path / "a", capsys)[0] == 1
    assert _pooled("breaker") == []                      # Error: freed, not pooled
    assert len(_pooled("source")) == 1 and len(_pooled("pose")) == 1


def test_ctrl_c_through_the_python_api_stops_the_run_and_keeps_the_rows(tmp_path):
    """SIGINT while the FMUs run (from a timer thread started by the run's first progress
    report, so it lands 0.3 s into the stepping wherever the main thread is - mostly inside an
    FMU's Python code - however slowly the machine instantiated) ends the run as Interrupted
    with the rows so far; no FMU sees a KeyboardInterrupt (which pythonfmu would turn into
    Fatal about 2 times in 3), so the instances end cleanly and are reused."""
    graph = runner.prepare(chain_scenario(tmp_path, "long", step_size=1e-4, stop_time=100.0))
    master.release_instances()
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))

    def started(fraction):
        if timer.ident is None:         # the first report: the stepping has begun
            timer.start()
    try:
        with pytest.raises(Interrupted) as caught:
            master.simulate(graph, graph.scenario.experiment, progress=started)
    finally:
        timer.cancel()
    partial = caught.value.results
    assert partial is not None and not partial.complete
    assert 0 < partial.steps < 1_000_000
    assert caught.value.time == partial.time[-1]
    # the kept rows are the circle's (docs/spec.md, The seed scenario): gauss-seidel,
    # pose.y = right Riemann sum of cos
    t = partial.time
    assert np.allclose(np.diff(t), 1e-4, atol=1e-12, rtol=0)
    right_sum = np.concatenate([[0.0], np.cumsum(1e-4 * np.cos(t[1:]))])
    assert np.allclose(partial["pose.y"], right_sum, atol=1e-8, rtol=0)
    assert all(len(_pooled(i.name)) == 1 for i in graph.instances)    # ended cleanly
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler   # handler restored


def test_raising_step_fails_cleanly_in_a_fresh_process(tmp_path, fmus):
    out = tmp_path / "out"
    proc = run_in_fresh_process(failing_scenario(tmp_path, fmus, "raises", mode=1), out)
    assert "breaker" in proc.stderr and "t = 5 s" in proc.stderr
    assert json.loads((out / "summary.json").read_text())["complete"] is False
    assert proc.returncode == 1, proc.stderr[-2000:]


# --- recording --------------------------------------------------------------------------------

SPEC_OUTPUTS = {"source.vx", "source.vy", "source.w", "c2w.w1", "c2w.w2", "c2w.w3", "c2w.w4",
               "w2c.vx", "w2c.vy", "w2c.w", "pose.x", "pose.y", "pose.theta"}


def test_outputs_restrict_and_order_the_columns(tmp_path, capsys):
    wanted = ["pose.y", "source.vx", "c2w.w3", "pose.x"]
    path = chain_scenario(tmp_path, "some", outputs=wanted)
    assert run_cli(path, tmp_path / "out", capsys)[0] == 0
    header, data = read_csv(tmp_path / "out" / "results.csv")
    assert header == ["time"] + wanted
    assert np.allclose(data[:, 2], np.sin(data[:, 0]), atol=1e-12, rtol=0)


def test_default_records_every_output(tmp_path, capsys):
    path = chain_scenario(tmp_path, "every")
    assert run_cli(path, tmp_path / "out", capsys)[0] == 0
    header, _ = read_csv(tmp_path / "out" / "results.csv")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    expected = []          # every output of every component, read from the FMUs themselves
    for name in ("source", "c2w", "w2c", "pose"):
        md = read_model_description(summary["fmus"][name]["path"])
        expected += [f"{name}.{v.name}" for v in md.modelVariables if v.causality == "output"]
    assert SPEC_OUTPUTS <= set(expected)
    assert header[0] == "time"
    assert sorted(header[1:]) == sorted(expected)


def test_an_fmu_written_again_within_one_clock_tick_is_extracted_anew(tmp_path):
    """Written again in place with as many bytes before the file system's clock moved on (the
    modification time set back to the first one's stands for that): the same inode, size and
    modification time, new content - extracted anew, not taken for the first file."""
    from mecanum_fmu.storage import zip_bytes
    fmu = tmp_path / "Block.fmu"
    fmu.write_bytes(zip_bytes({"resources/a.txt": b"one"}))
    stamp = fmu.stat().st_mtime_ns
    first = master.RUNTIME.extracted(fmu)
    with open(fmu, "r+b") as f:            # the same inode
        f.write(zip_bytes({"resources/a.txt": b"two"}))
    os.utime(fmu, ns=(stamp, stamp))
    assert fmu.stat().st_size == len(zip_bytes({"resources/a.txt": b"one"}))
    second = master.RUNTIME.extracted(fmu)
    assert (Path(first) / "resources" / "a.txt").read_bytes() == b"one"
    assert (Path(second) / "resources" / "a.txt").read_bytes() == b"two"


def test_this_process_leaves_an_fmus_bundled_python_packed_and_runs_it(tmp_path, built_fmus):
    """A Python host never opens the Python an FMU of ours carries (the loader uses the host's):
    its libpython and standard library stay in the archive, the rest is unpacked, and the FMU
    runs from there. Another FMU's resources/python/ (no MANIFEST of ours) is unpacked whole."""
    import zipfile
    from mecanum_fmu.storage import zip_bytes
    fmu = tmp_path / "PoseIntegrator.fmu"
    shutil.copyfile(built_fmus["PoseIntegrator"], fmu)
    carried = set(zipfile.ZipFile(fmu).namelist())
    assert {"resources/python/stdlib.zip", "binaries/linux64/libpython3.11.so.1.0"} <= carried
    folder = Path(master.RUNTIME.extracted(fmu))
    unpacked = {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}
    assert unpacked == {n for n in carried if not n.startswith("resources/python/lib")
                        and "/libpython" not in n and n != "resources/python/stdlib.zip"}
    scenario = write_scenario(tmp_path, "pose", """\
name: pose
experiment: {start_time: 0.0, stop_time: 1.0, step_size: 0.1}
components:
  pose: {fmu: PoseIntegrator.fmu, parameters: {x0: 0.5}}
outputs: [pose.x]
""")
    graph = runner.prepare(scenario, estimate="none")
    assert master.simulate(graph, graph.scenario.experiment)["pose.x"][-1] == 0.5
    other = tmp_path / "Other.fmu"
    other.write_bytes(zip_bytes({"resources/python/stdlib.zip": b"theirs",
                                 "binaries/linux64/libpython3.so": b"theirs too"}))
    assert sorted(p.name for p in Path(master.RUNTIME.extracted(other)).rglob("*")
                  if p.is_file()) == ["libpython3.so", "stdlib.zip"]


def test_a_rebuilt_fmu_at_the_same_path_is_extracted_anew(tmp_path, built_fmus):
    """The extraction is keyed by the FMU's content; its hash is kept per file (inode, size,
    modification time), so a file written again at the same path is hashed and unpacked
    again, and an unchanged one is not."""
    fmu = tmp_path / "Block.fmu"
    shutil.copyfile(built_fmus["Center2Wheel"], fmu)
    first = master.RUNTIME.extracted(fmu)
    assert master.RUNTIME.extracted(fmu) == first
    shutil.copyfile(built_fmus["Wheel2Center"], fmu)      # the same inode, new content
    second = master.RUNTIME.extracted(fmu)
    assert second != first
    assert read_model_description(fmu).modelName == "Wheel2Center"
    assert read_model_description(second).modelName == "Wheel2Center"
    assert read_model_description(first).modelName == "Center2Wheel"
