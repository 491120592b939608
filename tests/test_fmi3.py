"""The FMI 3.0 FMUs (fmus/fmi3/, models/build3.py) and FMI 3.0 components in the master.

- fmpy's validator finds nothing; units and dependencies are declared;
- FMPy's own simulate_fmu runs each FMI 3.0 FMU and its FMI 2.0 twin to the same values;
- a plain C FMI 3.0 host runs one with nothing set, under valgrind, and where no Python exists
  at all (a mount namespace, root);
- a scenario mixing FMI 2.0 and 3.0 components gives the all-FMI-2.0 run's values, under every
  master (fixed steps, rollback, adaptive with a tolerance), and so does its SSP read back;
- Ecos (ecospy and its `ecos` program) runs an all-FMI-3.0 SSP to our Jacobi master's end.
Under MECANUM_FMU_REQUIRE_TOOLS=1 a missing tool (gcc, valgrind, unshare, ecospy) fails.
"""
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from helpers import CHAIN_CONNECTIONS, ROOT, mode_fmu3, run_host_or_skip, \
    tool_missing as missing, write_scenario
from mecanum_fmu import master
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.interop.cross_check import CSV_TOLERANCE, compared_outputs, cross_check, \
    ours_jacobi
from mecanum_fmu.interop.ssp_write import export_ssp
from mecanum_fmu.runner import prepare, run
from test_no_preload import PYTHONS, _hidden, _python_places

AGREE = 1e-12
CHAIN = """\
name: {name}
experiment: {{start_time: 0.0, stop_time: 3.0, step_size: 0.02}}
components:
  source: {{fmu: {source}, parameters: {{vx_expr: "0.4*sin(t)", vy_expr: "0.3 + 0.1*t", w_expr: "0.5*cos(2*t)"}}}}
  c2w: {{fmu: {c2w}}}
  w2c: {{fmu: {w2c}, parameters: {{dR2: 0.002}}}}
  pose: {{fmu: {pose}, parameters: {{x0: 1, theta0: 0.3}}}}
""" + CHAIN_CONNECTIONS


def test_fmpy_validation_finds_no_problems(fmi3_fmus):
    for name, fmu in fmi3_fmus.items():
        assert validate_fmu(str(fmu)) == [], name


def test_units_dependencies_and_the_wheel_speed_array(fmi3_fmus, built_fmus):
    """Same variables and value references as the FMI 2.0 twin, every Float64 has a unit,
    outputs declare their dependencies, and Center2Wheel's wheel_speeds is a [4] array."""
    for name, fmu in fmi3_fmus.items():
        md3, md2 = read_model_description(str(fmu)), read_model_description(str(built_fmus[name]))
        assert md3.fmiVersion == "3.0" and md3.coSimulation.canGetAndSetFMUstate, name
        scalars2 = {v.name: v.valueReference for v in md2.modelVariables}
        scalars3 = {v.name: v.valueReference for v in md3.modelVariables
                    if v.name in scalars2}
        assert scalars3 == scalars2, name
        assert all(v.unit for v in md3.modelVariables if v.type == "Float64"), name
        assert all(o.dependencies is not None for o in md3.outputs), name
    md = read_model_description(str(fmi3_fmus["Center2Wheel"]))
    array = next(v for v in md.modelVariables if v.name == "wheel_speeds")
    assert [d.start for d in array.dimensions] == [4] and array.unit == "rad/s"
    deps = {o.variable.name: sorted(d.name for d in o.dependencies) for o in md.outputs}
    assert deps["wheel_speeds"] == deps["w1"] == ["vx", "vy", "w"]


def _inputs(md) -> dict:
    """A fixed, non-trivial start value for every Real input (FMI 2.0 and 3.0 names agree)."""
    values = iter((0.3, 0.5, 0.2, -0.4, 0.7, 0.1))
    return {v.name: next(values) for v in md.modelVariables
            if v.causality == "input" and v.type in ("Real", "Float64")}


@pytest.mark.parametrize("model", ["VelocitySource", "Center2Wheel", "Wheel2Center",
                                   "PoseIntegrator", "PathFollower", "OmniCenter2Wheel",
                                   "OmniWheel2Center", "FieldToBody", "Bicycle", "SteeringSource"])
