"""The shape the project promises: short functions, commands that decide when to build, one log
per FMU instance."""
import ast
import shutil
import zipfile
from pathlib import Path

from helpers import ROOT, run_child

SRC = ROOT / "src" / "mecanum_fmu"
MAX_LINES = 60


def test_no_function_in_src_is_longer_than_60_lines():
    long = []
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_LINES:
                    long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({lines})")
    assert not long, long


def test_validate_never_builds_and_names_the_fix(tmp_path):
    empty = tmp_path / "fmus"
    empty.mkdir()
    proc = run_child("validate", ROOT / "scenarios" / "circle.yaml", "--fmu-dir", empty)
    assert proc.returncode == 2, proc.stderr
    assert "is not built" in proc.stderr and "python -m mecanum_fmu fmus" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert list(empty.iterdir()) == []


def _stale_copy(fmu: Path, dest: Path) -> Path:
    """The same FMU with another GUID: what an FMU built from older sources looks like."""
    with zipfile.ZipFile(fmu) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    xml = members["modelDescription.xml"].decode()
    start = xml.index('guid="') + 6
    members["modelDescription.xml"] = (xml[:start] + "{00000000-0000-0000-0000-000000000000}"
                                       + xml[xml.index('"', start):]).encode()
    with zipfile.ZipFile(dest, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return dest


def test_validate_warns_about_a_stale_fmu_and_leaves_it_alone(tmp_path, built_fmus):
    folder = tmp_path / "fmus"
    folder.mkdir()
    for name, path in built_fmus.items():
        shutil.copy(path, folder / path.name)
    stale = _stale_copy(built_fmus["Center2Wheel"], folder / "Center2Wheel.fmu")
    before = stale.read_bytes()
    proc = run_child("validate", ROOT / "scenarios" / "circle.yaml", "--fmu-dir", folder)
    assert proc.returncode == 0, proc.stderr
    assert "Center2Wheel" in proc.stderr and "out of date" in proc.stderr
    assert stale.read_bytes() == before


def test_run_builds_the_missing_fmus_it_needs(tmp_path):
    folder = tmp_path / "fmus"
    proc = run_child("run", ROOT / "scenarios" / "modes" / "forward.yaml", "--fmu-dir", folder,
                     "--no-plots", "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["VelocitySource.fmu", "Center2Wheel.fmu", "Wheel2Center.fmu", "PoseIntegrator.fmu"])


def test_each_instance_has_its_own_log():
    """Two instances with the same name (two simulations) never share FMU messages: the
    logger finds the log through the callbacks' componentEnvironment, not the name."""
    from mecanum_fmu.runtime import Runtime
    runtime = Runtime()
    first, second = runtime.new_log(), runtime.new_log()
    assert first.key != second.key
    runtime._on_log(first.key, b"source", 3, b"error", b"first  failed")
    runtime._on_log(second.key, b"source", 0, b"info", b"second ok")
    runtime._on_log(None, b"source", 0, b"info", b"nobody's")
    assert first.messages == ["[Error] first failed"]
    assert second.messages == ["[OK] second ok"]


def test_output_piped_into_a_reader_that_leaves_is_no_traceback():
    """`mecanum-fmu info ... | head -1`: the reader closes the pipe; the command stops quietly."""
    import subprocess
    from helpers import cli_args, child_env
    proc = subprocess.Popen(cli_args("info", "Wheel2Center"), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=child_env(), cwd=ROOT)
    proc.stdout.close()                       # the reader leaves before anything is written
    err = proc.stderr.read().decode()
    proc.wait(timeout=60)
    assert "Traceback" not in err and "BrokenPipe" not in err, err
    assert proc.returncode in (0, 141)


def _imported(path: Path) -> set[str]:
    """The modules a file imports, absolute (mecanum_fmu.x.y), nested imports included."""
    package = ".".join(path.relative_to(SRC.parent).with_suffix("").parts[:-1])
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            found.add(".".join(p for p in (base, node.module) if p))
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


def test_the_master_core_knows_no_model():
    """The stepping core and the breakpoints read what the graph carries: no models/ import."""
    for name in ("breakpoints", "plan", "stepping"):
        imports = _imported(SRC / "master" / f"{name}.py")
        assert not [m for m in imports if m.startswith("mecanum_fmu.models")], name


def test_nothing_below_the_runner_imports_it():
    """runner.py is the library's `run`; only the commands above it (cli, sweep) import it."""
    below = [p for sub in ("master", "report", "models", "interop", "scenario") for p in
             (SRC / sub).rglob("*.py")]
    offenders = [p.relative_to(ROOT).as_posix() for p in below
                 if "mecanum_fmu.runner" in _imported(p)]
    assert not offenders, offenders
