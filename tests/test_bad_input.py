"""Bad input end to end: every hand-written mistake in tests/bad_scenarios/ gives exit code 2
and a clean `error:` message naming the file, the place and the problem - never a traceback.

Each corpus file starts with comment lines the test reads:
    # expect: <substring of the message>
    # place: <the place the message must name>
    # also: <another substring that must appear>      (optional, repeatable)
FMU files the corpus refers to (not-a-zip, FMI 1.0/3.0, model-exchange only, ...) are made here
in tmp_path, next to a copy of the corpus, so no binaries are committed.
"""
from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
from helpers import CHAIN_CONNECTIONS, child_env

REPO = Path(__file__).resolve().parents[1]
from mecanum_fmu.cli import main

CORPUS_DIR = Path(__file__).resolve().parent / "bad_scenarios"
CORPUS = sorted(CORPUS_DIR.glob("*.yaml"))
SUBPROCESS_ENV = {**os.environ, **child_env()}

COMPONENTS = """\
components:
  source: {fmu: VelocitySource, parameters: {vx_expr: "sin(t)", vy_expr: "cos(t)", w_expr: "0"}}
  c2w:    {fmu: Center2Wheel}
  w2c:    {fmu: Wheel2Center}
  pose:   {fmu: PoseIntegrator}
"""
EXPERIMENT = "experiment: {start_time: 0.0, stop_time: 1.0, step_size: 0.05}\n"


def header(path: Path) -> dict[str, list[str]]:
    """The `# key: value` comment lines at the top of a corpus file."""
    out: dict[str, list[str]] = {"expect": [], "place": [], "also": []}
    for line in path.read_bytes().decode("utf-8").splitlines():
        if not line.startswith("#"):
            break
        key, _, value = line[1:].strip().partition(":")
        if key.strip() in out:
            out[key.strip()].append(value.strip())
    return out


def _zip(path: Path, files: dict[str, str]) -> None:
    with zipfile.ZipFile(path, "w") as zf:
        for name, text in files.items():
            zf.writestr(name, text)


def _md(version: str, body: str, name: str = "Fake") -> str:
    ident = 'guid="{0f0f0f0f-0000-0000-0000-000000000000}"' if version != "3.0" else \
        'instantiationToken="{0f0f0f0f-0000-0000-0000-000000000000}"'
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="{version}" '
            f'modelName="{name}" {ident}>\n{body}\n</fmiModelDescription>\n')


def make_helper_fmus(folder: Path) -> None:
    """The broken and foreign FMUs the corpus names, made small and on the spot."""
    (folder / "notazip.fmu").write_bytes(b"this is plain text, not a zip archive\n")
    _zip(folder / "nomd.fmu", {"readme.txt": "an archive without modelDescription.xml"})
    # FMI 1.0: modelIdentifier on the root, no CoSimulation element (as FMI 1.0 writes it)
    _zip(folder / "fmi1.fmu", {"modelDescription.xml": _md(
        "1.0", "<ModelVariables/>", "Old").replace('modelName="Old"',
                                                  'modelName="Old" modelIdentifier="Old"')})
    _zip(folder / "fmi3.fmu", {"modelDescription.xml": _md(
        "3.0", '<CoSimulation modelIdentifier="New"/><ModelVariables/><ModelStructure/>', "New")})
    _zip(folder / "me_only.fmu", {"modelDescription.xml": _md(
        "2.0", '<ModelExchange modelIdentifier="Me"/><ModelVariables/><ModelStructure/>', "Me")})
    # An FMI 2.0 co-simulation description with one Integer output: enough for every check
    # `validate` makes (it only reads model descriptions; nothing is instantiated).
    _zip(folder / "counter.fmu", {"modelDescription.xml": _md("2.0", """
  <CoSimulation modelIdentifier="badinput_counter"/>
  <ModelVariables>
    <ScalarVariable name="count" valueReference="0" causality="output" variability="discrete"
                    initial="exact"><Integer start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1" dependencies=""/></Outputs></ModelStructure>""",
        "badinput_counter")})
    counter = (folder / "counter.fmu")
    with zipfile.ZipFile(counter) as zf:
        md = zf.read("modelDescription.xml").decode()
    # unsafe archives (issue 13): a member that leaves the folder, a zip bomb, a wrapping vr
    _zip(folder / "escape.fmu", {"modelDescription.xml": md, "../../escaped.txt": "x"})
    _zip(folder / "vr32.fmu", {"modelDescription.xml": md.replace('valueReference="0"',
                                                                  'valueReference="4294967296"')})
    _zip(folder / "bomb.fmu", {"modelDescription.xml": md, "resources/bomb.bin": "\0" * 1000})
    _zip(folder / "dot.fmu", {"modelDescription.xml": md, ".": "x"})      # issue 23, old set
    _declare_size(folder / "bomb.fmu", "resources/bomb.bin", 0xFFFF_FFF0)


