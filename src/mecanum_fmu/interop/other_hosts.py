"""Run an SSP archive in another FMI host - libcosim, Ecos, or Ecos' command-line program.

Used by `cross-check`, the tests and the benchmark to show that the FMUs and the wired system
behave the same outside our master. Each host runs in a child process
(`python -m mecanum_fmu.interop.other_hosts HOST SSP ...`, which prints one JSON line): a native crash
in a host cannot take the caller with it, each process loads each FMU once, and the wall time
is the host's own.

  libcosim  Open Simulation Platform, PyPI `libcosimpy`, `CosimExecution.from_ssp_file`
            (fixed-step algorithm; time is an integer count of nanoseconds).
  ecos      PyPI `ecospy`, `EcosSimulation(ssp_path=...)` (needs Intel TBB's libtbb.so.12:
            PyPI `tbb`, loaded from the environment before ecospy, else the system's). Ecos
            applies an SSP's parameter bindings only when their set is named at init, so we
            name it (ssp.PARAMETER_SET); without that it silently runs the FMUs' defaults.
  ecos-cli  the `ecos` program shipped inside the ecospy wheel: a non-Python host. It runs with
            LD_PRELOAD removed from its environment: our FMUs carry their Python
            (models/embed.py). FMUs built elsewhere by plain pythonfmu need LD_PRELOAD=<libpython>;
            set MECANUM_FMU_ECOS_PRELOAD=<libpython> for those. Its CSV has 6 decimals.
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from .ssp import PARAMETER_SET

HOSTS = ("libcosim", "ecos", "ecos-cli")
INSTALL = {
    "libcosim": "pip install libcosimpy",
    "ecos": "pip install ecospy tbb",
    "ecos-cli": "pip install ecospy tbb",
}
UNAVAILABLE = 3          # the child's exit code when the host cannot be loaded


@dataclass(frozen=True)
class HostRun:
    host: str
    version: str
    end_time: float
    values: dict[str, float]     # `instance.variable` -> value at the end time
    setup_s: float | None        # load the SSP, unpack, instantiate and initialize
    simulate_s: float            # the stepping loop


class HostUnavailable(Exception):
    """The host's package or a library it needs is missing; the message says what to install."""


class HostFailed(Exception):
    """The host loaded but the run failed."""


def run_host(host: str, ssp: Path, *, start: float, stop: float, step: float,
             variables: list[str], timeout: float = 600) -> HostRun:
    """Run `ssp` in `host` from `start` to `stop` with a fixed communication `step` and return
    the end values of `variables` (Real, `instance.variable`)."""
    if host not in HOSTS:
        raise ValueError(f"unknown host {host!r} (choose one of {', '.join(HOSTS)})")
    cmd = [sys.executable, "-m", "mecanum_fmu.interop.other_hosts", host, str(Path(ssp).resolve()),
           repr(start), repr(stop), repr(step), *variables]
    # the child imports this package from where the caller has it (installed or not)
    package_root = str(Path(__file__).resolve().parents[2])
    # its own TMPDIR, removed when it ends however it ends: Ecos unpacks every SSP and FMU
    # there (ecos_ssp_*, ecos_<Model>_*, ~12 MB each) and leaves them
    with tempfile.TemporaryDirectory(prefix="mecanum-host-") as tmp:
        env = dict(os.environ, TMPDIR=tmp, PYTHONPATH=os.pathsep.join(
            p for p in (package_root, os.environ.get("PYTHONPATH")) if p))
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    if proc.returncode == UNAVAILABLE:
        raise HostUnavailable(f"{host}: {proc.stdout.strip() or proc.stderr.strip()} "
                              f"(install: {INSTALL[host]})")
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        raise HostFailed(f"{host} {_ended(proc.returncode)}: {_reason(proc)}")
    data = json.loads(lines[-1])
    return HostRun(host=host, version=data["version"], end_time=data["end_time"],
                   values=data["values"], setup_s=data["setup_s"], simulate_s=data["simulate_s"])


def _ended(code: int) -> str:
    if code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with code {code}"


def _reason(proc: subprocess.CompletedProcess) -> str:
    """What a failed child said, without the frames of a traceback (the child's own code is
    not the user's business): its last lines that are not part of one."""
    text = proc.stderr.strip() or proc.stdout.strip()
    lines = [line for line in text.splitlines() if line.strip()]
    if any(line.startswith("Traceback (most recent call last)") for line in lines):
        lines = lines[-1:]                  # the exception's own line
    return " / ".join(lines[-3:])[-1000:] or "no message"


# --- the child side ---------------------------------------------------------------------------

def _steps(start: float, stop: float, step: float) -> int:
    return int(round((stop - start) / step))


def _libcosim(ssp: str, start: float, stop: float, step: float, names: list[str]) -> dict:
    from importlib.metadata import version
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)     # by default it logs every FMI call
    ns = 1_000_000_000
    t0 = time.perf_counter()
    execution = CosimExecution.from_ssp_file(ssp, step_size=int(round(step * ns)))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    refs = {}
    for name in names:
        instance, variable = name.split(".", 1)
        index = execution.slave_index_from_instance_name(instance)
        by_name = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
        refs[name] = (index, by_name[variable])
    t1 = time.perf_counter()
    if not execution.simulate_until(int(round(stop * ns))):
        raise RuntimeError("libcosim: simulate_until failed")
    t2 = time.perf_counter()
    values = {name: observer.last_real_values(index, [ref])[0]
              for name, (index, ref) in refs.items()}
    end_time = execution.status().current_time / ns
    return dict(version=version("libcosimpy"), end_time=end_time, values=values,
                setup_s=t1 - t0, simulate_s=t2 - t1)


