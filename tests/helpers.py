"""Helpers for the master and CLI tests: test FMUs built once per process, scenario files,
reading results.csv."""
from __future__ import annotations

import csv
import dataclasses
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Callable

import fmpy
import numpy as np
import pytest

from mecanum_fmu.interop.other_hosts import HostUnavailable, run_host

ROOT = Path(__file__).resolve().parents[1]
FMU_SOURCES = Path(__file__).resolve().parent / "fmu_sources"
# docs/spec.md, The seed scenario: the seed circle's end point.
SPEC_END = (1.8390715290764525, -0.5440211108893698)

_BUILT: dict[str, Path] = {}
# CI sets it: a missing optional tool (libcosim, Ecos, a tmpfs mount) fails instead of skipping.
REQUIRE_TOOLS = os.environ.get("MECANUM_FMU_REQUIRE_TOOLS") == "1"


def tool_missing(reason: str):
    """An optional tool is not there: skip saying so, or fail when MECANUM_FMU_REQUIRE_TOOLS=1."""
    if REQUIRE_TOOLS:
        pytest.fail(f"{reason} - MECANUM_FMU_REQUIRE_TOOLS=1 forbids skipping")
    pytest.skip(reason)


def mount_tmpfs(folder: Path, options: str) -> Path:
    """Create folder and mount a tmpfs with `options` on it (root), or `tool_missing`."""
    folder.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        tool_missing(f"cannot mount a tmpfs (not root, or no permission): {proc.stderr}")
    return folder


def run_host_or_skip(host: str, ssp: Path, **kwargs):
    """`other_hosts.run_host`, or `tool_missing` when the host cannot be loaded."""
    try:
        return run_host(host, ssp, **kwargs)
    except HostUnavailable as err:
        tool_missing(str(err))


def test_fmus(tmp_path_factory) -> dict[str, Path]:
    """script stem -> built FMU, built once per process (each script has a unique module
    name, and one FMU must never be built or extracted twice in one process)."""
    if not _BUILT:
        from pythonfmu import FmuBuilder
        dest = tmp_path_factory.mktemp("test_fmus")
        for script in sorted(FMU_SOURCES.glob("mtest_*.py")):
            _BUILT[script.stem] = Path(FmuBuilder.build_FMU(script, dest=dest))
    return _BUILT


test_fmus.__test__ = False   # not a test, despite the name


def state_fmus(dest: Path, only: tuple[str, ...] = ()) -> dict[str, Path]:
    """script stem -> FMU built into `dest` from tests/fmu_sources/with_state (third-party
    style FMUs that can save their state: a wave source, a lag, two integrators, a drag, a
    spring, a bouncing ball),
    the outputs of those with an input declared free of it (dependencies="", as a C
    exporter would declare a state), the P controller's declared to read its inputs
    directly (an FMU whose dependencies are not declared may hold a state: plan.has_state):
    tests/test_estimate_any_fmu.py, bench/third_party.py. `only`: those stems alone."""
    from pythonfmu import FmuBuilder
    built = {}
    for script in sorted((FMU_SOURCES / "with_state").glob("xtest_*.py")):
        if only and script.stem not in only:
            continue
        built[script.stem] = Path(FmuBuilder.build_FMU(script, dest=dest,
                                                       canGetAndSetFMUstate=True))
        if script.stem != "xtest_wave":     # the P controller: u reads r and y directly
            declare_no_dependencies(built[script.stem], {
                "xtest_through": {"y": ["u"]}, "xtest_gain": {"u": ["r", "y"]}}.get(
                    script.stem))
    return built


def state_fmu3(dest: Path) -> Path:
    """The FMI 3.0 lag (tests/fmu_sources/fmi3_state/x3test_lag.py, pythonfmu3) built into
    `dest`, able to save its state, its output declared free of its input."""
    from pythonfmu3 import FmuBuilder
    fmu = Path(FmuBuilder.build_FMU(FMU_SOURCES / "fmi3_state" / "x3test_lag.py", dest=dest,
                                    canGetAndSetFMUState=True))
    declare_no_dependencies(fmu)
    return fmu


_ENDING: list[Path] = []


def ending_fmus(tmp_path_factory) -> Path:
    """A folder with CStop.fmu (plain C, FMI 2.0: tests/fmu_sources/c_stop) and
    X3testStop.fmu (pythonfmu3, FMI 3.0, no dependencies declared:
    tests/fmu_sources/fmi3_stop), FMUs that ask to end the simulation at their t_end; built
    once per process."""
    if not _ENDING:
        if shutil.which("gcc") is None:
            tool_missing("gcc is needed to build the FMI 2.0 test FMU that ends its run")
        dest = tmp_path_factory.mktemp("ending_fmus")
        library, source = dest / "cstop.so", FMU_SOURCES / "c_stop"
        subprocess.run(["gcc", "-shared", "-fPIC", "-O1", "-I",
                        str(Path(fmpy.__file__).parent / "c-code"), "-o", str(library),
                        str(source / "cstop.c")], check=True)
        with zipfile.ZipFile(dest / "CStop.fmu", "w") as fmu:
            fmu.write(source / "modelDescription.xml", "modelDescription.xml")
            fmu.write(library, "binaries/linux64/cstop.so")
        from pythonfmu3 import FmuBuilder
        FmuBuilder.build_FMU(FMU_SOURCES / "fmi3_stop" / "x3test_stop.py", dest=dest,
                             canGetAndSetFMUState=True)
        _ENDING.append(dest)
    return _ENDING[0]


