"""Hostile input (issue 13, the input half): damaged and unsafe archives (FMU and SSP), zip
bombs, unbounded numbers, special files, names that could leave results/.

Every case ends in exit 2 with a clean message naming the file and the place, or in a clean
run; never a traceback, a file written outside --out or a temporary folder left behind.
Archives are damaged here, on the spot, from the freshly built bundled FMUs: no binaries are
committed.
"""
from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest
from helpers import child_env, run_main
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mecanum_fmu import archive
from mecanum_fmu.interop import ssp_read
from mecanum_fmu.archive import ArchiveError, extract_all
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.runtime import RUNTIME
from mecanum_fmu.scenario.document import load_scenario, usable_name
from mecanum_fmu.interop.ssp_read import load_ssp

POSE_ALONE = """\
experiment: {{start_time: 0.0, stop_time: 0.1, step_size: 0.05, master: gauss-seidel}}
components:
  pose: {{fmu: {fmu}}}
"""
SO = "binaries/linux64/PoseIntegrator.so"
SCRIPT = "resources/mecanum_fmu_pose_integrator.py"


# -- archive surgery ---------------------------------------------------------------------------
def members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as zf:
        return {i.filename: zf.read(i) for i in zf.infolist()}


def write_members(path: Path, content: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in content.items():
            zf.writestr(zipfile.ZipInfo(name, (1980, 1, 1, 0, 0, 0)), data)
    return path


def _headers(data: bytes) -> list[tuple[int, int]]:
    """(central directory entry offset, local header offset) of every member."""
    with zipfile.ZipFile(__import__("io").BytesIO(data)) as zf:
        pos, out = zf.start_dir, []
        for info in zf.infolist():
            n, m, k = struct.unpack_from("<HHH", data, pos + 28)
            out.append((pos, info.header_offset))
            pos += 46 + n + m + k
    return out


def declare_size(data: bytes, index: int, size: int) -> bytes:
    """The archive with member index claiming to inflate to size bytes (both headers)."""
    out = bytearray(data)
    central, local = _headers(data)[index % len(_headers(data))]
    struct.pack_into("<I", out, central + 24, size)
    struct.pack_into("<I", out, local + 22, size)
    return bytes(out)


def flip(data: bytes, at: int, mask: int) -> bytes:
    out = bytearray(data)
    out[at % len(out)] ^= mask
    return bytes(out)


def flip_inside(path: Path, member: str, into: int = 500) -> bytes:
    """The archive with one byte of member's compressed data flipped (a CRC error)."""
    data = path.read_bytes()
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
    n, m = struct.unpack_from("<HH", data, info.header_offset + 26)
    return flip(data, info.header_offset + 30 + n + m + min(into, info.compress_size - 1), 0xFF)


def rename(path: Path, index: int, new: str) -> dict[str, bytes]:
    content = members(path)
    names = list(content)
    old = names[index % len(names)]
    return {(new if name == old else name): data for name, data in content.items()}


# -- fixtures ----------------------------------------------------------------------------------
@pytest.fixture
def sandbox(tmp_path, monkeypatch):
    """tmp_path as the cwd, with its own temporary folder and cache to watch for leftovers."""
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def leftovers(tmp: Path) -> list[str]:
    """Temporary folders and partial files not owned by the runtime's extraction cache."""
    kept = {Path(p).name for p in RUNTIME._extracted.values()}
    return sorted(p.name for p in tmp.iterdir() if p.name not in kept) + sorted(
        str(p) for p in tmp.parent.rglob(".*.part"))


def assert_clean(code: int, err: str, *names: str) -> None:
    assert code == 2, err
    assert "Traceback" not in err and err.startswith("error:"), err
    problems = [line for line in err.splitlines() if line.startswith("  ")]
    assert len(problems) == 1, err
    for name in names:
        assert name in problems[0], err


# -- class 1: an FMU that cannot be loaded -----------------------------------------------------
@pytest.mark.parametrize("damage, stage, expect", [
    ("no_binary", "validate", "has no binary for this platform"),
    ("no_platform_folder", "validate", "no binaries at all"),
    ("garbage_binary", "run", "cannot be loaded"),
    ("crc_binary", "run", "is damaged"),
    ("absolute_member", "validate", "is an absolute path"),
    ("dotdot_member", "validate", "could leave the extraction folder"),
    ("no_slave_script", "validate", "slave script"),
    ("no_slavemodule_txt", "validate", "without resources/slavemodule.txt"),   # was a segfault
    ("raising_slave_script", "run", "cannot be instantiated"),
])
def test_fmu_that_cannot_be_loaded(damage, stage, expect, built_fmus, sandbox, capsys):
    good = built_fmus["PoseIntegrator"]
    fmu = sandbox / f"{damage}.fmu"
    content = members(good)
    if damage == "crc_binary":
        fmu.write_bytes(flip_inside(good, SO))
    else:
        if damage == "no_binary":
            content.pop(SO)
        elif damage == "no_platform_folder":
            content = {k: v for k, v in content.items() if not k.startswith("binaries/")}
        elif damage == "garbage_binary":
            content[SO] = b"\x7fELF but not really" * 50
        elif damage == "absolute_member":
            content[str(sandbox / "escaped.txt")] = b"x"
        elif damage == "dotdot_member":
            content["../escaped.txt"] = b"x"
        elif damage == "no_slave_script":
            content["resources/renamed.py"] = content.pop(SCRIPT)
        elif damage == "no_slavemodule_txt":
            content["a/"] = content.pop("resources/slavemodule.txt")
        elif damage == "raising_slave_script":
            content[SCRIPT] = b"raise RuntimeError('broken on purpose')\n"
        write_members(fmu, content)
    scenario = sandbox / "s.yaml"
    scenario.write_text(POSE_ALONE.format(fmu=fmu.name))
    code, _, err = run_main(capsys, "validate", scenario)
    if stage == "validate":
        assert_clean(code, err, fmu.name, "components.pose.fmu", expect)
        return
    assert code == 0, err
    code, _, err = run_main(capsys, "run", scenario, "--out", "out", "--no-plots", "--quiet")
    assert_clean(code, err, fmu.name, "components.pose", "'pose'", expect)
    assert not (sandbox / "escaped.txt").exists() and not (sandbox.parent / "escaped.txt").exists()
    assert leftovers(sandbox / "tmp") == []
    assert sorted(p.name for p in sandbox.iterdir()) == sorted(
        ["tmp", "s.yaml", fmu.name, "out"] + (["cache"] if (sandbox / "cache").exists() else []))


# -- class 2: zip bombs inside FMUs ------------------------------------------------------------
def test_declared_bomb_refused_before_extraction(built_fmus, sandbox, capsys):
    content = members(built_fmus["PoseIntegrator"])
    names = list(content)
    fmu = sandbox / "bomb.fmu"
    # a member declaring ~4 GiB: over the per-member limit, refused from the headers alone
    fmu.write_bytes(declare_size(write_members(fmu, content).read_bytes(),
                                 names.index(SCRIPT), 0xFFFF_FFF0))
    scenario = sandbox / "s.yaml"
    scenario.write_text(POSE_ALONE.format(fmu=fmu.name))
    code, _, err = run_main(capsys, "validate", scenario)
    assert_clean(code, err, "bomb.fmu", "inflates to 4 GiB")
    with pytest.raises(ArchiveError, match="inflates to"):
        extract_all(fmu, "bomb_")
    assert leftovers(sandbox / "tmp") == []


def test_inflation_counted_during_extraction(built_fmus, sandbox, monkeypatch):
    """Limits hold on the bytes actually inflated, not only on the headers: a member whose
    header understates its size stops at the declared size (then fails its CRC), and the
    partial folder is removed."""
    fmu = write_members(sandbox / "liar.fmu", {"modelDescription.xml": b"<x/>",
                                               "resources/big.bin": b"\0" * (1 << 20)})
    fmu.write_bytes(declare_size(fmu.read_bytes(), 1, 1000))
    with pytest.raises(ArchiveError, match="resources/big.bin"):
        extract_all(fmu, "liar_")
    assert leftovers(sandbox / "tmp") == []
    # the per-member and total limits during extraction (lowered here: no GiB written)
    monkeypatch.setattr(archive, "MAX_MEMBER_BYTES", 100_000)
    with pytest.raises(ArchiveError, match="limit"):
        extract_all(built_fmus["PoseIntegrator"], "limited_")
    assert leftovers(sandbox / "tmp") == []


# -- class 3: damaged or oversized SSP members -------------------------------------------------
@pytest.fixture(scope="module")
def exported_circle(fmu_dir, tmp_path_factory) -> Path:
    """The circle's SSP, exported once for the module by `export-ssp` in this process."""
    from mecanum_fmu import cli
    root = Path(__file__).resolve().parents[1]
    path = tmp_path_factory.mktemp("circle_ssp") / "circle.ssp"
    assert cli.main(["export-ssp", str(root / "scenarios" / "circle.yaml"), "-o", str(path),
                     "--fmu-dir", str(fmu_dir)]) == 0
    return path


@pytest.fixture
def circle_ssp(exported_circle, sandbox) -> Path:
    """A copy of the circle's SSP in the sandbox (an export is the same bytes each time)."""
    return Path(shutil.copy(exported_circle, sandbox / "circle.ssp"))


def _ssd_with_parameter_file(content: dict[str, bytes], member: str) -> dict[str, bytes]:
    ssd = content["SystemStructure.ssd"].decode().replace(
        "<ssd:ParameterBindings>",
        f'<ssd:ParameterBindings><ssd:ParameterBinding source="{member}"/>', 1)
    return {**content, "SystemStructure.ssd": ssd.encode()}


@pytest.mark.parametrize("damage, place, expect", [
    ("crc_ssd", "SystemStructure.ssd", "is damaged"),
    ("crc_fmu", "@source", "is damaged"),
    ("big_parameter_file", "@source", "inflates to"),
    ("folder_like_member", "file", "is both a file and a folder"),
    ("dotdot_member", "file", "could leave the extraction folder"),
    ("huge_integer", "Parameter[1]", "too large"),
    ("fmu_over_limit", "file", "limit"),
])
def test_damaged_ssp(damage, place, expect, circle_ssp, sandbox, capsys, monkeypatch):
    content = members(circle_ssp)
    ssp = sandbox / f"{damage}.ssp"
    if damage == "crc_ssd":
        ssp.write_bytes(flip_inside(circle_ssp, "SystemStructure.ssd", 40))
    elif damage == "crc_fmu":
        ssp.write_bytes(flip_inside(circle_ssp, "resources/PoseIntegrator.fmu", 5000))
    else:
        if damage == "big_parameter_file":
            monkeypatch.setattr(ssp_read, "_MAX_SSD_BYTES", 200_000)
            content = _ssd_with_parameter_file(content, "resources/p.ssv")
            content["resources/p.ssv"] = b" " * 300_000
        elif damage == "folder_like_member":
            content["resources/PoseIntegrator.fmu/inside"] = b"x"
        elif damage == "dotdot_member":
            content["resources/../../x"] = b"x"
        elif damage == "huge_integer":
            # c2w's first parameter, L = 0.16 (String values are not in the SSD: in the FMUs)
            ssd = content["SystemStructure.ssd"]
            assert ssd.count(b'<ssv:Real value="0.16" />') == 2          # c2w's and w2c's
            content["SystemStructure.ssd"] = ssd.replace(
                b'<ssv:Real value="0.16" />', b'<ssv:Integer value="1' + b"0" * 400 + b'" />', 1)
        elif damage == "fmu_over_limit":
            monkeypatch.setattr(archive, "MAX_MEMBER_BYTES", 100_000)
        write_members(ssp, content)
    code, _, err = run_main(capsys, "validate", ssp)
    assert_clean(code, err, ssp.name, place, expect)
    assert leftovers(sandbox / "tmp") == []


def test_ssp_cache_member_named_like_a_folder(circle_ssp, sandbox, capsys):
    """A cache entry that is a folder where the FMU copy should go: a clean error."""
    code, _, err = run_main(capsys, "validate", circle_ssp)
    assert code == 0, err
    for fmu in (sandbox / "cache").rglob("PoseIntegrator.fmu"):
        fmu.unlink()
        fmu.mkdir()
        (fmu / "x").write_text("x")
    code, _, err = run_main(capsys, "validate", circle_ssp)
    assert_clean(code, err, "circle.ssp", "cannot be copied into the cache")


# -- class 4: numbers --------------------------------------------------------------------------
def test_value_reference_of_2_to_the_32_is_refused(built_fmus, sandbox, capsys):
    content = members(built_fmus["PoseIntegrator"])
    md = content["modelDescription.xml"].decode()
    first = md.index('valueReference="')
    end = md.index('"', first + 16)
    content["modelDescription.xml"] = (md[:first] + 'valueReference="4294967296' +
                                       md[end:]).encode()
    fmu = write_members(sandbox / "vr.fmu", content)
    scenario = sandbox / "s.yaml"
    scenario.write_text(POSE_ALONE.format(fmu=fmu.name))
    code, _, err = run_main(capsys, "validate", scenario)
    assert_clean(code, err, "vr.fmu", "valueReference 4294967296", "2**32-1")


# -- class 5: special files, duplicate keys, control characters --------------------------------
@pytest.mark.parametrize("kind", ["fifo.yaml", "fifo.ssp", "fifo.ssd", "/dev/zero"])
def test_special_files_are_refused(kind, tmp_path):
    """In a child: before the fix a FIFO hung the process and /dev/zero ate the memory."""
    path = kind if kind.startswith("/") else str(tmp_path / kind)
    if not kind.startswith("/"):
        os.mkfifo(path)
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "validate", path],
                          capture_output=True, text=True, timeout=120, env=child_env(tmp_path))
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert f"{path}: file: is not a regular file" in proc.stderr


