"""Self-contained FMUs (models/embed.py): each carries its Python, so a host runs it with
nothing set - no LD_PRELOAD, PYTHONHOME, PYTHONPATH - whatever Python the machine has or lacks.

- Where no Python exists: a mount namespace (`unshare -m`, root) hides every Python
  installation and libpython; Ecos' `ecos` program (a non-Python host) runs our SSP there with
  a plain PATH and lands on our Jacobi master's result.
- With Debian's /usr/bin/python3 first on PATH (what crashed hosts before): the same.
- Python hosts (ctypes, so no package is needed): 3.11 (pyenv, and Debian's static build)
  runs the FMU in the host's own interpreter; 3.10, 3.12 and 3.13 get a clear message in the
  FMU's log from fmi2Instantiate, never a crash.
Under MECANUM_FMU_REQUIRE_TOOLS=1 a missing tool (ecos, unshare, a pyenv Python) fails.
"""
import copy
import glob
import os
import shlex
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from helpers import CHAIN_CONNECTIONS, ROOT, tool_missing as missing, write_scenario
from mecanum_fmu.interop.cross_check import CSV_TOLERANCE, compared_outputs, ours_jacobi
from mecanum_fmu.interop.other_hosts import (HostUnavailable, ecos_command, ecos_csv_values,
                                             ecos_libraries, ecos_program)
from mecanum_fmu.interop.ssp_write import export_ssp
from mecanum_fmu.models.link import binary_needs
from mecanum_fmu.runner import prepare

PYENV = Path("/root/.pyenv/versions")
TWIST = """\
name: twist
experiment: {start_time: 0.0, stop_time: 4.0, step_size: 0.02, master: jacobi}
components:
  source: {fmu: VelocitySource, parameters: {vx_expr: "0.4", vy_expr: "0.3*sin(2*t)", w_expr: "0.5*cos(t)"}}
  c2w: {fmu: Center2Wheel}
  w2c: {fmu: Wheel2Center}
  pose: {fmu: PoseIntegrator, parameters: {x0: 5, theta0: 0.3}}
""" + CHAIN_CONNECTIONS


def test_every_fmu_carries_its_python_and_no_link_to_the_builders(built_fmus):
    for name, fmu in built_fmus.items():
        with zipfile.ZipFile(fmu) as zf:
            names = set(zf.namelist())
            loader = binary_needs(zf.read(f"binaries/linux64/{name}.so"))
            real = binary_needs(zf.read(f"binaries/linux64/{name}.pythonfmu.so"))
        assert "resources/python/stdlib.zip" in names, name
        assert any(n.startswith("binaries/linux64/libpython3.") for n in names), name
        for needs in (loader, real):        # nothing points at the builder's Python
            assert needs.libpython is None and needs.runpath is None, (name, needs)
        assert fmu.stat().st_size <= 5_000_000, (name, fmu.stat().st_size)   # the budget


PROBE = r"""
import sys
stdlib, dynload, resources, module = sys.argv[1:5]
sys.path[:] = [stdlib, dynload, resources]
for name in list(sys.modules):       # start-up's one non-frozen package: from the bundle too
    if name.split(".")[0] == "encodings":
        del sys.modules[name]
before = set(sys.modules)            # builtin and frozen modules (inside libpython)
import encodings, pythonfmu
__import__(module)
bad = [n for n, m in sys.modules.items() if n not in before and getattr(m, "__file__", None)
       and getattr(m.__spec__, "origin", None) != "frozen"      # frozen: inside libpython
       and not m.__file__.startswith((stdlib, dynload, resources))]
print("outside:", bad)
"""


