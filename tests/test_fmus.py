"""The four built FMUs: standard conformance, model structure, reproducibility, behaviour.

Process rules (pythonfmu): every FMU is loaded from ONE extraction folder per content
(``mecanum_fmu.runtime.RUNTIME.extracted``), the shared library is never unloaded (only
fmi2FreeInstance, never fmpy's freeInstance/freeLibrary), and simulate_fmu always gets an
instance created here, so it never extracts or unloads anything itself.
"""
import io
import json
import math
import os
import re
import subprocess
import sys
import zipfile
from contextlib import contextmanager
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.validation import validate_fmu

import mecanum_fmu
from mecanum_fmu.runtime import RUNTIME
extracted = RUNTIME.extracted

MODELS = ("VelocitySource", "Center2Wheel", "Wheel2Center", "PoseIntegrator", "PathFollower")

# docs/spec.md (Parameters, Kinematics, Pose integration): seed geometry and the variables of
# each block.
ALPHA, L0, W0, R0 = math.pi / 4, 0.16, 0.12, 0.06
OUTPUTS = {"VelocitySource": ("vx", "vy", "w"),
           "Center2Wheel": ("w1", "w2", "w3", "w4"),
           "Wheel2Center": ("vx", "vy", "w", "icr_x", "icr_y", "has_icr"),
           "PoseIntegrator": ("x", "y", "theta"),
           "PathFollower": ("vx", "vy", "w")}
DIRECT_DEPENDENCIES = {"VelocitySource": (),
                       "Center2Wheel": ("vx", "vy", "w"),
                       "Wheel2Center": ("w1", "w2", "w3", "w4"),
                       "PoseIntegrator": (),
                       "PathFollower": ("x", "y", "theta")}
UNIT_OF = {"vx": "m/s", "vy": "m/s", "w": "rad/s",
           "w1": "rad/s", "w2": "rad/s", "w3": "rad/s", "w4": "rad/s",
           "alpha": "rad", "theta": "rad", "theta0": "rad",
           "L": "m", "W": "m", "R": "m", "x": "m", "y": "m", "x0": "m", "y0": "m",
           "icr_x": "m", "icr_y": "m", "w_max": "rad/s",
           "dR1": "m", "dR2": "m", "dR3": "m", "dR4": "m",
           "k_pos": "1/s", "k_theta": "1/s"}
BASE_UNITS = {"m": {"m": 1}, "m/s": {"m": 1, "s": -1},
              "rad": {"rad": 1}, "rad/s": {"rad": 1, "s": -1}, "1/s": {"s": -1}}
SI_BASES = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


# ------------------------------------------------------- reference formulas of docs/spec.md

def spec_inverse(vx, vy, w, alpha=ALPHA, L=L0, W=W0, R=R0):
    c = math.cos(alpha) / math.sin(alpha)
    k = L + W * c
    return ((-c * vx + vy + k * w) / R, (c * vx + vy - k * w) / R,
            (-c * vx + vy - k * w) / R, (c * vx + vy + k * w) / R)


def spec_forward(w1, w2, w3, w4, alpha=ALPHA, L=L0, W=W0, R=R0):
    t = math.sin(alpha) / math.cos(alpha)
    k = L + W / t
    return (R * t / 4 * (-w1 + w2 - w3 + w4), R / 4 * (w1 + w2 + w3 + w4),
            R / (4 * k) * (w1 - w2 - w3 + w4))


# ------------------------------------------------------------------ loading helpers

@contextmanager
def instance(path, name, logging_on=False):
    """An instantiated FMU2Slave on the shared extraction; yields (fmu, md, vr, messages)."""
    unzipdir = extracted(path)
    md = read_model_description(unzipdir)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    messages = []

    def on_log(_env, _instance, status, category, message):
        messages.append((status, (category or b"").decode(), (message or b"").decode()))
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(on_log)
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    fmu.instantiate(loggingOn=logging_on, callbacks=callbacks)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    try:
        yield fmu, md, vr, messages
    finally:
        fmu._functions["fmi2FreeInstance"](fmu.component)   # never unload the library
        del callbacks


