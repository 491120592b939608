"""FMUs that load in any host with nothing set (no LD_PRELOAD anywhere): the binaries name the
libpython they were built for (needed entry + runpath), a non-Python host (Ecos' `ecos`
program) runs a scenario whose source is not at its defaults, a host that ignores String
parameters (libcosim on an SSP stripped of them) still runs the scenario's profile, and a
Python host on a statically linked interpreter (Debian's /usr/bin/python3) runs the FMUs in its
own interpreter."""
import os
import subprocess
import zipfile
from pathlib import Path

import pytest

from helpers import CHAIN_CONNECTIONS, run_host_or_skip, write_scenario
from mecanum_fmu.interop.ssp_write import export_ssp
from mecanum_fmu.models.link import binary_needs, build_link
from mecanum_fmu.runner import prepare

STRAIGHT = """\
name: straight
experiment: {start_time: 0.0, stop_time: 10.0, step_size: 0.05, master: jacobi}
components:
  source: {fmu: VelocitySource, parameters: {vx_expr: "0.5", vy_expr: "0", w_expr: "0"}}
  c2w: {fmu: Center2Wheel}
  w2c: {fmu: Wheel2Center}
  pose: {fmu: PoseIntegrator, parameters: {x0: 5.0}}
""" + CHAIN_CONNECTIONS
# vx = 0.5 m/s for 10 s from x0 = 5, no turning: the end point is (10, 0) exactly in any
# master (the twist is constant); with the defaults (sin t, cos t) it would be (6.84, -0.54).
END = {"pose.x": 10.0, "pose.y": 0.0}


def _no_preload():
    if "LD_PRELOAD" in os.environ:
        pytest.fail("LD_PRELOAD is set in the test environment; these tests need none")


def _run(host, ssp):
    return run_host_or_skip(host, ssp, start=0.0, stop=10.0, step=0.05, variables=sorted(END))


@pytest.fixture(scope="module")
def straight(tmp_path_factory, fmu_dir):
    folder = tmp_path_factory.mktemp("straight")
    graph = prepare(write_scenario(folder, "straight", STRAIGHT),
                    fmu_dir=fmu_dir)
    return folder, export_ssp(graph, folder / "straight.ssp")


def test_every_binary_names_the_libpython_it_was_built_for(built_fmus):
    link = build_link()
    if link is None:
        pytest.skip("this interpreter has no shared libpython to link to")
    for name, fmu in built_fmus.items():
        with zipfile.ZipFile(fmu) as zf:
            binary = zf.read(f"binaries/linux64/{name}.so")
        needs = binary_needs(binary)
        assert needs is not None and needs.soname == link.soname, name
        assert needs.runpath == link.folder and needs.found == link.path, name


def test_ecos_program_runs_a_non_default_source_with_nothing_preloaded(straight):
    _no_preload()
    run = _run("ecos-cli", straight[1])
    for name, value in END.items():
        assert run.values[name] == pytest.approx(value, abs=1e-5), run.values