def test_each_slave_imports_from_its_bundled_stdlib_alone(built_fmus, tmp_path):
    """All ten FMUs: the slave and pythonfmu import with sys.path = the FMU's own stdlib zip,
    lib-dynload and resources, and nothing comes from elsewhere."""
    for name, fmu in built_fmus.items():
        folder = tmp_path / name
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(folder)
            module = zf.read("resources/slavemodule.txt").decode().strip()
        home = folder / "resources" / "python"
        proc = subprocess.run([sys.executable, "-I", "-S", "-c", PROBE, str(home / "stdlib.zip"),
                               str(home / "lib-dynload"), str(folder / "resources"), module],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, (name, proc.stderr[-2000:])
        assert proc.stdout.strip() == "outside: []", (name, proc.stdout)


@pytest.fixture(scope="session")
def ssps(fmu_dir, tmp_path_factory):
    """circle (h = 0.05) and a non-default twist: (ssp, graph, names, our Jacobi end values).
    Made once per test process: the heavy test that uses it runs apart from the others."""
    folder = tmp_path_factory.mktemp("travel")
    out = {}
    for name, path in (("circle", ROOT / "scenarios" / "circle.yaml"),
                       ("twist", write_scenario(folder, "twist", TWIST))):
        graph = prepare(path, master_name="jacobi", step_size=0.05 if name == "circle" else None,
                        fmu_dir=fmu_dir)
        names = compared_outputs(graph)
        out[name] = (export_ssp(graph, folder / f"{name}.ssp"), graph, names,
                     ours_jacobi(graph, names).values)
    return out


def _ecos_setup(tmp_path) -> tuple[Path, list[str]]:
    """The ecos program and its libraries, copied to tmp_path (outside any hidden folder)."""
    try:
        libs = ecos_libraries()
        if not libs:
            raise HostUnavailable("ecospy not installed")
        program = ecos_program(tmp_path)
    except (HostUnavailable, OSError) as err:
        missing(f"ecos program unavailable: {err} (pip install ecospy tbb)")
    libdir = tmp_path / "libs"
    libdir.mkdir()
    for folder in libs:
        for lib in glob.glob(f"{folder}/*.so*"):
            shutil.copy(lib, libdir)
    return program, [str(libdir)]


def _python_places() -> list[str]:
    """Every Python installation, venv and libpython on this machine (files and folders)."""
    patterns = ["/usr/bin/python*", "/usr/local/bin/python*", "/bin/python*",
                "/usr/lib/python3*", "/usr/local/lib/python3*", "/usr/lib/x86_64-linux-gnu/libpython*",
                "/usr/local/lib/libpython*", "/lib/x86_64-linux-gnu/libpython*", "/root/.pyenv",
                "/opt/conda", "/usr/share/python*"]
    places = {p for pattern in patterns for p in glob.glob(pattern)}
    places |= {sys.prefix, sys.base_prefix, str(Path(sys.executable).resolve().parent.parent)}
    places = {os.path.realpath(p) for p in places if os.path.exists(p)}
    return sorted(p for p in places                     # not inside another hidden folder
                  if not any(p.startswith(q + "/") for q in places if q != p))


def _hidden(command: list[str], places: list[str]) -> list[str]:
    """command run in a private mount namespace where every path in places is empty."""
    hide = []
    for place in places:
        cover = "tmpfs -t tmpfs" if os.path.isdir(place) else "--bind /dev/null"
        hide.append(f"mount {cover} {shlex.quote(place)}")
    check = "! python3 -c pass 2>/dev/null && ! python -c pass 2>/dev/null"
    script = " && ".join(hide + [check, "exec " + shlex.join(command)])
    return ["unshare", "--mount", "--propagation", "private", "sh", "-c", script]


def _run_ecos(program, libs, ssp, graph, names, cwd, hide):
    exp = graph.scenario.experiment
    command = ["env", "-i", "PATH=/usr/bin:/bin", "LD_LIBRARY_PATH=" + ":".join(libs),
               f"TMPDIR={cwd}",                     # ecos unpacks the SSP there
               *ecos_command(program, str(ssp), exp.start_time, exp.stop_time, exp.step_size)]
    if hide:
        command = _hidden(command, _python_places())
    proc = subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, (proc.returncode, proc.stdout[-2000:], proc.stderr[-2000:])
    return ecos_csv_values(cwd, names)


@pytest.mark.parametrize("hide", [True, False], ids=["no-python-at-all", "debian-python3-first"])
@pytest.mark.parametrize("case", ["circle", "twist"])
def test_ecos_program_runs_the_ssp_with_nothing_set(ssps, tmp_path, case, hide):
    if hide and (os.geteuid() != 0 or shutil.which("unshare") is None):
        missing("hiding Python needs root and unshare (a mount namespace)")
    if not hide and not Path("/usr/bin/python3").is_file():
        missing("no Debian /usr/bin/python3 here")
    program, libs = _ecos_setup(tmp_path)
    ssp, graph, names, ours = ssps[case]
    end, values = _run_ecos(program, libs, ssp, graph, names, tmp_path, hide)
    assert end == pytest.approx(graph.scenario.experiment.stop_time, abs=1e-9)
    for name in names:      # ecos' CSV has 6 decimals: equal up to its rounding
        assert abs(values[name] - ours[name]) <= CSV_TOLERANCE / 2 + 1e-12, (name, values, ours)


def test_ecos_program_sees_the_twist_parameters(ssps, tmp_path):
    """The twist is not the FMUs' default: x0 = 5 (an integer literal, a Real variable) and the
    expressions travel, so the end point is far from the default run's."""
    ssp, graph, names, ours = ssps["twist"]
    assert ours["pose.x"] > 5.5 and ours["source.vx"] == pytest.approx(0.4, abs=1e-15)


HOST = r'''
import ctypes, os, sys, zipfile, tempfile, pathlib
fmu, guid, name, vr_x, vr_vx = sys.argv[1:6]
folder = tempfile.mkdtemp(dir=os.environ.get("TMPDIR"))
zipfile.ZipFile(fmu).extractall(folder)
lib = ctypes.CDLL(os.path.join(folder, "binaries", "linux64", name + ".so"))
LOG = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                       ctypes.c_char_p)
class Callbacks(ctypes.Structure):
    _fields_ = [("logger", LOG), ("allocateMemory", ctypes.c_void_p),
                ("freeMemory", ctypes.c_void_p), ("stepFinished", ctypes.c_void_p),
                ("componentEnvironment", ctypes.c_void_p)]
messages = []
def log(env, instance, status, category, message):
    messages.append(message.decode())
logger = LOG(log)
libc = ctypes.CDLL(None)
callbacks = Callbacks(logger, ctypes.cast(libc.calloc, ctypes.c_void_p),
                      ctypes.cast(libc.free, ctypes.c_void_p), None, None)
lib.fmi2Instantiate.restype = ctypes.c_void_p
lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                                ctypes.POINTER(Callbacks), ctypes.c_int, ctypes.c_int]
resources = pathlib.Path(folder, "resources").as_uri().encode()
c = lib.fmi2Instantiate(b"pose", 1, guid.encode(), resources, ctypes.byref(callbacks), 0, 0)
if not c:
    print("REFUSED", " | ".join(messages))
    sys.exit(0)
c = ctypes.c_void_p(c)
lib.fmi2SetupExperiment(c, 0, ctypes.c_double(0.0), ctypes.c_double(0.0), 0, ctypes.c_double(1.0))
lib.fmi2EnterInitializationMode(c); lib.fmi2ExitInitializationMode(c)
lib.fmi2SetReal(c, (ctypes.c_uint * 1)(int(vr_vx)), 1, (ctypes.c_double * 1)(0.5))
for k in range(10):
    assert lib.fmi2DoStep(c, ctypes.c_double(k * 0.1), ctypes.c_double(0.1), 1) == 0
out = (ctypes.c_double * 1)()
lib.fmi2GetReal(c, (ctypes.c_uint * 1)(int(vr_x)), 1, out)
lib.fmi2FreeInstance(c)
print("RAN", repr(out[0]), any(m.startswith("mecanum_fmu_pose_integrator") for m in sys.modules))
'''
PYTHONS = {"3.10": PYENV / "3.10.13/bin/python3.10", "3.11": PYENV / "3.11.7/bin/python3.11",
           "3.12": PYENV / "3.12.1/bin/python3.12", "3.13": PYENV / "3.13.0/bin/python3.13",
           "3.11-debian-static": Path("/usr/bin/python3")}


@pytest.mark.parametrize("host", sorted(PYTHONS))
def test_a_python_host_runs_the_fmu_or_refuses_it_clearly(built_fmus, tmp_path, host):
    """The bundled Python is 3.11: a 3.11 host runs the FMU in its own interpreter (the slave
    module is in the host's sys.modules); another version gets the loader's message in the
    FMU's log and fmi2Instantiate returns NULL - the host process exits normally."""
    python = PYTHONS[host]
    if not python.is_file():
        missing(f"{python} not installed")
    from fmpy import read_model_description
    fmu = built_fmus["PoseIntegrator"]
    md = read_model_description(str(fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    script = tmp_path / "host.py"
    script.write_text(HOST)
    env = {"PATH": "/usr/bin:/bin", "TMPDIR": str(tmp_path)}
    proc = subprocess.run([str(python), "-I", str(script), str(fmu), md.guid, "PoseIntegrator",
                           str(vrs["x"]), str(vrs["vx"])], capture_output=True, text=True,
                          timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    outcome = proc.stdout.split()
    version = subprocess.run([str(python), "-c", "import sys; print(sys.version_info[:2])"],
                             capture_output=True, text=True).stdout.strip()
    if version == "(3, 11)":
        assert outcome[0] == "RAN", proc.stdout
        assert float(outcome[1]) == pytest.approx(0.5, abs=1e-12)      # 0.5 m/s for 1 s
        assert outcome[2] == "True"                  # in the host's interpreter: one Python
    else:
        assert outcome[0] == "REFUSED", proc.stdout
        running = version[1:-1].replace(", ", ".")          # e.g. 3.12: then ".1;" follows
        assert f"bundles Python 3.11, but the process already runs Python {running}." \
            in proc.stdout, proc.stdout


@pytest.mark.heavy(6)
def test_a_plain_c_host_runs_and_exits_without_a_memory_error(built_fmus, tmp_path):
    """A C host that frees its instance and returns from main without dlclose, as most do, under
    valgrind: no invalid read or write anywhere, from loading the FMU to the process's exit.
    (pythonfmu's library, left loaded, used to reset its interpreter state after exit() had
    destroyed it; glibc then aborted the host now and then: "corrupted double-linked list".)"""
    if shutil.which("valgrind") is None or shutil.which("gcc") is None:
        missing("valgrind and gcc are needed (apt-get install valgrind gcc)")
    host = tmp_path / "plain_host"
    subprocess.run(["gcc", "-O1", "-o", str(host), str(ROOT / "tests" / "hosts" / "plain_host.c"),
                    "-ldl"], check=True)
    from fmpy import extract, read_model_description
    folder = Path(extract(str(built_fmus["PoseIntegrator"]), str(tmp_path / "fmu")))
    md = read_model_description(str(folder))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    proc = subprocess.run(
        ["valgrind", "--error-exitcode=9", str(host),
         str(folder / "binaries" / "linux64" / "PoseIntegrator.so"), md.guid,
         (folder / "resources").as_uri(), str(vrs["vx"]), "0.5", str(vrs["x"])],
        capture_output=True, text=True, timeout=300, env={"PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in proc.stderr, proc.stderr[-3000:]
    assert proc.stdout.split()[0] == "RAN", proc.stdout
    assert float(proc.stdout.split()[1]) == pytest.approx(0.5, abs=1e-12)   # 0.5 m/s for 1 s


# ------------------------------------------------------------------ damaged self-contained FMUs

def _bundled(fmu: Path) -> list[str]:
    """The files the FMU's MANIFEST lists (the loader's check), read here from the archive."""
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
        listed = [line.split(" ", 2)[2] for line in
                  zf.read("resources/python/MANIFEST").decode().splitlines()]
    assert {n for n in names if n.startswith(("binaries/linux64/", "resources/python/"))} \
        - set(listed) == {"binaries/linux64/PoseIntegrator.so", "resources/python/MANIFEST"}
    return listed


def _kinds(names: list[str]) -> list[str]:
    """The first bundled file of each kind: each file of binaries/, the first extension module
    of lib-dynload/, each other file of resources/python/ (the loader checks each the same way;
    a host run per file costs about a second)."""
    first: dict[str, str] = {}
    for name in names:
        first.setdefault("lib-dynload" if "/lib-dynload/" in name else name, name)
    return list(first.values())


def _damaged(data: bytes, name: str) -> bytes:
    """A library cut in half (what made a host die of SIGBUS when it was mapped); any other
    file with one byte flipped in the middle (same size, other contents)."""
    if ".so" in name:
        return data[:len(data) // 2]
    middle = len(data) // 2
    return data[:middle] + bytes([data[middle] ^ 0x20]) + data[middle + 1:]


def _assert_one_message(log: str, name: str):
    lines = [line for line in log.splitlines() if " is damaged: " in line]
    assert len(lines) == 1 and f"the FMU PoseIntegrator is damaged: {name} has " in lines[0], log
    assert "Traceback" not in log and "Python path configuration" not in log, log


def test_a_plain_c_host_refuses_each_damaged_bundled_file_without_a_crash(built_fmus, tmp_path):
    """Each bundled file in turn, damaged in the unpacked FMU: fmi2Instantiate returns NULL,
    one message in the FMU's log names the file, the host exits normally (no SIGBUS)."""
    if shutil.which("gcc") is None:
        missing("gcc is needed (apt-get install gcc)")
    host = tmp_path / "plain_host"
    subprocess.run(["gcc", "-O1", "-o", str(host), str(ROOT / "tests" / "hosts" / "plain_host.c"),
                    "-ldl"], check=True)
    from fmpy import extract, read_model_description
    fmu = built_fmus["PoseIntegrator"]
    folder = Path(extract(str(fmu), str(tmp_path / "fmu")))
    md = read_model_description(str(folder))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    command = [str(host), str(folder / "binaries" / "linux64" / "PoseIntegrator.so"), md.guid,
               (folder / "resources").as_uri(), str(vrs["vx"]), "0.5", str(vrs["x"])]
    for name in _bundled(fmu):
        path = folder / name
        intact = path.read_bytes()
        path.write_bytes(_damaged(intact, name))
        proc = subprocess.run(command, capture_output=True, text=True, timeout=120,
                              env={"PATH": "/usr/bin:/bin"})
        path.write_bytes(intact)
        assert proc.returncode == 0, (name, proc.returncode, proc.stderr[-2000:])
        assert proc.stdout.strip() == "REFUSED", (name, proc.stdout)
        _assert_one_message(proc.stderr, name)
    proc = subprocess.run(command, capture_output=True, text=True, timeout=120,
                          env={"PATH": "/usr/bin:/bin"})
    assert proc.stdout.split()[0] == "RAN", proc.stdout             # restored: it runs again


def _with_member(archive: Path, member: str, data: bytes, dest: Path) -> Path:
    """A copy of the zip archive with one member's bytes replaced, every member stored rather
    than deflated: what is damaged is a file's bytes, which the loader and doctor check after
    unpacking, not the archive's compression (deflating the 10 MB FMU and the 40 MB SSP again
    for each of its 16 bundled files was most of these tests' time)."""
    with zipfile.ZipFile(archive) as src, zipfile.ZipFile(dest, "w", zipfile.ZIP_STORED) as out:
        for info in src.infolist():
            content = data if info.filename == member else src.read(info)
            stored = copy.copy(info)
            stored.compress_type = zipfile.ZIP_STORED
            out.writestr(stored, content)
    return dest


@pytest.mark.heavy(4)
def test_ecos_program_refuses_each_kind_of_damaged_bundled_file_without_a_crash(ssps, tmp_path):
    """The circle SSP with one of PoseIntegrator's bundled files of each kind damaged in turn
    (the binary, libpython, an extension module, the standard library: _kinds; the plain C host
    above takes every file): Ecos' `ecos` logs the loader's one message naming the file and
    exits without a signal. (Ecos goes on after fmi2Instantiate returned NULL: each later call
    of that FMU fails with fmi2Error, and Ecos, which ignores the status, writes its CSV and
    exits 0.)"""
    program, libs = _ecos_setup(tmp_path)
    ssp, graph, names, _ = ssps["circle"]
    exp = graph.scenario.experiment
    member = "resources/PoseIntegrator.fmu"
    with zipfile.ZipFile(ssp) as zf:
        fmu = tmp_path / "PoseIntegrator.fmu"
        fmu.write_bytes(zf.read(member))
    for name in _kinds(_bundled(fmu)):
        with zipfile.ZipFile(fmu) as zf:
            bad = _with_member(fmu, name, _damaged(zf.read(name), name), tmp_path / "bad.fmu")
        run = tmp_path / "run"
        run.mkdir()
        damaged = _with_member(ssp, member, bad.read_bytes(), run / "circle.ssp")
        ecos = ecos_command(program, str(damaged), exp.start_time, exp.stop_time, exp.step_size)
        command = ["env", "-i", "PATH=/usr/bin:/bin", "LD_LIBRARY_PATH=" + ":".join(libs),
                   f"TMPDIR={run}", *ecos[:-1], "debug"]        # its FMU log is at debug level
        proc = subprocess.run(command, cwd=run, capture_output=True, text=True, timeout=300)
        assert 0 <= proc.returncode < 128, (name, proc.returncode, proc.stderr[-2000:])
        _assert_one_message(proc.stdout + proc.stderr, name)
        shutil.rmtree(run)


def test_doctor_finds_each_damaged_bundled_file(built_fmus, tmp_path):
    """`doctor` runs the loader's check on the archive: each damaged file is named, and the FMU
    is no longer called self-contained."""
    from mecanum_fmu.interop.doctor import fmu_needs
    fmu = built_fmus["PoseIntegrator"]
    assert "linux64: self-contained" in fmu_needs(fmu, "PoseIntegrator")
    for name in _bundled(fmu):
        with zipfile.ZipFile(fmu) as zf:
            bad = _with_member(fmu, name, _damaged(zf.read(name), name), tmp_path / "bad.fmu")
        line = fmu_needs(bad, "PoseIntegrator")
        assert line.startswith(f"DAMAGED: {name} has ") and "self-contained" not in line, line