def simulate(path, name, **kwargs):
    """fmpy.simulate_fmu on an instance made here (fmpy then neither extracts nor unloads)."""
    with instance(path, name) as (fmu, md, _vr, _messages):
        kwargs.setdefault("stop_time", 10.0)
        kwargs.setdefault("output_interval", 0.1)
        return simulate_fmu(extracted(path), model_description=md, fmu_instance=fmu, **kwargs)


def constant_input(**values):
    names = list(values)
    dtype = [("time", np.float64)] + [(n, np.float64) for n in names]
    rows = [(t, *(values[n] for n in names)) for t in (0.0, 10.0)]
    return np.array(rows, dtype=dtype)


def initialize(fmu, start=0.0):
    fmu.setupExperiment(startTime=start)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()


def check_times(result, step=0.1, stop=10.0):
    n = int(round(stop / step))
    assert len(result) == n + 1
    np.testing.assert_allclose(result["time"], np.arange(n + 1) * step, rtol=0, atol=1e-9)


# ------------------------------------------------------------------ conformance

@pytest.mark.parametrize("model", MODELS)
def test_validate_fmu_finds_no_problems(built_fmus, model):
    assert validate_fmu(str(built_fmus[model])) == []


def test_fmpy_validate_command_finds_no_problems(built_fmus):
    procs = {m: subprocess.Popen([sys.executable, "-m", "fmpy", "validate", str(built_fmus[m])],
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for m in MODELS}
    for model, proc in procs.items():
        out, _ = proc.communicate(timeout=60)
        assert proc.returncode == 0, (model, out)
        assert "No problems found" in out, (model, out)


@pytest.mark.parametrize("model", MODELS)
def test_model_name_and_identifier(built_fmus, model):
    md = read_model_description(str(built_fmus[model]))
    assert md.modelName == model
    assert md.coSimulation.modelIdentifier == model
    assert md.fmiVersion == "2.0"


@pytest.mark.parametrize("model", MODELS)
def test_output_dependencies(built_fmus, model):
    md = read_model_description(str(built_fmus[model]))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert sorted(outputs) == sorted(OUTPUTS[model])
    assert sorted(u.variable.name for u in md.outputs) == sorted(outputs)
    for unknown in md.outputs:
        assert sorted(d.name for d in unknown.dependencies) == sorted(DIRECT_DEPENDENCIES[model])
    # Every output is an InitialUnknown (and nothing else is).
    assert sorted(u.variable.name for u in md.initialUnknowns) == sorted(outputs)


@pytest.mark.parametrize("model", MODELS)
def test_empty_dependencies_are_explicit(built_fmus, model):
    """FMI 2.0: a missing 'dependencies' attribute means 'depends on everything'; an output
    that depends on nothing must say dependencies=""."""
    with zipfile.ZipFile(built_fmus[model]) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    variables = list(root.find("ModelVariables"))
    for unknown in root.find("ModelStructure/Outputs"):
        assert "dependencies" in unknown.attrib
        names = sorted(variables[int(i) - 1].get("name") for i in unknown.get("dependencies").split())
        assert names == sorted(DIRECT_DEPENDENCIES[model])


@pytest.mark.parametrize("model", MODELS)
def test_descriptions_and_units(built_fmus, model):
    md = read_model_description(str(built_fmus[model]))
    assert md.description and md.description.strip()
    units = {u.name: u for u in md.unitDefinitions}
    for v in md.modelVariables:
        assert v.description and v.description.strip(), v.name
        if v.type == "Real":                     # every Real here is a physical quantity
            assert v.unit == UNIT_OF[v.name], v.name
            assert v.unit in units, v.name
    for name, unit in units.items():
        expected = BASE_UNITS[name]
        for base in SI_BASES:
            assert int(getattr(unit.baseUnit, base) or 0) == expected.get(base, 0), (name, base)


@pytest.mark.parametrize("model", MODELS)
def test_default_experiment_and_capabilities(built_fmus, model):
    md = read_model_description(str(built_fmus[model]))
    assert float(md.defaultExperiment.startTime) == 0.0
    assert float(md.defaultExperiment.stopTime) == 10.0
    assert md.coSimulation.canGetAndSetFMUstate is True
    assert md.coSimulation.canSerializeFMUstate is True


@pytest.mark.parametrize("model", MODELS)
def test_entries_are_deflated(built_fmus, model):
    with zipfile.ZipFile(built_fmus[model]) as zf:
        infos = zf.infolist()
        assert infos
        for info in infos:
            assert info.compress_type == zipfile.ZIP_DEFLATED, info.filename
        assert zf.testzip() is None


def slave_scripts(path):
    with zipfile.ZipFile(path) as zf:
        names = zf.namelist()
        scripts = [n for n in names if re.fullmatch(r"resources/[^/]+\.py", n)]
        module = zf.read("resources/slavemodule.txt").decode().strip()
        return scripts, module, {n: zf.read(n).decode() for n in scripts}


def test_slave_scripts_are_uniquely_named_and_self_contained(built_fmus, tmp_path):
    modules = {}
    for model in MODELS:
        scripts, module, texts = slave_scripts(built_fmus[model])
        assert len(scripts) == 1, scripts
        assert scripts[0] == f"resources/{module}.py"
        text = texts[scripts[0]]
        assert not re.search(r"^\s*(from|import)\s+mecanum_fmu(\.|\s|$)", text, re.MULTILINE), model
        assert f"class {model}(" in text
        modules[model] = module
    assert len(set(modules.values())) == len(MODELS)
    # The script imports with only its own resources/ on the path: no mecanum_fmu package.
    for model in MODELS:
        res = tmp_path / model
        with zipfile.ZipFile(built_fmus[model]) as zf:
            for n in zf.namelist():
                if n.startswith("resources/"):
                    zf.extract(n, res)
    code = ("import importlib, sys\n"
            "for folder, module, model in %r:\n"
            "    sys.path.insert(0, folder)\n"
            "    m = importlib.import_module(module)\n"
            "    assert hasattr(m, model), model\n"
            "    sys.path.remove(folder)\n"
            "assert 'mecanum_fmu' not in sys.modules, 'imported the package'\n"
            "print('ok')\n") % [(str(tmp_path / m / "resources"), modules[m], m) for m in MODELS]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-I", "-c", code], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr


def test_every_slave_script_fmi2_and_fmi3_imports_without_the_package(built_fmus, fmi3_fmus,
                                                                     tmp_path):
    """Every bundled FMU of both versions: no line of its script imports mecanum_fmu (the
    Encoder's and Gyro's shared slaves/sampled.py imports blocks/sensors.py: inlined too), and
    the script imports in a child with only its resources/ and the site packages."""
    fmus = [*built_fmus.values(), *fmi3_fmus.values()]
    places = []
    for n, fmu in enumerate(fmus):
        scripts, module, texts = slave_scripts(fmu)
        assert scripts == [f"resources/{module}.py"], (fmu, scripts)
        lines = re.findall(r"^[ \t]*(?:from|import)[ \t]+mecanum_fmu\b.*$", texts[scripts[0]],
                           re.MULTILINE)
        assert lines == [], (fmu, lines)
        with zipfile.ZipFile(fmu) as zf:
            zf.extract(scripts[0], tmp_path / str(n))
        places.append((str(tmp_path / str(n) / "resources"), module, fmu.stem))
    assert len({module for _, module, _ in places}) == len(fmus)
    code = ("import importlib, sys\n"
            "for folder, module, model in %r:\n"
            "    sys.path.insert(0, folder)\n"
            "    assert hasattr(importlib.import_module(module), model), model\n"
            "    sys.path.remove(folder)\n"
            "assert 'mecanum_fmu' not in sys.modules, 'imported the package'\n"
            "print('ok')\n") % places
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-I", "-c", code], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]


def test_build_is_reproducible(built_fmus, tmp_path):
    """A second build, in a fresh process with another hash seed and an empty cache (the
    bundled Python's pieces made anew: stripped libpython, compiled stdlib), gives the same
    bytes."""
    src = Path(mecanum_fmu.__file__).resolve().parents[1]
    dest = tmp_path / "again"
    env = dict(os.environ, PYTHONPATH=str(src), PYTHONHASHSEED="12345",
               XDG_CACHE_HOME=str(tmp_path / "cache"))
    code = ("import sys; from mecanum_fmu.models.build import build_all; "
            "build_all(sys.argv[1])")
    subprocess.run([sys.executable, "-c", code, str(dest)], check=True, env=env, timeout=600)
    assert any((tmp_path / "cache" / "mecanum_fmu" / "runtime").iterdir())   # really made anew
    again = sorted(p.name for p in dest.iterdir())
    assert again == sorted(f"{m}.fmu" for m in built_fmus)    # every bundled FMU
    for model in built_fmus:
        assert (dest / f"{model}.fmu").read_bytes() == built_fmus[model].read_bytes(), model


def test_reused_members_are_the_bytes_a_fresh_compression_writes(tmp_path):
    """write_zip(reuse=) copies a member deflated in another archive instead of deflating it
    again (the bundled libpython): the archive is byte for byte the one written without."""
    import random
    from mecanum_fmu.storage import zip_bytes
    rng = random.Random(7)
    big = bytes(rng.getrandbits(8) for _ in range(200_000)) + b"abc" * 100_000
    members = {"b/libpython.so": big, "a/model.xml": b"<x/>" * 50, "c/stdlib.zip": b"z" * 999}
    old = tmp_path / "old.zip"
    old.write_bytes(zip_bytes({"b/libpython.so": big, "c/stdlib.zip": b"z" * 999,
                               "other": b"not in the new one"}, compresslevel=9))
    fresh = zip_bytes(members, compresslevel=9)
    assert zip_bytes(members, compresslevel=9, reuse=old) == fresh
    with zipfile.ZipFile(io.BytesIO(fresh)) as zf:
        assert {n: zf.read(n) for n in zf.namelist()} == members
    changed = dict(members, **{"b/libpython.so": big[:-1] + b"!"})      # same size, other CRC
    assert zip_bytes(changed, compresslevel=9, reuse=old) == zip_bytes(changed, compresslevel=9)


# ------------------------------------------------------------------ running alone

def test_velocity_source_default_is_the_seed(built_fmus):
    result = simulate(built_fmus["VelocitySource"], "vs_default")
    check_times(result)
    t = result["time"]
    np.testing.assert_allclose(result["vx"], np.sin(t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["vy"], np.cos(t), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(result["w"], 0.0)
    for row in result[::7]:
        assert row["vx"] == pytest.approx(math.sin(row["time"]), abs=1e-12)
        assert row["vy"] == pytest.approx(math.cos(row["time"]), abs=1e-12)


def test_velocity_source_expressions(built_fmus):
    result = simulate(built_fmus["VelocitySource"], "vs_expr",
                      start_values={"vx_expr": "2*t", "vy_expr": "t*t - 1", "w_expr": "0.25"})
    check_times(result)
    t = result["time"]
    np.testing.assert_allclose(result["vx"], 2 * t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["vy"], t * t - 1, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(result["w"], 0.25)


@pytest.mark.parametrize("twist", [(0.3, -0.2, 0.5), (-1.0, 0.4, -2.0)])
def test_center2wheel_is_spec_inverse(built_fmus, twist):
    vx, vy, w = twist
    result = simulate(built_fmus["Center2Wheel"], "c2w_run", input=constant_input(vx=vx, vy=vy, w=w))
    check_times(result)
    expected = spec_inverse(vx, vy, w)
    for i, name in enumerate(("w1", "w2", "w3", "w4")):
        np.testing.assert_allclose(result[name], expected[i], rtol=1e-12, atol=1e-12)


def test_center2wheel_uses_its_geometry_parameters(built_fmus):
    geometry = {"alpha": 0.6, "L": 0.2, "W": 0.1, "R": 0.05}
    result = simulate(built_fmus["Center2Wheel"], "c2w_geom", start_values=geometry,
                      input=constant_input(vx=0.3, vy=-0.2, w=0.5), stop_time=1.0)
    expected = spec_inverse(0.3, -0.2, 0.5, **geometry)
    assert expected != pytest.approx(spec_inverse(0.3, -0.2, 0.5))
    for i, name in enumerate(("w1", "w2", "w3", "w4")):
        np.testing.assert_allclose(result[name], expected[i], rtol=1e-12)


def test_wheel2center_is_spec_forward(built_fmus):
    wheels = (3.0, -1.0, 2.0, 5.0)     # inconsistent: a least-squares twist
    result = simulate(built_fmus["Wheel2Center"], "w2c_run",
                      input=constant_input(**dict(zip(("w1", "w2", "w3", "w4"), wheels))))
    check_times(result)
    expected = spec_forward(*wheels)
    for i, name in enumerate(("vx", "vy", "w")):
        np.testing.assert_allclose(result[name], expected[i], rtol=1e-12, atol=1e-14)
    # docs/spec.md, Instantaneous centre of rotation: the ICR is at (-vy/w, vx/w) in the body frame.
    vx, vy, w = expected
    assert w != 0.0
    np.testing.assert_array_equal(result["has_icr"], True)
    np.testing.assert_allclose(result["icr_x"], -vy / w, rtol=1e-12)
    np.testing.assert_allclose(result["icr_y"], vx / w, rtol=1e-12)


def test_wheel2center_pure_translation_has_no_icr(built_fmus):
    wheels = (2.0, -1.0, 2.0, -1.0)   # c*vx + vy pattern, w = 0 exactly
    result = simulate(built_fmus["Wheel2Center"], "w2c_trans", stop_time=1.0,
                      input=constant_input(**dict(zip(("w1", "w2", "w3", "w4"), wheels))))
    vx, vy, w = spec_forward(*wheels)
    assert w == 0.0 and vx != 0.0
    np.testing.assert_allclose(result["vx"], vx, rtol=1e-12)
    np.testing.assert_allclose(result["vy"], vy, rtol=1e-12)
    np.testing.assert_array_equal(result["w"], 0.0)
    np.testing.assert_array_equal(result["has_icr"], False)


def test_wheel2center_uses_its_geometry_parameters(built_fmus):
    geometry = {"alpha": 1.1, "L": 0.3, "W": 0.05, "R": 0.1}
    wheels = (3.0, -1.0, 2.0, 5.0)
    result = simulate(built_fmus["Wheel2Center"], "w2c_geom", start_values=geometry, stop_time=1.0,
                      input=constant_input(**dict(zip(("w1", "w2", "w3", "w4"), wheels))))
    expected = spec_forward(*wheels, **geometry)
    for i, name in enumerate(("vx", "vy", "w")):
        np.testing.assert_allclose(result[name], expected[i], rtol=1e-12)


def test_pose_integrator_follows_the_exact_arc(built_fmus):
    # vy = 1, w = 0.5 from the origin heading +Y: ICR at (-2, 0), radius 2, counter-clockwise.
    result = simulate(built_fmus["PoseIntegrator"], "pose_run",
                      input=constant_input(vx=0.0, vy=1.0, w=0.5))
    check_times(result)
    t = result["time"]
    np.testing.assert_allclose(result["theta"], 0.5 * t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["x"], 2.0 * (np.cos(0.5 * t) - 1.0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["y"], 2.0 * np.sin(0.5 * t), rtol=0, atol=1e-12)
    end = result[-1]
    assert (end["x"], end["y"]) == pytest.approx((2 * (math.cos(5) - 1), 2 * math.sin(5)), abs=1e-12)
    assert math.hypot(end["x"] + 2.0, end["y"]) == pytest.approx(2.0, abs=1e-12)


def test_pose_integrator_start_pose(built_fmus):
    # Facing world -X (theta0 = pi/2), forward motion moves along -x.
    result = simulate(built_fmus["PoseIntegrator"], "pose_start", stop_time=2.0,
                      start_values={"x0": 1.0, "y0": 2.0, "theta0": math.pi / 2},
                      input=constant_input(vx=0.0, vy=1.0, w=0.0))
    t = result["time"]
    np.testing.assert_allclose(result["x"], 1.0 - t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["y"], 2.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["theta"], math.pi / 2, rtol=0, atol=0)


# ------------------------------------------------------------------ all four at once

def test_all_four_in_one_process(built_fmus):
    h = 0.1
    with instance(built_fmus["VelocitySource"], "vs") as (vs, _, vs_vr, _), \
            instance(built_fmus["Center2Wheel"], "c2w") as (c2w, _, c2w_vr, _), \
            instance(built_fmus["Wheel2Center"], "w2c") as (w2c, _, w2c_vr, _), \
            instance(built_fmus["PoseIntegrator"], "pose") as (pose, _, pose_vr, _):
        for fmu in (vs, c2w, w2c, pose):
            initialize(fmu)
        twist_names = ("vx", "vy", "w")
        wheel_names = ("w1", "w2", "w3", "w4")

        vs.doStep(currentCommunicationPoint=0.0, communicationStepSize=h)
        twist = vs.getReal([vs_vr[n] for n in twist_names])
        assert twist == pytest.approx([math.sin(h), math.cos(h), 0.0], abs=1e-12)

        c2w.setReal([c2w_vr[n] for n in twist_names], twist)
        c2w.doStep(currentCommunicationPoint=0.0, communicationStepSize=h)
        wheels = c2w.getReal([c2w_vr[n] for n in wheel_names])
        assert wheels == pytest.approx(spec_inverse(*twist), rel=1e-12)
        assert wheels[0] == pytest.approx((math.cos(h) - math.sin(h)) / 0.06, rel=1e-12)
        assert wheels[1] == pytest.approx((math.cos(h) + math.sin(h)) / 0.06, rel=1e-12)

        w2c.setReal([w2c_vr[n] for n in wheel_names], wheels)
        w2c.doStep(currentCommunicationPoint=0.0, communicationStepSize=h)
        back = w2c.getReal([w2c_vr[n] for n in twist_names])
        assert back == pytest.approx(twist, abs=1e-12)

        pose.setReal([pose_vr[n] for n in twist_names], back)
        pose.doStep(currentCommunicationPoint=0.0, communicationStepSize=h)
        x, y, theta = pose.getReal([pose_vr[n] for n in ("x", "y", "theta")])
        assert (x, y, theta) == pytest.approx((h * math.sin(h), h * math.cos(h), 0.0), abs=1e-12)

        for fmu in (vs, c2w, w2c, pose):
            fmu.terminate()


def test_feedthrough_matches_declared_dependencies(built_fmus):
    """Center2Wheel/Wheel2Center outputs follow their inputs without a step (they declare a
    dependency on them); PoseIntegrator outputs do not (dependencies == [])."""
    with instance(built_fmus["Center2Wheel"], "c2w_ft") as (c2w, _, vr, _):
        initialize(c2w)
        c2w.setReal([vr["vx"], vr["vy"], vr["w"]], [0.3, -0.2, 0.5])
        got = c2w.getReal([vr[n] for n in ("w1", "w2", "w3", "w4")])
        assert got == pytest.approx(spec_inverse(0.3, -0.2, 0.5), rel=1e-12)
        c2w.terminate()
    with instance(built_fmus["Wheel2Center"], "w2c_ft") as (w2c, _, vr, _):
        initialize(w2c)
        w2c.setReal([vr[n] for n in ("w1", "w2", "w3", "w4")], [3.0, -1.0, 2.0, 5.0])
        got = w2c.getReal([vr[n] for n in ("vx", "vy", "w")])
        assert got == pytest.approx(spec_forward(3.0, -1.0, 2.0, 5.0), rel=1e-12)
        w2c.terminate()
    with instance(built_fmus["PoseIntegrator"], "pose_ft") as (pose, _, vr, _):
        initialize(pose)
        pose.setReal([vr["vx"], vr["vy"], vr["w"]], [1.0, 1.0, 1.0])
        assert pose.getReal([vr[n] for n in ("x", "y", "theta")]) == [0.0, 0.0, 0.0]
        pose.terminate()


# ------------------------------------------------------------------ failures at initialization
#
# pythonfmu 0.7.0 turns a Python exception inside an FMI call into fmi2Fatal without releasing
# the GIL state it took (handle_py_exception throws past PyGILState_Release); after two such
# failures with fmi2FreeInstance one process segfaults in the garbage collector. So each
# failing initialization runs alone in a fresh process (its own extraction, nothing shared).

FAILING_INIT = r"""
import json, sys, tempfile
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
path, name, value = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
unzipdir = extract(path, tempfile.mkdtemp())
md = read_model_description(unzipdir)
vr = {v.name: v.valueReference for v in md.modelVariables}
messages = []
def on_log(env, inst, status, category, message):
    messages.append((status, (category or b"").decode(), (message or b"").decode()))
cb = fmi2CallbackFunctions()
cb.logger = fmi2CallbackLoggerTYPE(on_log)
cb.allocateMemory, cb.freeMemory = defaultCallbacks.allocateMemory, defaultCallbacks.freeMemory
fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="failing")
fmu.instantiate(loggingOn=True, callbacks=cb)
if isinstance(value, str):
    fmu.setString([vr[name]], [value])
else:
    fmu.setReal([vr[name]], [value])
fmu.setupExperiment(startTime=0.0, stopTime=1.0)
error = None
try:
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
except Exception as exc:
    error = "%s: %s" % (type(exc).__name__, exc)
print(json.dumps({"error": error, "messages": messages}), flush=True)
import os
os._exit(0)   # no interpreter teardown with a failed pythonfmu instance still alive
"""


def failing_init(path, name, value):
    """Set one start value, initialize in a fresh process; return (error, log messages)."""
    proc = subprocess.run([sys.executable, "-c", FAILING_INIT, str(path), name, json.dumps(value)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    return report["error"], report["messages"]


@pytest.mark.parametrize("model, name, value", [
    ("Center2Wheel", "alpha", 0.0),
    ("Center2Wheel", "alpha", math.pi / 2),
    ("Center2Wheel", "L", 0.0),
    ("Center2Wheel", "R", -0.06),
    ("Wheel2Center", "alpha", 0.0),
    ("Wheel2Center", "W", -0.12),
    ("Wheel2Center", "R", float("nan")),
])
def test_invalid_geometry_fails_initialization(built_fmus, model, name, value):
    error, messages = failing_init(built_fmus[model], name, value)
    assert error is not None and error.startswith("FMICallException"), error
    assert "InitializationMode" in error
    errors = [m for status, _cat, m in messages if status >= 3]     # fmi2Error or fmi2Fatal
    assert any(re.search(rf"\b{name}\b", m) for m in errors), messages
    others = {"alpha", "L", "W", "R"} - {name}
    assert not any(re.search(rf"\bparameter {o}\b", m) for m in errors for o in others), messages


def test_valid_geometry_initializes_in_the_same_harness(built_fmus):
    """The harness above reports no error for a valid value (so its failures mean something)."""
    error, messages = failing_init(built_fmus["Center2Wheel"], "alpha", 0.3)
    assert error is None, (error, messages)


def test_valid_geometry_at_the_edge_initializes(built_fmus):
    result = simulate(built_fmus["Center2Wheel"], "edge_ok", stop_time=0.2,
                      start_values={"alpha": 0.01, "L": 1e-3, "W": 1e-3, "R": 1e-3},
                      input=constant_input(vx=0.0, vy=1e-3, w=0.0))
    np.testing.assert_allclose(result["w1"], 1.0, rtol=1e-12)


@pytest.mark.parametrize("name", ["vx_expr", "w_expr"])
def test_bad_expression_fails_initialization(built_fmus, tmp_path, name):
    marker = tmp_path / "pwned"
    bad = f"__import__('os').system('touch {marker}')"
    error, messages = failing_init(built_fmus["VelocitySource"], name, bad)
    assert error is not None and error.startswith("FMICallException"), error
    assert "InitializationMode" in error
    assert not marker.exists()
    errors = [m for status, _cat, m in messages if status >= 3]
    assert any("__import__" in m for m in errors), messages


def test_plain_import_expression_fails_initialization(built_fmus):
    error, _messages = failing_init(built_fmus["VelocitySource"], "vy_expr", "__import__('os')")
    assert error is not None and error.startswith("FMICallException"), error


def test_good_expression_in_the_same_harness(built_fmus):
    error, messages = failing_init(built_fmus["VelocitySource"], "vx_expr", "where(t < 2, 1, -1)")
    assert error is None, (error, messages)


# ------------------------------------------------------------------ FMU state

def test_pose_integrator_state_round_trip(built_fmus):
    h, n_before, n_after = 0.1, 4, 6
    names = ("x", "y", "theta")
    with instance(built_fmus["PoseIntegrator"], "pose_ref") as (ref, _, vr, _), \
            instance(built_fmus["PoseIntegrator"], "pose_probe") as (probe, _, _vr2, _):
        inputs = [vr["vx"], vr["vy"], vr["w"]]
        outs = [vr[n] for n in names]
        for fmu in (ref, probe):
            fmu.setReal(inputs, [0.2, 1.0, 0.5])
            initialize(fmu)

        reference = []
        for k in range(n_before + n_after):
            ref.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
            reference.append(ref.getReal(outs))

        for k in range(n_before):
            probe.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        state = probe.getFMUstate()
        serialized = probe.serializeFMUstate(state)
        assert isinstance(serialized, bytes) and serialized
        # Wander off: other inputs, more steps.
        probe.setReal(inputs, [-3.0, 0.0, -2.0])
        for k in range(n_before, n_before + 3):
            probe.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        assert probe.getReal(outs) != pytest.approx(reference[n_before + 2], abs=1e-3)

        probe.setFMUstate(state)
        assert probe.getReal(outs) == reference[n_before - 1]
        for k in range(n_before, n_before + n_after):
            probe.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
            assert probe.getReal(outs) == reference[k], k
        probe.freeFMUstate(state)

        # The serialized state restores the same point too.
        restored = probe.deSerializeFMUstate(serialized)
        probe.setFMUstate(restored)
        probe.freeFMUstate(restored)
        assert probe.getReal(outs) == reference[n_before - 1]
        probe.doStep(currentCommunicationPoint=n_before * h, communicationStepSize=h)
        assert probe.getReal(outs) == reference[n_before]
        for fmu in (ref, probe):
            fmu.terminate()


def test_without_a_compiler_the_build_says_its_fmus_are_not_self_contained(monkeypatch):
    """No gcc: `make fmus` still builds (plain pythonfmu FMUs) and its last line says what
    they then need, naming what is missing."""
    from mecanum_fmu.models import embed
    monkeypatch.setattr(embed.shutil, "which", lambda name: None)
    embed.runtime_or_none.cache_clear()
    try:
        assert embed.runtime_or_none() is None
        line = embed.summary()
        assert "NOT self-contained" in line and "gcc not found" in line, line
    finally:
        monkeypatch.undo()
        embed.runtime_or_none.cache_clear()
    assert embed.runtime_or_none() is not None