def _declare_size(path: Path, member: str, size: int) -> None:
    """Make member claim to inflate to size bytes (local and central headers)."""
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        local, central = zf.getinfo(member).header_offset, zf.start_dir
        for info in zf.infolist():
            if info.filename == member:
                break
            n, m, k = struct.unpack_from("<HHH", data, central + 28)
            central += 46 + n + m + k
    struct.pack_into("<I", data, local + 22, size)
    struct.pack_into("<I", data, central + 24, size)
    path.write_bytes(bytes(data))


@pytest.fixture
def corpus(tmp_path: Path) -> Path:
    """A copy of the corpus with its helper FMUs; the cwd is that folder."""
    folder = tmp_path / "corpus"
    shutil.copytree(CORPUS_DIR, folder)
    make_helper_fmus(folder)
    return folder


def validate(path: Path, capsys) -> tuple[int, str, str]:
    code = main(["validate", str(path)])
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean_error(code: int, err: str, path: Path, expect: list[str]) -> None:
    assert code == 2, err
    assert "Traceback" not in err
    assert err.startswith("error:"), err
    assert path.name in err, err
    for text in expect:
        assert text in err, f"{text!r} not in:\n{err}"


def test_corpus_is_big_and_annotated():
    assert len(CORPUS) >= 32
    for path in CORPUS:
        meta = header(path)
        assert meta["expect"] and meta["place"], f"{path.name}: missing # expect: / # place:"


@pytest.mark.parametrize("name", [p.name for p in CORPUS])
def test_bad_scenario(name, corpus, capsys, monkeypatch):
    monkeypatch.chdir(corpus)
    path = corpus / name
    meta = header(path)
    started = time.monotonic()
    code, out, err = validate(path, capsys)
    assert time.monotonic() - started < 30
    assert_clean_error(code, err, path, meta["expect"] + meta["place"] + meta["also"])
    assert "ok -" not in out
    # every problem line is `file: place: message`
    problem_lines = [line for line in err.splitlines() if line.startswith("  ")]
    assert problem_lines and all(str(path) in line for line in problem_lines), err
    assert len(err) < 20_000        # messages stay short even for huge values


def test_expression_injection_runs_nothing(corpus, capsys, monkeypatch):
    monkeypatch.chdir(corpus)
    for command in ("validate", "run"):
        code = main([command, str(corpus / "37_expression_injection.yaml"), *(
            ["--out", str(corpus / "out"), "--no-plots", "--quiet"] if command == "run" else [])])
        assert code == 2
    _, err = capsys.readouterr()
    assert "Traceback" not in err
    assert not list(corpus.rglob("pwned_by_scenario"))
    assert not (REPO / "pwned_by_scenario").exists()
    assert not (corpus / "out").exists()


def test_all_problems_reported_at_once(corpus, capsys):
    path = corpus / "47_three_mistakes.yaml"
    code, _, err = validate(path, capsys)
    assert code == 2
    assert err.splitlines()[0] == "error: 3 problem(s) in the input:"
    assert len([line for line in err.splitlines() if line.startswith("  ")]) == 3


def test_algebraic_loop_names_its_variables(corpus, capsys):
    code, _, err = validate(corpus / "17_algebraic_loop.yaml", capsys)
    assert code == 2
    for var in ("c2w.vx", "c2w.w1", "w2c.w1", "w2c.vx"):
        assert var in err


def test_huge_file(tmp_path, capsys):
    path = tmp_path / "huge.yaml"
    with path.open("w") as f:
        f.write(EXPERIMENT + COMPONENTS)
        f.write("description: >\n")
        for _ in range(30_000):
            f.write("  " + "lorem ipsum " * 4 + "\n")
    assert path.stat().st_size > 1_000_000
    code, _, err = validate(path, capsys)
    assert_clean_error(code, err, path, ["too large", "file"])


