"""Shared fixtures: the bundled FMUs, built once per test session; the session's own TMPDIR."""
import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

# The tests look at what a run leaves in TMPDIR, and a machine is never idle (a compiler
# elsewhere leaves cc*.s in /tmp): each test process gets a TMPDIR of its own, set before the
# tests create any temporary, and the processes they start inherit it (helpers.child_env).
# The session's process makes one folder in the machine's TMPDIR; pytest-xdist's workers
# inherit its path through SESSION_TMP and each take a sub-folder of it (gw0, gw1, ...).
SESSION_TMP = "MECANUM_FMU_TEST_SESSION_TMP"


def _own_tmpdir() -> Path:
    session = os.environ.get(SESSION_TMP)
    if session is None or not os.path.isdir(session):
        session = tempfile.mkdtemp(prefix="mecanum_fmu_tests_")
        os.environ[SESSION_TMP] = session
    own = Path(session) / os.environ.get("PYTEST_XDIST_WORKER", "main")
    own.mkdir(exist_ok=True)
    os.environ["TMPDIR"] = str(own)
    tempfile.tempdir = str(own)        # gettempdir() may have cached the old one already
    return own


OWN_TMPDIR = _own_tmpdir()

os.environ.setdefault("MPLBACKEND", "Agg")
# Started in the background (nohup, `make test &`), the shell hands every process an ignored
# SIGINT, and Python then installs no KeyboardInterrupt: the Ctrl-C tests need it as a terminal
# gives it, to this process and to the runs it starts.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# Hypothesis tries the same examples on every run, so `make test` passes or fails the same way
# each time (a test that fails now and then is a failing test). HYPOTHESIS_PROFILE=explore
# searches afresh; what it finds becomes a fixed example (@example) or a fix.
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))

try:
    import mecanum_fmu  # noqa: F401
except ImportError:  # package not installed: fall back to the src layout
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

# The installed pythonfmu and pythonfmu3 before any FMU runs here: an FMU that FMPy runs in this
# process (simulate_fmu) imports them from its own extracted resources when nothing has yet, and
# FMPy deletes that folder afterwards; a later FmuBuilder (helpers.test_fmus) then found no
# binaries to pack, and its FMUs failed in whichever tests came after on that worker.
import pythonfmu.builder  # noqa: E402,F401
import pythonfmu3.builder  # noqa: E402,F401

MODEL_NAMES = ("VelocitySource", "Center2Wheel", "Wheel2Center", "PoseIntegrator", "PathFollower",
               # the other chassis (docs/chassis.md, tests/test_chassis.py)
               "OmniCenter2Wheel", "OmniWheel2Center", "FieldToBody", "Bicycle", "SteeringSource",
               # sensors and dead reckoning (docs/robot.md, tests/test_odometry.py)
               "Encoder", "Gyro", "Odometry",
               # the drive train (docs/robot.md, tests/test_robot.py)
               "DCMotor", "MecanumDynamics")


# both versions in one child: fmu_dir holds the FMI 2.0 FMUs and fmu_dir/fmi3 their FMI 3.0
# twins (a scenario's `fmu: fmi3/<Model>`)
BUILD = """import json, sys
from mecanum_fmu.models.build import build_all
from mecanum_fmu.models.build3 import build_all3
paths = build_all(sys.argv[1])
build_all3(sys.argv[1])
print(json.dumps([str(p) for p in paths]))
"""