def test_simulate_fmu_agrees_with_the_fmi2_twin(fmi3_fmus, built_fmus, model):
    """FMPy's own simulate_fmu, the same start values: every output of the FMI 3.0 FMU equals
    its FMI 2.0 twin's within 1e-12 over 3 s; the wheel_speeds array equals w1..w4."""
    md2 = read_model_description(str(built_fmus[model]))
    start = _inputs(md2)
    outputs = [v.name for v in md2.modelVariables if v.causality == "output"]
    run = {version: simulate_fmu(str(fmu), start_values=start, stop_time=3.0, step_size=0.01,
                                 output_interval=0.01, fmi_type="CoSimulation",
                                 output=outputs + (["wheel_speeds"] * (version == 3 and
                                                   "w1" in outputs and model.endswith("2Wheel"))))
           for version, fmu in ((2, built_fmus[model]), (3, fmi3_fmus[model]))}
    assert len(run[2]) == len(run[3]) > 250
    worst = max(np.abs(run[3][n].astype(float) - run[2][n].astype(float)).max() for n in outputs)
    assert worst <= AGREE, (model, worst)
    assert any(np.abs(run[2][n].astype(float)).max() > 0.01 for n in outputs), model  # not all 0
    if "wheel_speeds" in run[3].dtype.names:
        wheels = np.column_stack([run[3][f"w{i}"] for i in range(1, 5)])
        assert np.array_equal(run[3]["wheel_speeds"], wheels)


def _plain_host(tmp_path) -> Path:
    if shutil.which("gcc") is None:
        missing("gcc is needed (apt-get install gcc)")
    host = tmp_path / "plain_host3"
    subprocess.run(["gcc", "-O1", "-o", str(host), str(ROOT / "tests" / "hosts" / "plain_host3.c"),
                    "-ldl"], check=True)
    return host


def _host_command(host, fmi3_fmus, tmp_path) -> list[str]:
    folder = Path(extract(str(fmi3_fmus["PoseIntegrator"]), str(tmp_path / "fmu")))
    md = read_model_description(str(folder))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    return [str(host), str(folder / "binaries" / "x86_64-linux" / "PoseIntegrator.so"), md.guid,
            str(folder / "resources") + "/", str(vrs["vx"]), "0.5", str(vrs["x"])]