def test_non_utf8_file(tmp_path, capsys):
    path = tmp_path / "latin1.yaml"
    path.write_bytes(("description: Fahrzeug f\u00fcr Kreisfahrt\n" + EXPERIMENT + COMPONENTS)
                     .encode("latin-1"))
    code, _, err = validate(path, capsys)
    assert_clean_error(code, err, path, ["is not UTF-8", "file"])


@pytest.mark.parametrize("content, expect", [
    ("", "is empty"),                                           # empty file -> None
    ("# only a comment\n", "is empty"),
    ("just some text", "expected a mapping"),
    ("42", "expected a mapping"),
    ("components: {a: {fmu: VelocitySource}}\n\t- tab", "YAML syntax error"),
    ("? [a, b]\n: 1\n", "YAML"),                               # unhashable key
    ("components: !!python/object/apply:os.system ['true']", "YAML"),   # safe_load refuses
    ("components: {a: &x {fmu: *x}}", "fmu"),                  # recursive alias
])
def test_more_bad_yaml(tmp_path, capsys, content, expect):
    path = tmp_path / "odd.yaml"
    path.write_text(content)
    code, _, err = validate(path, capsys)
    assert_clean_error(code, err, path, [expect])


def test_scenario_is_a_folder_or_missing(tmp_path, capsys):
    code, _, err = validate(tmp_path, capsys)
    assert_clean_error(code, err, tmp_path, ["is a folder"])
    code, _, err = validate(tmp_path / "nope.yaml", capsys)
    assert_clean_error(code, err, tmp_path / "nope.yaml", ["not found"])


def test_feedback_through_pose_is_not_a_loop(tmp_path, capsys):
    """pose.theta -> c2w.w closes a cycle, but PoseIntegrator has no direct feedthrough."""
    path = tmp_path / "feedback.yaml"
    path.write_text(EXPERIMENT + COMPONENTS
                    + CHAIN_CONNECTIONS.replace("[source.w,  c2w.w]", "[pose.theta, c2w.w]"))
    assert "[pose.theta, c2w.w]" in path.read_text()
    code, out, err = validate(path, capsys)
    assert code == 0, err
    assert "ok -" in out
    assert "algebraic loop" not in err


def test_unconnected_input_is_a_warning(tmp_path, capsys):
    path = tmp_path / "loose.yaml"
    path.write_text(EXPERIMENT + COMPONENTS
                    + CHAIN_CONNECTIONS.replace("  - [source.w,  c2w.w]\n", ""))
    code, out, err = validate(path, capsys)
    assert code == 0, err
    assert "warning:" in err and "input 'w' is not connected" in err
    assert "components.c2w" in err
    assert "error" not in err


@pytest.mark.parametrize("name", ["03_unknown_top_level_key.yaml", "17_algebraic_loop.yaml",
                                  "36_billion_laughs.yaml"])
def test_subprocess_run(name, corpus, tmp_path):
    """`python -m mecanum_fmu run` end to end: exit code 2, clean message, nothing written."""
    path = corpus / name
    meta = header(path)
    out_dir = tmp_path / "results"
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "run", str(path),
                           "--out", str(out_dir), "--no-plots"],
                          cwd=corpus, env=SUBPROCESS_ENV, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    for text in [path.name] + meta["expect"] + meta["place"] + meta["also"]:
        assert text in proc.stderr, f"{text!r} not in:\n{proc.stderr}"
    assert not out_dir.exists()


def test_a_root_folder_entry_is_harmless(tmp_path):
    """Issue 23, old set: a './' folder entry (the archive's own folder, written by some zip
    tools) names nothing to extract; it is skipped, not refused. A file named '.' is."""
    from mecanum_fmu.archive import ArchiveError, checked_members
    path = tmp_path / "root.zip"
    _zip(path, {"./": "", "modelDescription.xml": "<x/>"})
    with zipfile.ZipFile(path) as zf:
        assert [i.filename for i in checked_members(zf)] == ["modelDescription.xml"]
    _zip(path, {".": "x", "modelDescription.xml": "<x/>"})
    with zipfile.ZipFile(path) as zf, pytest.raises(ArchiveError, match="names the extraction"):
        checked_members(zf)
