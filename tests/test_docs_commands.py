"""Every command in README.md and docs/*.md runs as written (issue 20, item 6).

The commands are the lines of the shell code blocks (```sh, bash, shell, console; with `$ `
prompts only the prompted lines) and the inline code spans that call the venv's Python or the
package (`.venv/bin/python -m mecanum_fmu info Center2Wheel`). They run one after another, in
the order a reader meets them (README.md, then docs/*.md by name; the long ones, HEAVY, first
and the tests split between pytest-xdist's workers), in bash, from one fresh copy
of the checkout as `make run` leaves it (the FMUs built, results/circle/ written), outside the
venv (its bin/ is not on PATH); a command written in several places runs once per copy. Each must exit 0, or the code its trailing comment names
(`# exit 2`). A command that is known to be long is skipped by an entry of SKIPS with its
reason; anything else that does not run cleanly fails, naming the file, the line, the command
and the end of its stderr.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from helpers import ROOT

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL_LANGUAGES = {"sh", "bash", "shell", "console"}
TIMEOUT = 600        # a safety net against a hung command, not a measurement
# Programs that only the venv has: written bare they run another interpreter, or nothing.
VENV_ONLY = re.compile(r"(?:^|[\s;|&(=])(python3?|mecanum-fmu|fmpy|pytest|pip)(?=\s|$)")

# (pattern searched in the command, why it is not run here). Keep each reason true.
SKIPS = [
    (r"^make (run|fmus)\b", "builds the venv and the FMUs: the state this test starts from "
                            "(the copy's fixture runs its `run scenarios/circle.yaml` step)"),
    (r"^make test\b", "the whole test suite, this test included"),
    (r"^make bench\b|\bbench/\w+\.py\b", "a benchmark: minutes, and it measures time "
                                         "(docs/benchmarks.md)"),
    (r"-m mecanum_fmu sweep\b", "a sweep: 1,000 runs on Dask workers, a minute or more "
                                "(tests/test_sweep.py runs small sweeps)"),
    (r"run scenarios/robot/(circle|track_circle)\.yaml", "10,000 steps of eight FMUs and "
     "the estimate's two more runs: minutes on a loaded machine (tests/test_robot.py runs "
     "both scenarios)"),
    (r"run scenarios/robot/belief_drive_track_(circle|gyro)\.yaml", "10,000 steps of "
     "fourteen FMUs: 15 s each on a quiet machine (tests/test_robot_belief.py runs both; its "
     "`run` of the first one, to 2 s, writes the report and every figure)"),
    (r"--animate\b", "draws a GIF frame by frame: minutes on a loaded machine "
                     "(tests/test_plots.py covers the animation)"),
    (r"\bdocs/make_gallery\.py\b", "redraws docs/img/ (the gallery and its animation): minutes"),
    (r"\bdocs/drift_study\.py\b", "reads the runs.csv of the belief_drift sweep (minutes; "
                                  "skipped above)"),
    (r"\bOMSimulator\b", "OpenModelica's OMSimulator: not installed by make "
                         "(docs/openmodelica.md is followed by hand)"),
    (r"\$B/ecos\b|\./ecos\b", "the Ecos program copied out of ecospy by hand; `cross-check` "
                              "and tests/test_no_preload.py run it as ecos-cli"),
    (r"<[a-z][\w ]*>|(?<![\w=$-])[A-Z]{2,}[\w]*\.(yaml|ssp|csv)\b|\bsystem\.ssp\b",
     "a template: a placeholder stands for the reader's own file or value"),
    (r"-m mecanum_fmu\.interop\.other_hosts$", "names the per-host child process that "
                                                "`cross-check` starts with its job as arguments"),
]

# Commands that are known not to run today, each with the issue or branch that fixes it. Keyed
# by the command exactly as written: rewriting the command retires its entry. The test is an
# xfail(strict): when the command runs again, it reports XPASS and the entry must go.
KNOWN_BROKEN: dict[str, str] = {
    # "the command as written": "why it fails and which issue fixes it" (a strict xfail)
}


@dataclass(frozen=True)
class DocCommand:
    file: str            # relative to the checkout
    line: int            # where the command starts
    text: str            # as written (continuation lines joined, trailing comment cut)
    comment: str         # the trailing comment, if any
    venv_active: bool    # the paragraph before it says "with the venv active"
    before: tuple = ()   # the commands above it in its shell block: a reader runs them first

    def where(self) -> str:
        return f"{self.file}:{self.line}"


def split_comment(line: str) -> tuple[str, str]:
    """`cmd  # note` -> ("cmd", "note"); a # inside quotes is kept."""
    for match in re.finditer(r"\s#", line):
        before = line[:match.start()]
        if before.count('"') % 2 == 0 and before.count("'") % 2 == 0:
            return before.rstrip(), line[match.end():].strip()
    return line.rstrip(), ""