def _ecos(ssp: str, start: float, stop: float, step: float, names: list[str]) -> dict:
    from importlib.metadata import version
    from ecospy import EcosSimulation

    t0 = time.perf_counter()
    sim = EcosSimulation(ssp_path=ssp, step_size=step)
    sim.init(start_time=start, parameter_set=PARAMETER_SET)   # else Ecos ignores the bindings
    t1 = time.perf_counter()
    # a step count, not step_until(stop): Ecos adds h to its clock each step, and after 200
    # steps of 0.05 the clock reads 9.95000000000001, so step_until(10) stops one step short
    sim.step(_steps(start, stop, step))
    t2 = time.perf_counter()
    values = {name: sim.get_real(name.replace(".", "::", 1)) for name in names}
    end_time = sim.get_time()
    sim.terminate()
    return dict(version=version("ecospy"), end_time=end_time, values=values,
                setup_s=t1 - t0, simulate_s=t2 - t1)


def tbb_folder() -> str | None:
    """The folder of Intel TBB's runtime libtbb.so.12 from PyPI `tbb`, or None when that
    wheel is not installed (then the system's library, if any, is used)."""
    from importlib.metadata import PackageNotFoundError, distribution
    try:
        tbb = next((f for f in distribution("tbb").files or () if f.name == "libtbb.so.12"), None)
    except PackageNotFoundError:
        return None
    return str(Path(tbb.locate()).resolve().parent) if tbb is not None else None


def ecos_libraries() -> list[str]:
    """The folders the `ecos` program needs on LD_LIBRARY_PATH: ecospy's binaries and TBB's."""
    from importlib.util import find_spec
    spec = find_spec("ecospy")
    folders = [str(Path(spec.origin).parent / "binaries")] if spec is not None else []
    return folders + [f for f in (tbb_folder(),) if f]


def ecos_program(folder: Path) -> Path:
    """A runnable copy of the wheel's `ecos` program in folder (the wheel ships it without
    the executable bit)."""
    from importlib.util import find_spec
    program = Path(folder) / "ecos"
    shutil.copy(Path(find_spec("ecospy").origin).parent / "binaries" / "ecos", program)
    program.chmod(0o755)
    return program


def ecos_command(program: Path, ssp: str, start: float, stop: float, step: float) -> list[str]:
    # stop half a step late: Ecos' clock drifts by adding h each step (see _ecos)
    return [str(program), "simulate", "--path", ssp, "--startTime", repr(start),
            "--stopTime", repr(stop + step / 2), "--stepSize", repr(step),
            "--parameterSet", PARAMETER_SET, "-l", "warn"]


def ecos_csv_values(folder: Path, names: list[str]) -> tuple[float, dict[str, float]]:
    """The end time and the last row's values of `names` in the CSV ecos wrote in folder."""
    table = next(Path(folder).glob("*.csv"))
    with open(table, newline="") as fh:
        rows = list(csv.reader(fh, skipinitialspace=True))
    header = {h.split("[", 1)[0].replace("::", ".", 1): i for i, h in enumerate(rows[0])}
    last = rows[-1]
    return float(last[header["time"]]), {name: float(last[header[name]]) for name in names}


def _ecos_cli(ssp: str, start: float, stop: float, step: float, names: list[str]) -> dict:
    from importlib.metadata import version

    with tempfile.TemporaryDirectory(prefix="mecanum-ecos-") as tmp:
        program = ecos_program(Path(tmp))
        env = dict(os.environ, LD_LIBRARY_PATH=os.pathsep.join(
            p for p in (*ecos_libraries(), os.environ.get("LD_LIBRARY_PATH")) if p))
        env.pop("LD_PRELOAD", None)       # the FMUs must load by themselves
        if os.environ.get("MECANUM_FMU_ECOS_PRELOAD"):     # FMUs built elsewhere
            env["LD_PRELOAD"] = os.environ["MECANUM_FMU_ECOS_PRELOAD"]
        t0 = time.perf_counter()
        proc = subprocess.run(ecos_command(program, ssp, start, stop, step), cwd=tmp, env=env,
                              capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            raise RuntimeError(f"the ecos program {_ended(proc.returncode)}: {_reason(proc)}")
        end_time, values = ecos_csv_values(Path(tmp), names)
    return dict(version=version("ecospy"), end_time=end_time, values=values,
                setup_s=None, simulate_s=wall)


def _load_tbb() -> None:
    """Load PyPI tbb's libtbb.so.12 globally, so ecospy's libecosc.so finds it (when the
    wheel is installed; otherwise the system's library is used)."""
    import ctypes
    folder = tbb_folder()
    if folder is not None:
        ctypes.CDLL(str(Path(folder) / "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)


def _child(argv: list[str]) -> int:
    host, ssp, start, stop, step, *names = argv
    runner = {"libcosim": _libcosim, "ecos": _ecos, "ecos-cli": _ecos_cli}[host]
    try:
        if host == "libcosim":
            import libcosimpy.CosimExecution  # noqa: F401
        else:
            _load_tbb()
            import ecospy  # noqa: F401  (loads libecosc.so, which needs libtbb.so.12)
    except (ImportError, OSError) as err:
        print(f"cannot load {host}: {err}")
        return UNAVAILABLE
    try:
        data = runner(ssp, float(start), float(stop), float(step), names)
    except Exception as err:        # one line for the caller (run_host), no traceback
        print(f"{type(err).__name__}: {' '.join(str(err).split())[-1000:]}", file=sys.stderr)
        return 1
    print(json.dumps(data))
    return 0


if __name__ == "__main__":
    from mecanum_fmu.process import exit_now
    exit_now(_child(sys.argv[1:]))