def test_duplicate_keys_name_both_lines(sandbox):
    path = sandbox / "dup.yaml"
    path.write_text("components:\n  a: {fmu: VelocitySource}\n  b: {fmu: Center2Wheel}\n"
                    "  a: {fmu: Wheel2Center}\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert str(err.value) == (f"{path}: line 4, column 3: YAML syntax error: duplicate key "
                              "'a' (first given on line 2); keep one")


def test_control_characters_are_escaped(sandbox, capsys):
    path = sandbox / "esc\x1b[2Jape.yaml"
    path.write_text('components:\n  a: {fmu: VelocitySource}\n'
                    'connections: [["ev\\e[31mil\\u202e.x", "a.vx"]]\n')
    code, _, err = run_main(capsys, "validate", path)
    assert code == 2 and "\x1b" not in err and "\u202e" not in err, repr(err)
    assert "esc\\x1b[2Jape.yaml" in err and "ev\\x1b[31mil\\u202e" in err, err


# -- class 6: names that could leave results/ --------------------------------------------------
@pytest.mark.parametrize("text, name", [("..", None), (".", None), ("a/../..", "a_.._.."),
                                        ("../../etc", ".._.._etc"), ("x" * 300, "x" * 100)])
def test_usable_names(text, name):
    assert usable_name(text) == name