def _strip_strings(ssp: Path, dest: Path) -> Path:
    """The SSP with every String parameter binding removed (what OMSimulator does)."""
    from xml.etree import ElementTree as ET
    from mecanum_fmu.interop.ssp import q
    with zipfile.ZipFile(ssp) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    root = ET.fromstring(members["SystemStructure.ssd"])
    removed = 0
    for params in root.iter(q("ssv", "Parameters")):
        for param in list(params):
            if param.find(q("ssv", "String")) is not None:
                params.remove(param)
                removed += 1
    assert removed == 3          # vx_expr, vy_expr, w_expr
    members["SystemStructure.ssd"] = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    assert b"vx_expr" not in members["SystemStructure.ssd"].split(b"<ssd:Connectors")[0]
    with zipfile.ZipFile(dest, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return dest


def test_a_host_that_ignores_strings_still_runs_the_scenarios_profile(straight):
    _no_preload()
    stripped = _strip_strings(straight[1], straight[0] / "stripped.ssp")
    run = _run("libcosim", stripped)
    for name, value in END.items():
        assert run.values[name] == pytest.approx(value, abs=1e-9), run.values


HOST = r'''
import ctypes, os, sys, zipfile, tempfile, pathlib
fmu, guid, name = sys.argv[1], sys.argv[2], sys.argv[3]
folder = tempfile.mkdtemp()
zipfile.ZipFile(fmu).extractall(folder)
lib = ctypes.CDLL(os.path.join(folder, "binaries", "linux64", name + ".so"))
LOG = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                       ctypes.c_char_p)
class Callbacks(ctypes.Structure):
    _fields_ = [("logger", LOG), ("allocateMemory", ctypes.c_void_p),
                ("freeMemory", ctypes.c_void_p), ("stepFinished", ctypes.c_void_p),
                ("componentEnvironment", ctypes.c_void_p)]
libc = ctypes.CDLL(None)
callbacks = Callbacks(LOG(lambda *a: None), ctypes.cast(libc.calloc, ctypes.c_void_p),
                      ctypes.cast(libc.free, ctypes.c_void_p), None, None)
lib.fmi2Instantiate.restype = ctypes.c_void_p
lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                                ctypes.POINTER(Callbacks), ctypes.c_int, ctypes.c_int]
resources = pathlib.Path(folder, "resources").as_uri().encode()
c = lib.fmi2Instantiate(b"pose", 1, guid.encode(), resources, ctypes.byref(callbacks), 0, 0)
assert c, "fmi2Instantiate failed"
for f in ("fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode",
          "fmi2DoStep", "fmi2SetReal", "fmi2GetReal"):
    getattr(lib, f).argtypes = None
c = ctypes.c_void_p(c)
lib.fmi2SetupExperiment(c, 0, ctypes.c_double(0.0), ctypes.c_double(0.0), 0, ctypes.c_double(1.0))
lib.fmi2EnterInitializationMode(c); lib.fmi2ExitInitializationMode(c)
vr = (ctypes.c_uint * 1)(int(sys.argv[4])); one = (ctypes.c_double * 1)(0.5)
lib.fmi2SetReal(c, (ctypes.c_uint * 1)(int(sys.argv[5])), 1, one)
for k in range(10):
    assert lib.fmi2DoStep(c, ctypes.c_double(k * 0.1), ctypes.c_double(0.1), 1) == 0
out = (ctypes.c_double * 1)()
lib.fmi2GetReal(c, vr, 1, out)
print(out[0], any(m.startswith("mecanum_fmu_pose_integrator") for m in sys.modules))
'''


def test_a_statically_linked_python_host_runs_the_fmu_in_its_own_interpreter(tmp_path,
                                                                               built_fmus):
    """Debian's /usr/bin/python3 links libpython statically; the FMU's needed libpython is
    mapped but its symbols bind to the host: the slave runs in the host's interpreter."""
    _no_preload()
    python = Path("/usr/bin/python3")
    if not python.is_file() or not build_link():
        pytest.skip("no /usr/bin/python3 or no shared libpython here")
    ldd = subprocess.run(["ldd", str(python)], capture_output=True, text=True)
    if "libpython" in ldd.stdout:        # (its sysconfig says Py_ENABLE_SHARED=1 regardless)
        pytest.skip("/usr/bin/python3 links libpython dynamically here")
    venv = tmp_path / "venv"
    subprocess.run([str(python), "-m", "venv", "--without-pip", str(venv)], check=True)
    from fmpy import read_model_description
    fmu = built_fmus["PoseIntegrator"]
    md = read_model_description(str(fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    script = tmp_path / "host.py"
    script.write_text(HOST)
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONPATH")}
    proc = subprocess.run([str(venv / "bin" / "python"), str(script), str(fmu), md.guid,
                           "PoseIntegrator", str(vrs["x"]), str(vrs["vx"])],
                          capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    x, in_host = proc.stdout.split()
    assert float(x) == pytest.approx(0.5, abs=1e-12)      # 0.5 m/s for 1 s
    assert in_host == "True"