def block_commands(lines: list[str]) -> list[tuple[int, str, str]]:
    """(offset, command, comment) of a shell block's lines."""
    prompted = any(line.startswith("$ ") for line in lines)
    found, i = [], 0
    while i < len(lines):
        start, line = i, lines[i]
        while line.endswith("\\") and i + 1 < len(lines):
            i += 1
            line = line[:-1].rstrip() + " " + lines[i].strip()
        i += 1
        if prompted:
            if not line.startswith("$ "):
                continue
            line = line[2:]
        text, comment = split_comment(line.strip())
        if text and not text.startswith("#"):
            found.append((start, text, comment))
    return found


def is_inline_command(span: str) -> bool:
    """A code span that calls Python or the package with something to do (not a bare name
    such as `python -m mecanum_fmu`)."""
    span = re.sub(r"^(\w+=\S+\s+)+", "", span)
    match = re.match(r"(\.venv/bin/)?(python3?|mecanum-fmu)\s+(.*)$", span)
    if not match:
        return False
    rest = match.group(3).strip()
    return bool(rest) and rest not in ("-m mecanum_fmu", "-m")


def paragraph_before(lines: list[str], index: int) -> str:
    start = index
    while start > 0 and lines[start - 1].strip():
        start -= 1
    return " ".join(lines[start:index + 1])


def extract(path: Path, root: Path = ROOT) -> list[DocCommand]:
    """The commands of one markdown file, in reading order."""
    rel = str(path.relative_to(root))
    lines = path.read_text().splitlines()
    found, prose, i = [], [], 0
    while i < len(lines):
        fence = re.match(r"^```\s*(\w*)", lines[i])
        if not fence:
            prose.append(lines[i])
            i += 1
            continue
        end = next((j for j in range(i + 1, len(lines)) if lines[j].startswith("```")), len(lines))
        if fence.group(1) in SHELL_LANGUAGES:
            active = "venv active" in paragraph_before(lines, i - 1)
            block: list[DocCommand] = []
            for offset, text, comment in block_commands(lines[i + 1:end]):
                block.append(DocCommand(rel, i + 2 + offset, text, comment, active,
                                        tuple(block)))
            found += block
        prose += [""] * (end + 1 - i)              # keep the line numbers of the prose
        i = end + 1
    return sorted(found + inline_commands(rel, prose), key=lambda c: c.line)


def inline_commands(rel: str, prose: list[str]) -> list[DocCommand]:
    text = "\n".join(prose)
    found = []
    for match in re.finditer(r"`([^`]+)`", text):
        span = " ".join(match.group(1).split())
        if is_inline_command(span):
            line = text.count("\n", 0, match.start()) + 1
            active = "venv active" in paragraph_before(prose, line - 1)
            found.append(DocCommand(rel, line, span, "", active))
    return found


COMMANDS = [command for doc in DOCS for command in extract(doc)]


# (pattern, seconds on a quiet machine): the long commands that run here, started first
# (@pytest.mark.heavy, tests/conftest.py) so that none is left alone at the end of the suite
HEAVY = [(r"run scenarios/chassis/\*", 7)]


def marks(command: DocCommand) -> list:
    """A known broken command's strict xfail; a long one's heavy mark."""
    found = [pytest.mark.heavy(seconds) for pattern, seconds in HEAVY
             if re.search(pattern, command.text)][:1]
    if command.text in KNOWN_BROKEN:
        found.append(pytest.mark.xfail(strict=True, reason=f"{KNOWN_BROKEN[command.text]}; once "
                     "it runs, delete its entry in KNOWN_BROKEN (tests/test_docs_commands.py)"))
    return found


def params() -> list:
    """The commands that run here (the long ones, SKIPS, are checked without running them by
    test_long_commands_are_written_for_the_venv: no test is skipped)."""
    return [pytest.param(command, id=command.where(), marks=marks(command))
            for command in COMMANDS if skip_reason(command.text) is None]


def venv() -> Path:
    """The venv that runs this test (what `make` made), else the checkout's .venv/."""
    return Path(sys.prefix) if sys.prefix != sys.base_prefix else ROOT / ".venv"