def mode_fmu3(dest: Path) -> Path:
    """X3testMode.fmu (pythonfmu3, FMI 3.0: tests/fmu_sources/fmi3_enum) built into `dest`,
    its Int64 mode_in and mode rewritten into Enumerations of a declared type Mode (slow = 1,
    fast = 2), as FMI 3.0's Reference FMU Feedthrough declares its Enumeration_input."""
    from pythonfmu3 import FmuBuilder
    fmu = Path(FmuBuilder.build_FMU(FMU_SOURCES / "fmi3_enum" / "x3test_mode.py", dest=dest))

    def enumerations(xml: str) -> str:
        xml = re.sub(r'<Int64 name="(mode_in|mode)"',
                     r'<Enumeration name="\1" declaredType="Mode"', xml)
        return xml.replace("<ModelVariables>", '<TypeDefinitions><EnumerationType name="Mode">'
                           '<Item name="slow" value="1"/><Item name="fast" value="2"/>'
                           "</EnumerationType></TypeDefinitions>\n\t<ModelVariables>", 1)
    rewrite_description(fmu, enumerations)
    return fmu


def rewrite_description(fmu: Path, edit: Callable[[str], str], dest: Path | None = None
                        ) -> Path:
    """The FMU with its modelDescription.xml passed through `edit`, in place or as `dest`."""
    with zipfile.ZipFile(fmu) as zf:
        entries = {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}
    entries["modelDescription.xml"] = edit(entries["modelDescription.xml"].decode()).encode()
    with zipfile.ZipFile(dest or fmu, "w") as zf:
        for name, data in entries.items():
            zf.writestr(name, data)
    return dest or fmu


def declare_no_dependencies(fmu: Path, direct: dict[str, list[str]] | None = None) -> None:
    """Rewrite the FMU's model description: every output declared free of every input
    (dependencies="", as a C exporter declares a state; pythonfmu writes none), but those
    in `direct` (FMI 2.0): output name -> the inputs that reach it directly."""
    def declared(xml: str) -> str:
        index = {name: i + 1 for i, name in enumerate(
            re.findall(r'<ScalarVariable name="([^"]+)"', xml))}
        name_of = {str(i): name for name, i in index.items()}
        xml = re.sub(r'<Unknown index="(\d+)"/>',
                     lambda m: '<Unknown index="{}" dependencies="{}"/>'.format(
                         m.group(1), " ".join(str(index[n]) for n in
                                              (direct or {}).get(name_of[m.group(1)], []))),
                     xml)
        return re.sub(r'<Output valueReference="(\d+)"/>',               # FMI 3.0
                      r'<Output valueReference="\1" dependencies=""/>', xml)
    rewrite_description(fmu, declared)


def with_experiment(graph, **changes):
    """(the graph with its experiment changed, that experiment): a run at another step,
    master or tolerance without writing a scenario."""
    exp = dataclasses.replace(graph.scenario.experiment, **changes)
    return dataclasses.replace(graph, scenario=dataclasses.replace(graph.scenario,
                                                                   experiment=exp)), exp


def write_scenario(folder: Path, name: str, text: str) -> Path:
    path = Path(folder) / f"{name}.yaml"
    path.write_text(text)
    return path


CHAIN_COMPONENTS = {
    "source": "source: {fmu: VelocitySource, parameters: "
              "{vx_expr: 'sin(t)', vy_expr: 'cos(t)', w_expr: '0'}}",
    "c2w": "c2w: {fmu: Center2Wheel}",
    "w2c": "w2c: {fmu: Wheel2Center}",
    "pose": "pose: {fmu: PoseIntegrator}",
}
CHAIN_CONNECTIONS = """\
connections:
  - [source.vx, c2w.vx]
  - [source.vy, c2w.vy]
  - [source.w,  c2w.w]
  - [c2w.w1, w2c.w1]
  - [c2w.w2, w2c.w2]
  - [c2w.w3, w2c.w3]
  - [c2w.w4, w2c.w4]
  - [w2c.vx, pose.vx]
  - [w2c.vy, pose.vy]
  - [w2c.w,  pose.w]
"""
# the closed loop pose -> follower -> c2w -> w2c -> pose (a PathFollower's scenarios)
LOOP_CONNECTIONS = """\
connections:
  - [pose.x, follower.x]
  - [pose.y, follower.y]
  - [pose.theta, follower.theta]
  - [follower.vx, c2w.vx]
  - [follower.vy, c2w.vy]
  - [follower.w,  c2w.w]
  - [c2w.w1, w2c.w1]
  - [c2w.w2, w2c.w2]
  - [c2w.w3, w2c.w3]
  - [c2w.w4, w2c.w4]
  - [w2c.vx, pose.vx]
  - [w2c.vy, pose.vy]
  - [w2c.w,  pose.w]
"""