@given(st.text(max_size=120))
def test_results_folder_never_leaves_results(text):
    name = usable_name(text)
    if name is not None:
        results = Path("/r/results")
        assert (results / name).resolve().parent == results and len(name) <= 100


def test_dot_dot_names_in_yaml_and_ssd(circle_ssp, sandbox):
    yaml_path = sandbox / "..yaml"          # stem "."; no name: key
    yaml_path.write_text("components:\n  a: {fmu: VelocitySource}\n")
    assert load_scenario(yaml_path).name == "scenario"
    named = sandbox / "named.yaml"
    named.write_text("name: ..\ncomponents:\n  a: {fmu: VelocitySource}\n")
    with pytest.raises(ScenarioError, match="not a usable name"):
        load_scenario(named)
    content = members(circle_ssp)
    content["SystemStructure.ssd"] = content["SystemStructure.ssd"].replace(
        b'name="circle"', b'name=".."', 1)
    odd = write_members(sandbox / "...ssp", content)      # stem ".." too
    assert load_ssp(odd).name == "scenario"


# -- Hypothesis: damaged archives --------------------------------------------------------------
NAMES = ["../x", "/abs", "a/", "x\\y", "resources/", "modelDescription.xml", "./a", "a//b",
         "binaries/linux64/PoseIntegrator.so/x", "C:/x"]
