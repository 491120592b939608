"""Shared fixtures: the four bundled FMUs, built once per test session."""
import os
import signal
import sys
from pathlib import Path

import pytest
from hypothesis import settings

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

MODEL_NAMES = ("VelocitySource", "Center2Wheel", "Wheel2Center", "PoseIntegrator", "PathFollower",
               # the other chassis (docs/chassis.md, tests/test_chassis.py)
               "OmniCenter2Wheel", "OmniWheel2Center", "FieldToBody", "Bicycle", "SteeringSource",
               # the drive train (docs/robot.md, tests/test_robot.py)
               "DCMotor", "MecanumDynamics")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    """The folder of the bundled FMUs (a scenario's --fmu-dir), built once into a fresh
    temporary folder.

    Build before any FMU is loaded into this process: the build imports each slave script
    under its FMU module name and must not meet an already loaded copy.
    """
    from mecanum_fmu.models.build import build_all

    dest = tmp_path_factory.mktemp("built_fmus")
    paths = [Path(p) for p in build_all(dest)]
    assert sorted(p.stem for p in paths) == sorted(MODEL_NAMES)
    for path in paths:
        assert path.is_file() and path.parent == dest
    return dest


@pytest.fixture(scope="session")
def built_fmus(fmu_dir):
    """modelName -> Path of the freshly built FMU."""
    return {name: fmu_dir / f"{name}.fmu" for name in MODEL_NAMES}


def pytest_sessionfinish(session, exitstatus):
    session.config._mecanum_exitstatus = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave without interpreter shutdown, as `mecanum_fmu.cli.exit_with` does: with pythonfmu
    FMUs loaded, CPython's finalization aborts now and then. The report is printed by now."""
    if hasattr(config, "_mecanum_exitstatus"):
        from mecanum_fmu.process import exit_now
        exit_now(config._mecanum_exitstatus)