def chain_scenario(folder: Path, name: str, *, master: str = "gauss-seidel",
                   step_size: float = 0.05, stop_time: float = 2.0,
                   order=("source", "c2w", "w2c", "pose"), outputs=None,
                   profile=("sin(t)", "cos(t)", "0")) -> Path:
    """The seed's four-block chain (docs/spec.md, The original study) with the components
    declared in `order`."""
    comps = dict(CHAIN_COMPONENTS)
    comps["source"] = ("source: {fmu: VelocitySource, parameters: "
                       "{vx_expr: '%s', vy_expr: '%s', w_expr: '%s'}}" % profile)
    lines = [f"name: {name}",
             f"experiment: {{start_time: 0.0, stop_time: {stop_time!r}, "
             f"step_size: {step_size!r}, master: {master}}}",
             "parameters: {alpha: 0.7853981633974483, L: 0.16, W: 0.12, R: 0.06}",
             "components:"]
    lines += [f"  {comps[c]}" for c in order]
    text = "\n".join(lines) + "\n" + CHAIN_CONNECTIONS
    if outputs is not None:
        text += "outputs:\n" + "".join(f"  - {o}\n" for o in outputs)
    return write_scenario(folder, name, text)


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and the rows as a float array."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    data = np.array([[float(v) for v in row] for row in body], dtype=float).reshape(
        len(body), len(header))
    return header, data


# ---- running the CLI ----------------------------------------------------------------------

def child_env(tmp: Path | None = None, **extra: str) -> dict[str, str]:
    """A minimal environment for a child `python -m mecanum_fmu`: this checkout's src first,
    Agg plots, no bytecode; TMPDIR=tmp when given (to see what a run leaves behind), else this
    test process's own (tests/conftest.py)."""
    env = {"PYTHONPATH": os.pathsep.join([str(ROOT / "src")] + [p for p in [
               os.environ.get("PYTHONPATH")] if p]),
           "PATH": os.environ.get("PATH", "/usr/bin:/bin"), "MPLBACKEND": "Agg",
           "PYTHONDONTWRITEBYTECODE": "1"}
    for key in ("HOME", "XDG_CACHE_HOME", "MECANUM_FMU_REQUIRE_TOOLS", "LD_LIBRARY_PATH",
                "TMPDIR"):
        if key in os.environ:
            env[key] = os.environ[key]
    if tmp is not None:
        env["TMPDIR"] = str(tmp)
    env.update(extra)
    return env


def cli_args(*args) -> list[str]:
    return [sys.executable, "-m", "mecanum_fmu", *map(str, args)]


def run_child(*args, cwd=None, env=None, timeout: float = 300) -> subprocess.CompletedProcess:
    """`python -m mecanum_fmu ARGS` in a child process (text output captured)."""
    return subprocess.run(cli_args(*args), capture_output=True, text=True, timeout=timeout,
                          cwd=cwd or ROOT, env=env or child_env())


def run_main(capsys, *args) -> tuple[int, str, str]:
    """`mecanum_fmu.cli.main(ARGS)` in this process: (exit code, stdout, stderr)."""
    from mecanum_fmu import cli
    code = cli.main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def pose_without_state_save(fmu_dir: Path, folder: Path) -> Path:
    """folder/PoseNoState.fmu: PoseIntegrator whose model description says it cannot get and
    set its state (canGetAndSetFMUstate="false")."""
    fmu = folder / "PoseNoState.fmu"
    with zipfile.ZipFile(fmu_dir / "PoseIntegrator.fmu") as src, \
            zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "modelDescription.xml":
                data = data.replace(b'canGetAndSetFMUstate="true"',
                                    b'canGetAndSetFMUstate="false"')
            dst.writestr(info, data)
    return fmu


def assert_estimated(summary: dict, output: str, error, factor: float = 3.0,
                     end_factor: float | None = None) -> None:
    """The summary's estimate of `output`, its largest and its end, within `factor` of the
    true |error| per row (the end within `end_factor`, default the same)."""
    for which, value, within in (("max", error.max(), factor),
                                 ("end", error[-1], end_factor or factor)):
        estimate = summary["error_estimate"][output][which]
        assert value / within <= estimate <= within * value, (output, which, estimate, value)