def checkout_files() -> list[str]:
    """What a fresh clone holds: the tracked files plus new ones not ignored (this work tree)."""
    proc = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                          cwd=ROOT, capture_output=True, text=True)
    if proc.returncode == 0:
        return [name for name in proc.stdout.split("\0") if name and (ROOT / name).is_file()]
    # not a git checkout: everything but what make and the tests make
    made = {".git", ".venv", "results", "build", "__pycache__", ".hypothesis", ".pytest_cache"}
    return [str(path.relative_to(ROOT)) for path in sorted(ROOT.rglob("*"))
            if path.is_file() and path.suffix != ".fmu" and not any(
                part in made or part.endswith(".egg-info") for part in path.relative_to(ROOT).parts)]


def bytecode() -> list[str]:
    """src/'s compiled modules, as `make` leaves them (its `bytecode` step). copy2 keeps each
    source's time, so the copies stay valid: the commands do not compile the package again."""
    return [str(p.relative_to(ROOT)) for p in sorted((ROOT / "src").glob("**/__pycache__/*.pyc"))]


def command_env(copy: Path, tmp: Path, venv_active: bool = False) -> dict[str, str]:
    """The reader's shell: outside the venv unless the doc says it is active. PYTHONPATH
    points at the copy's src/, as the editable install of a fresh clone would."""
    own_bin = {venv().resolve() / "bin", (ROOT / ".venv" / "bin").resolve()}
    path = [p for p in os.environ.get("PATH", "/usr/bin:/bin").split(os.pathsep)
            if p and Path(p).resolve() not in own_bin]
    if venv_active:
        path.insert(0, str(copy / ".venv" / "bin"))
    env = {"PATH": os.pathsep.join(path), "PYTHONPATH": str(copy / "src"), "TMPDIR": str(tmp),
           "MPLBACKEND": "Agg", "PYTHONDONTWRITEBYTECODE": "1"}
    for key in ("HOME", "XDG_CACHE_HOME", "LANG", "MECANUM_FMU_REQUIRE_TOOLS", "LD_LIBRARY_PATH"):
        if key in os.environ:
            env[key] = os.environ[key]
    if venv_active:
        env["VIRTUAL_ENV"] = str(copy / ".venv")
    return env


@pytest.fixture(scope="session")
def fresh_copy(tmp_path_factory, fmu_dir):
    """A copy of the checkout as `make run` leaves it: the venv, fmus/*.fmu and
    fmus/fmi3/*.fmu (its `fmus` step builds both), results/circle/. One per test process
    (session scope): the heavy commands run first, apart from the module's other tests, and
    a module-scoped copy was made again (3 s) each time the module's tests resumed."""
    copy = tmp_path_factory.mktemp("fresh_clone")
    for name in checkout_files() + bytecode():
        (copy / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, copy / name)
    (copy / ".venv").symlink_to(venv(), target_is_directory=True)
    for folder in ("fmus", "fmus/fmi3"):
        (copy / folder).mkdir(exist_ok=True)
        for fmu in (fmu_dir / folder.removeprefix("fmus").lstrip("/")).glob("*.fmu"):
            shutil.copy2(fmu, copy / folder / fmu.name)
    step = ".venv/bin/python -m mecanum_fmu run scenarios/circle.yaml"       # make run's last line
    tmp = tmp_path_factory.mktemp("fresh_clone_tmp")
    proc = subprocess.run(["bash", "-c", step], cwd=copy, env=command_env(copy, tmp),
                          capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, f"`{step}` in the fresh copy: {tail(proc)}"
    RAN[(copy, step, False)] = proc      # README's `run scenarios/circle.yaml` is this command
    return copy


def tail(proc: subprocess.CompletedProcess, lines: int = 20) -> str:
    err = (proc.stderr or "").strip().splitlines()[-lines:]
    out = (proc.stdout or "").strip().splitlines()[-5:]
    return ("\n--- stderr, last lines:\n" + "\n".join(err) if err else "\n(no stderr)") + \
        ("\n--- stdout, last lines:\n" + "\n".join(out) if out else "")


def expected_code(comment: str) -> int:
    """0, or the exit code the trailing comment documents (`# exit 2`, `# exits 1`)."""
    match = re.search(r"\bexits? (?:code )?(\d+)\b", comment)
    return int(match.group(1)) if match else 0


def runnable(text: str) -> str:
    """A synopsis runs in its shortest form: its optional `[--option VALUE]` groups left out."""
    return re.sub(r"\s*\[--[^\]]*\]", "", text)


def skip_reason(text: str) -> str | None:
    return next((reason for pattern, reason in SKIPS if re.search(pattern, text)), None)


def bare_program(command: DocCommand) -> str | None:
    """Why the command would not run as written outside the venv, or None."""
    bare = VENV_ONLY.search(command.text)
    if bare and not command.venv_active:
        return (f"{command.where()}: `{command.text}`\n  a bare `{bare.group(1)}` is another "
                f"program (or none) outside the venv: write .venv/bin/{bare.group(1)}, or say "
                "\"with the venv active\" in the paragraph before it")
    return None


def test_long_commands_are_written_for_the_venv():
    """The commands too long to run here (SKIPS, each with its reason) are still written so
    that they run as written: no bare python, pip or pytest outside the venv."""
    long = [c for c in COMMANDS if skip_reason(c.text) is not None]
    assert long, "SKIPS matches no documented command: drop the rules that are dead"
    problems = [why for why in map(bare_program, long) if why]
    assert not problems, "\n".join(problems)


# (fresh copy, command as run, venv active) -> its finished process, in this test process
RAN: dict[tuple[Path, str, bool], subprocess.CompletedProcess] = {}


def run_in_copy(command: DocCommand, copy: Path, tmp: Path) -> subprocess.CompletedProcess:
    """The command's process in the copy. A command written in two places (README.md and a
    doc: `fmus`, `doctor`, a 10,000-step run) runs once per copy and both places are held to
    that one outcome (a TimeoutExpired is not kept: the next place runs it again). The
    commands above it in its block run first, in this copy, where they have not: the tests
    are split between pytest-xdist's workers, each with a copy of its own, and a block's
    later line may read what an earlier one wrote (docs/bags.md: the example bag, then its
    run)."""
    for earlier in command.before:
        if skip_reason(earlier.text) is None:
            run_in_copy(earlier, copy, tmp)
    key = (copy, runnable(command.text), command.venv_active)
    if key not in RAN:
        RAN[key] = subprocess.run(["bash", "-c", key[1]], cwd=copy,
                                  env=command_env(copy, tmp, command.venv_active),
                                  capture_output=True, text=True, timeout=TIMEOUT)
    return RAN[key]


@pytest.mark.parametrize("command", params())
def test_documented_command_runs(command, fresh_copy, tmp_path):
    where = f"{command.where()}: `{command.text}`"
    if (why := bare_program(command)):
        pytest.fail(why)
    expected = expected_code(command.comment)
    try:
        proc = run_in_copy(command, fresh_copy, tmp_path)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{where}\n  still running after {TIMEOUT} s: make it quicker, or add it to "
                    f"SKIPS with the reason")
    assert proc.returncode == expected, \
        f"{where}\n  exit code {proc.returncode}, documented {expected}{tail(proc)}"