DAMAGE = st.one_of(
    st.tuples(st.just("flip"), st.integers(0, 10**7), st.integers(1, 255)),
    st.tuples(st.just("truncate"), st.integers(0, 10**7)),
    st.tuples(st.just("rename"), st.integers(0, 50), st.sampled_from(NAMES)),
    st.tuples(st.just("inflate"), st.integers(0, 50), st.sampled_from([0, 7, 2**31, 2**32 - 2])),
)


def damaged(path: Path, damage: tuple, out: Path) -> Path:
    kind, *args = damage
    data = path.read_bytes()
    if kind == "flip":
        data = flip(data, *args)
    elif kind == "truncate":
        data = data[:args[0] % len(data)]
    elif kind == "rename":
        return write_members(out, rename(path, *args))
    else:
        data = declare_size(data, *args)
    out.write_bytes(data)
    return out


SETTINGS = settings(max_examples=25, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.mark.heavy(6)
@SETTINGS
@given(damage=DAMAGE)
def test_damaged_fmu_never_crashes(damage, built_fmus, sandbox, capsys):
    """validate in this process (it reads the archive, loads nothing); a run, in a child,
    only when validate accepts it (loading a broken library may take the process down)."""
    with tempfile.TemporaryDirectory(dir=sandbox) as folder:
        fmu = damaged(built_fmus["PoseIntegrator"], damage, Path(folder) / "d.fmu")
        scenario = Path(folder) / "s.yaml"
        scenario.write_text(POSE_ALONE.format(fmu="d.fmu"))
        code, _, err = run_main(capsys, "validate", scenario)
        assert "Traceback" not in err and code in (0, 2), err
        if code == 2:
            assert_clean(code, err, "d.fmu")
            return
        try:
            shutil.rmtree(extract_all(fmu, "hypothesis_"))
        except ArchiveError:
            pass
        assert leftovers(sandbox / "tmp") == []
        proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "run", str(scenario),
                               "--out", str(Path(folder) / "out"), "--no-plots", "--quiet"],
                              capture_output=True, text=True, timeout=120,
                              env=child_env(Path(folder)), cwd=folder)
        assert proc.returncode in (0, 2) and "Traceback" not in proc.stderr, proc.stderr
        assert not [p for p in Path(folder).iterdir() if p.name.startswith("mecanum_")]


@SETTINGS
@given(damage=DAMAGE)
def test_damaged_ssp_never_crashes(damage, circle_ssp, sandbox, capsys):
    with tempfile.TemporaryDirectory(dir=sandbox) as folder:
        ssp = damaged(circle_ssp, damage, Path(folder) / "d.ssp")
        code, _, err = run_main(capsys, "validate", ssp)
        assert "Traceback" not in err and code in (0, 2), err
        if code == 2:
            assert err.startswith("error:") and "d.ssp" in err, err
        assert not list((sandbox / "cache").rglob(".*.part"))