@pytest.mark.heavy(6)
def test_a_plain_c_fmi3_host_runs_it_under_valgrind(fmi3_fmus, tmp_path):
    """Nothing set (PATH only), the FMU's own Python; no invalid read or write from loading
    the FMU to the host's exit (main returns without dlclose)."""
    if shutil.which("valgrind") is None:
        missing("valgrind is needed (apt-get install valgrind)")
    command = _host_command(_plain_host(tmp_path), fmi3_fmus, tmp_path)
    proc = subprocess.run(["valgrind", "--error-exitcode=9", *command], capture_output=True,
                          text=True, timeout=300, env={"PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in proc.stderr, proc.stderr[-3000:]
    assert proc.stdout.split()[0] == "RAN", proc.stdout
    assert float(proc.stdout.split()[1]) == pytest.approx(0.5, abs=1e-12)   # 0.5 m/s for 1 s


def test_a_plain_c_fmi3_host_runs_it_where_no_python_exists(fmi3_fmus, tmp_path):
    """Every Python installation and libpython hidden (a private mount namespace): the FMU
    starts the Python it carries."""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        missing("hiding Python needs root and unshare (a mount namespace)")
    command = _host_command(_plain_host(tmp_path), fmi3_fmus, tmp_path)
    proc = subprocess.run(_hidden(["env", "-i", "PATH=/usr/bin:/bin", *command],
                                  _python_places()), capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, (proc.stdout, proc.stderr[-3000:])
    assert proc.stdout.split()[0] == "RAN", proc.stdout
    assert float(proc.stdout.split()[1]) == pytest.approx(0.5, abs=1e-12)


def _chain(folder, fmu_dir, name, master_name, tolerance=None, **fmus):
    models = {"source": "VelocitySource", "c2w": "Center2Wheel", "w2c": "Wheel2Center",
              "pose": "PoseIntegrator"}
    models.update(fmus)
    path = write_scenario(folder, name, CHAIN.format(name=name, **models))
    graph = prepare(path, master_name=master_name, tolerance=tolerance, fmu_dir=fmu_dir)
    return graph, master.simulate(graph, graph.scenario.experiment)


@pytest.mark.parametrize("master_name, tolerance", [("gauss-seidel", None), ("jacobi", None),
                                                    ("quadratic", None), ("adaptive", 1e-5)])
def test_a_mixed_fmi2_fmi3_scenario_matches_the_all_fmi2_run(fmu_dir, fmi3_fmus, tmp_path,
                                                             master_name, tolerance):
    """c2w and pose from fmus/fmi3/, nothing declared: the same rows as all FMI 2.0 (quadratic
    and adaptive roll the FMI 3.0 instances back with fmi3Get/SetFMUState)."""
    graph, mixed = _chain(tmp_path, fmu_dir, "mixed", master_name, tolerance,
                          c2w="fmi3/Center2Wheel", pose="fmi3/PoseIntegrator")
    assert {i.name: i.model.fmiVersion for i in graph.instances} == {
        "source": "2.0", "c2w": "3.0", "w2c": "2.0", "pose": "3.0"}
    _, plain = _chain(tmp_path, fmu_dir, "plain", master_name, tolerance)
    assert np.array_equal(mixed.time, plain.time) and len(plain.time) > 100
    for name in ("pose.x", "pose.y", "pose.theta", "c2w.w1", "c2w.w4", "w2c.vx"):
        assert np.abs(np.asarray(mixed[name]) - np.asarray(plain[name])).max() <= AGREE, name
    assert abs(plain.final("pose.x") - 1.0) > 0.05       # the car moved


def test_an_array_connection_is_refused_with_the_scalars_named(fmu_dir, fmi3_fmus, tmp_path):
    text = CHAIN.format(name="array", source="VelocitySource", c2w="fmi3/Center2Wheel",
                        w2c="Wheel2Center", pose="PoseIntegrator").replace(
        "[c2w.w1, w2c.w1]", "[c2w.wheel_speeds, w2c.w1]")
    with pytest.raises(ScenarioError) as err:
        prepare(write_scenario(tmp_path, "array", text), fmu_dir=fmu_dir)
    assert "a Float64 array [4]" in str(err.value) and "w1..w4" in str(err.value)


def test_the_fmi3_build_is_reproducible(fmi3_fmus, tmp_path):
    """Built again in a child (a build must not meet a slave module this worker has loaded
    by running the FMU): the same bytes."""
    code = ("import sys; from mecanum_fmu.models.build3 import build_fmu3; "
            "print(build_fmu3('Wheel2Center', sys.argv[1]))")
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    again = Path(proc.stdout.splitlines()[-1])
    assert again.read_bytes() == fmi3_fmus["Wheel2Center"].read_bytes()


def test_ssp_export_and_import_keep_the_fmi3_components(fmu_dir, fmi3_fmus, tmp_path):
    """export-ssp carries the FMI 3.0 FMUs; the SSP read back runs them to the same rows as
    the scenario it came from; the array output has no SSP 1.0 connector."""
    graph, direct = _chain(tmp_path, fmu_dir, "mixed", "gauss-seidel", None,
                           c2w="fmi3/Center2Wheel", pose="fmi3/PoseIntegrator")
    ssp = export_ssp(graph, tmp_path / "mixed.ssp")
    with zipfile.ZipFile(ssp) as zf:
        ssd = zf.read("SystemStructure.ssd").decode()
    assert 'startElement="c2w" startConnector="w1"' in ssd and "wheel_speeds" not in ssd
    back = prepare(ssp, master_name="gauss-seidel", fmu_dir=fmu_dir)
    assert {i.name: i.model.fmiVersion for i in back.instances} == {
        "source": "2.0", "c2w": "3.0", "w2c": "2.0", "pose": "3.0"}
    again = master.simulate(back, back.scenario.experiment)
    for name in ("pose.x", "pose.y", "pose.theta"):
        assert np.array_equal(np.asarray(again[name]), np.asarray(direct[name])), name


def test_a_string_parameter_is_baked_into_the_fmi3_fmu(fmi3_fmus, tmp_path):
    """What export-ssp does for hosts that do not set Strings: the value as the FMU's default,
    run by FMPy in a fresh process (the in-process module of the unbaked FMU is not reused)."""
    from mecanum_fmu.interop.ssp_bake import bake
    baked = tmp_path / "VelocitySource.fmu"
    source = fmi3_fmus["VelocitySource"]
    baked.write_bytes(bake(source.read_bytes(), {"vx_expr": "0.25"}, reuse=source))
    assert validate_fmu(str(baked)) == []
    md = read_model_description(str(baked))
    assert next(v.start for v in md.modelVariables if v.name == "vx_expr") == "0.25"
    code = ("import sys; from fmpy import simulate_fmu; r = simulate_fmu(sys.argv[1], "
            "stop_time=1.0, output_interval=0.1, output=['vx']); print(r['vx'].min(), r['vx'].max())")
    proc = subprocess.run([sys.executable, "-c", code, str(baked)], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert [float(v) for v in proc.stdout.split()] == [0.25, 0.25]


@pytest.mark.parametrize("host", ["ecos", "ecos-cli"])
def test_ecos_runs_an_all_fmi3_ssp_like_our_jacobi_master(fmu_dir, fmi3_fmus, tmp_path, host):
    """Ecos (ecospy, and its `ecos` program: no Python host) imports FMI 3.0 FMUs: the SSP of
    an all-FMI-3.0 chain ends where our Jacobi master ends (ecos-cli: up to its CSV's 6
    decimals)."""
    path = write_scenario(tmp_path, "all3", CHAIN.format(
        name="all3", source="fmi3/VelocitySource", c2w="fmi3/Center2Wheel",
        w2c="fmi3/Wheel2Center", pose="fmi3/PoseIntegrator"))
    graph = prepare(path, master_name="jacobi", fmu_dir=fmu_dir)
    names = compared_outputs(graph)
    assert "pose.x" in names
    ours = ours_jacobi(graph, names).values
    exp = graph.scenario.experiment
    theirs = run_host_or_skip(host, export_ssp(graph, tmp_path / "all3.ssp"),
                              start=exp.start_time, stop=exp.stop_time, step=exp.step_size,
                              variables=names)
    tolerance = CSV_TOLERANCE / 2 + 1e-12 if host == "ecos-cli" else 1e-12
    for name in names:
        assert abs(theirs.values[name] - ours[name]) <= tolerance, (name, theirs.values, ours)


@pytest.mark.parametrize("master_name, tolerance", [("quadratic", None), ("adaptive", 1e-6)])
def test_the_estimate_and_tolerance_are_the_same_with_fmi3_components(
        fmu_dir, fmi3_fmus, tmp_path, master_name, tolerance):
    """runner.run's summary: the error estimate (its coarse re-runs roll FMI 3.0 instances
    too) and, with --tolerance, the steps the adaptive master took, as for all FMI 2.0."""
    summaries = []
    for name, fmus in (("mixed", {"c2w": "fmi3/Center2Wheel", "pose": "fmi3/PoseIntegrator",
                                  "w2c": "fmi3/Wheel2Center"}), ("plain", {})):
        models = {"source": "VelocitySource", "c2w": "Center2Wheel", "w2c": "Wheel2Center",
                  "pose": "PoseIntegrator", **fmus}
        path = write_scenario(tmp_path, name, CHAIN.format(name=name, **models))
        graph = prepare(path, master_name=master_name, tolerance=tolerance, fmu_dir=fmu_dir)
        run(graph, tmp_path / name, plots=False)
        summaries.append(json.loads((tmp_path / name / "summary.json").read_text()))
    mixed, plain = summaries
    assert mixed["error_estimate"] == plain["error_estimate"]
    assert isinstance(plain["error_estimate"]["pose.x"]["end"], float)
    assert mixed.get("steps_taken") == plain.get("steps_taken")
    assert mixed["end_pose"] == plain["end_pose"]


def test_cross_check_says_libcosim_cannot_load_fmi3(fmu_dir, fmi3_fmus):
    """libcosimpy 0.0.6 fails on an SSP with an FMI 3.0 FMU with a bare assertion; the row
    says why instead, and names the FMI 3.0 components."""
    graph = prepare(ROOT / "scenarios" / "fmi3" / "circle_mixed.yaml", master_name="jacobi",
                    fmu_dir=fmu_dir)
    row = cross_check(graph, hosts=("libcosim",)).rows[0]
    assert row.run is None and not row.missing
    assert "cannot load FMI 3.0 FMUs and 'c2w', 'pose' are FMI 3.0" in row.problem


HOST3 = r'''
import ctypes, os, sys, zipfile, tempfile
fmu, token = sys.argv[1:3]
folder = tempfile.mkdtemp(dir=os.environ.get("TMPDIR"))
zipfile.ZipFile(fmu).extractall(folder)
lib = ctypes.CDLL(os.path.join(folder, "binaries", "x86_64-linux", "PoseIntegrator.so"))
LOG = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)
messages = []
log = LOG(lambda env, status, category, message: messages.append(message.decode()))
f = lib.fmi3InstantiateCoSimulation
f.restype = ctypes.c_void_p
f.argtypes = [ctypes.c_char_p] * 3 + [ctypes.c_bool] * 4 + [ctypes.c_void_p, ctypes.c_size_t,
                                                           ctypes.c_void_p, LOG, ctypes.c_void_p]
c = f(b"pose", token.encode(), (folder + "/resources/").encode(), 0, 1, 0, 0, None, 0, None,
      log, None)
if c:
    lib.fmi3FreeInstance(ctypes.c_void_p(c))
print("RAN" if c else "REFUSED", " | ".join(messages))
'''


@pytest.mark.parametrize("host", sorted(PYTHONS))
def test_a_python_host_runs_the_fmi3_fmu_or_refuses_it_clearly(fmi3_fmus, tmp_path, host):
    """As for FMI 2.0: a Python 3.11 host runs it in its own interpreter (its ctypes' libffi
    serves); another version gets the loader's message through fmi3's log callback and NULL."""
    python = PYTHONS[host]
    if not python.is_file():
        missing(f"{python} not installed")
    md = read_model_description(str(fmi3_fmus["PoseIntegrator"]))
    script = tmp_path / "host3.py"
    script.write_text(HOST3)
    proc = subprocess.run([str(python), "-I", str(script), str(fmi3_fmus["PoseIntegrator"]),
                           md.guid], capture_output=True, text=True, timeout=120,
                          env={"PATH": "/usr/bin:/bin", "TMPDIR": str(tmp_path)})
    assert proc.returncode == 0, proc.stderr[-2000:]
    version = subprocess.run([str(python), "-c", "import sys; print(sys.version_info[:2])"],
                             capture_output=True, text=True).stdout.strip()
    if version == "(3, 11)":
        assert proc.stdout.startswith("RAN"), proc.stdout
    else:
        running = version[1:-1].replace(", ", ".")
        assert proc.stdout.startswith("REFUSED"), proc.stdout
        assert f"bundles Python 3.11, but the process already runs Python {running}." \
            in proc.stdout, proc.stdout


def test_a_failure_names_the_fmi3_function(fmu_dir, fmi3_fmus):
    """The stepping code names FMI 2.0 functions; a failure of an FMI 3.0 instance says its
    own (fmi3GetFMUState, not fmi2GetFMUstate)."""
    from mecanum_fmu.master.instance import RunningInstance
    graph = prepare(ROOT / "scenarios" / "fmi3" / "circle_mixed.yaml", fmu_dir=fmu_dir)
    names = {}
    for name in ("c2w", "w2c"):
        r = RunningInstance(graph.instance(name))
        names[name] = [r.function_name(f) for f in ("fmi2GetFMUstate", "fmi2SetFMUstate",
                                                     "fmi2FreeFMUstate", "get")]
        r.free()
    assert names["c2w"] == ["fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState", "get"]
    assert names["w2c"] == ["fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate", "get"]


def test_an_fmi3_enumeration_is_read_and_set_as_int64(tmp_path_factory, tmp_path):
    """FMI 3.0 gets and sets an Enumeration as Int64 (the Reference FMUs' Feedthrough records
    its Enumeration_output by default; read as Int32, the run failed: 'Get Int32 is not
    allowed for value reference 34'). A start value, a link and the default recording."""
    fmu = mode_fmu3(tmp_path_factory.mktemp("mode_fmu3"))
    scenario = write_scenario(tmp_path, "modes", f"""\
name: modes
experiment: {{start_time: 0.0, stop_time: 1.0, step_size: 0.1, master: gauss-seidel}}
components:
  a: {{fmu: {fmu}, parameters: {{mode_in: 2}}}}
  b: {{fmu: {fmu}}}
connections:
  - [a.mode, b.mode_in]
""")
    graph = prepare(scenario)
    assert {str(p.ref): p.type for p in graph.recorded} == {
        "a.mode": "Integer", "a.y": "Real", "a.count": "Integer",
        "b.mode": "Integer", "b.y": "Real", "b.count": "Integer"}
    results = master.simulate(graph, graph.scenario.experiment)
    assert results.complete
    steps = np.arange(len(results.time))
    np.testing.assert_array_equal(results["a.count"], steps)     # Int32 beside the Int64s
    np.testing.assert_array_equal(results["a.mode"][1:], 2)      # its start value, set
    np.testing.assert_array_equal(results["b.mode"][1:], 2)      # a.mode read, b.mode_in set
    np.testing.assert_array_equal(results["b.y"][1:], 2.0)