SAMPLE = """\
Run `.venv/bin/python -m mecanum_fmu info Center2Wheel` first; `python -m mecanum_fmu` is
the program's name, `make bench` a target.

```sh
.venv/bin/python -m mecanum_fmu validate a.yaml   # exit 2
make fmus \\
    --quiet  # the comment ends "a.yaml"
```

```
.venv/bin/python -m mecanum_fmu run output.yaml
```

With the venv active:

```console
$ python -m mecanum_fmu doctor
python: <venv>/bin/python
```
"""


def test_extraction_reads_blocks_prompts_continuations_and_inline_commands(tmp_path):
    (tmp_path / "sample.md").write_text(SAMPLE)
    found = [(c.line, c.text, c.comment, c.venv_active) for c in extract(tmp_path / "sample.md",
                                                                          tmp_path)]
    assert found == [
        (1, ".venv/bin/python -m mecanum_fmu info Center2Wheel", "", False),
        (5, ".venv/bin/python -m mecanum_fmu validate a.yaml", "exit 2", False),
        (6, "make fmus --quiet", 'the comment ends "a.yaml"', False),
        (17, "python -m mecanum_fmu doctor", "", True)]


def test_the_rules_tell_bare_programs_templates_and_documented_codes():
    assert [m.group(1) for m in map(VENV_ONLY.search, [
        "python -m x", 'B=$(python -c "1")', "PYTHONPATH=src python3 a.py", "fmpy simulate a",
        ".venv/bin/python -m x", ".venv/bin/fmpy simulate a", "make run"]) if m] == \
        ["python", "python", "python3", "fmpy"]
    assert skip_reason("python -m mecanum_fmu run <scenario> --master <m>").startswith("a template")
    assert skip_reason("x sweep SWEEP.yaml") and not skip_reason("x run scenarios/circle.yaml")
    assert runnable("a run s.yaml [--out DIR] [--step-size H] -q") == "a run s.yaml -q"
    assert (expected_code("exit 2"), expected_code("exits 1, bad input"),
            expected_code("the exit: ok")) == (2, 1, 0)