@pytest.fixture(scope="session")
def fmu_dir():
    """The folder of the bundled FMUs (a scenario's --fmu-dir), made once per session in a
    fresh temporary folder that the session's xdist workers share: the first to need it
    makes it under a lock, the others wait for it and check what it holds. Where the
    checkout's fmus/ were built from the current sources (`make test` builds them first),
    they are copied; else they are built.

    The build runs in a child process: it imports each slave script under its FMU module
    name and must not meet a copy that this process has already loaded.
    """
    session = Path(os.environ[SESSION_TMP])
    dest = session / "built_fmus"
    with open(session / "built_fmus.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not dest.is_dir():
            partial = session / "built_fmus.partial"
            shutil.rmtree(partial, ignore_errors=True)
            if _copy_current_checkout_fmus(partial):
                partial.rename(dest)
        if not dest.is_dir():
            src = str(Path(__file__).resolve().parents[1] / "src")
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(
                [src] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
            proc = subprocess.run([sys.executable, "-c", BUILD, str(partial)],
                                  capture_output=True, text=True, env=env)
            assert proc.returncode == 0, proc.stderr[-3000:]
            paths = [Path(p) for p in json.loads(proc.stdout.splitlines()[-1])]
            assert all(path.is_file() and path.parent == partial for path in paths)
            assert sorted(p.stem for p in paths) == sorted(MODEL_NAMES)
            partial.rename(dest)
    assert sorted(p.stem for p in dest.glob("*.fmu")) == sorted(MODEL_NAMES)
    return dest


def _copy_current_checkout_fmus(dest: Path) -> bool:
    """Copy the checkout's fmus/ (and fmus/fmi3/) into dest when every bundled FMU there was
    built from the current sources (its GUID is the sources' digest: models/library.py), as
    `make test`'s own `fmus` step leaves them; else copy nothing and say so (False: build)."""
    from mecanum_fmu.models.library import is_current, is_current3
    checkout = Path(__file__).resolve().parents[1] / "fmus"
    if not all(is_current(name, checkout / f"{name}.fmu") and
               is_current3(name, checkout / "fmi3" / f"{name}.fmu") for name in MODEL_NAMES):
        return False
    (dest / "fmi3").mkdir(parents=True)
    for name in MODEL_NAMES:
        shutil.copy2(checkout / f"{name}.fmu", dest / f"{name}.fmu")
        shutil.copy2(checkout / "fmi3" / f"{name}.fmu", dest / "fmi3" / f"{name}.fmu")
    return True


@pytest.fixture(scope="session")
def fmi3_fmus(fmu_dir):
    """modelName -> Path of its FMI 3.0 FMU, built with the FMI 2.0 ones into fmu_dir/fmi3/
    (a scenario's `fmu: fmi3/<Model>`)."""
    paths = sorted((fmu_dir / "fmi3").glob("*.fmu"))
    assert [p.stem for p in paths] == sorted(MODEL_NAMES)
    return {p.stem: p for p in paths}


@pytest.fixture(scope="session")
def built_fmus(fmu_dir):
    """modelName -> Path of the freshly built FMU."""
    return {name: fmu_dir / f"{name}.fmu" for name in MODEL_NAMES}


def pytest_configure(config):
    config.addinivalue_line("markers", "heavy(seconds): a test that takes about `seconds` on a "
                            "quiet machine; the heavy ones run first, longest first")


def pytest_collection_modifyitems(items):
    """The heavy tests first, longest first; the rest in their order. With two workers a
    40 s test that starts last adds 40 s to the suite: started first, the other worker does
    the many short tests meanwhile (`make test`: --dist worksteal, Makefile)."""
    def seconds(item) -> float:
        mark = item.get_closest_marker("heavy")
        return mark.args[0] if mark else 0.0
    items.sort(key=lambda item: -seconds(item))       # stable: equal weights keep their order


def pytest_sessionfinish(session, exitstatus):
    session.config._mecanum_exitstatus = int(exitstatus)


def _remove_session_tmp(exitstatus: int) -> None:
    """The session's process (not an xdist worker) removes the session's TMPDIR when every test
    passed; after a failure it stays, for the failed tests' tmp_path folders."""
    if "PYTEST_XDIST_WORKER" in os.environ:
        return
    session = os.environ[SESSION_TMP]
    if exitstatus == 0:
        shutil.rmtree(session, ignore_errors=True)
    else:
        print(f"the session's TMPDIR is kept: {session}")


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave without interpreter shutdown, as `mecanum_fmu.cli.exit_with` does: with pythonfmu
    FMUs loaded, CPython's finalization aborts now and then. The report is printed by now (an
    xdist worker has sent its results)."""
    if hasattr(config, "_mecanum_exitstatus"):
        from mecanum_fmu.process import exit_now
        _remove_session_tmp(config._mecanum_exitstatus)
        exit_now(config._mecanum_exitstatus)
