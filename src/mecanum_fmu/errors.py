"""The project's exceptions. Only the CLI turns them into messages and exit codes."""
from __future__ import annotations

import difflib
import re
from typing import Any
from dataclasses import dataclass

# C0/C1 controls, line/paragraph separators and bidirectional overrides: printed raw they can
# rewrite the terminal or hide text; messages show them escaped (\x1b, \n, \u202e).
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def printable(text: str) -> str:
    """text with every control or direction-changing character escaped."""
    return _UNPRINTABLE.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)


_NUMBERED = re.compile(r"^(.*?)(\d+)$")


def did_you_mean(name: Any, choices) -> str:
    """'; did you mean X?' for the closest choice, or ''. A numbered name (w5) is matched to
    the nearest number of the same stem (w4) before anything else; case is ignored."""
    if not isinstance(name, str) or len(name) > 100:
        return ""
    choices = [c for c in choices if isinstance(c, str)]
    close = _same_stem(name, choices) or difflib.get_close_matches(name, choices, n=1,
                                                                   cutoff=0.6)
    if not close:
        folded = {c.lower(): c for c in choices}
        close = [folded[c] for c in difflib.get_close_matches(name.lower(), list(folded), n=1,
                                                              cutoff=0.6)]
    return f"; did you mean '{close[0]}'?" if close else ""


def _same_stem(name: str, choices: list[str]) -> list[str]:
    """The choice with name's stem and the nearest number (w5 -> w4), if there is one."""
    match = _NUMBERED.match(name)
    if match is None or not match.group(1):
        return []
    stem, number = match.group(1), int(match.group(2))
    numbered = [(abs(int(m.group(2)) - number), c) for c in choices
                if (m := _NUMBERED.match(c)) and m.group(1) == stem and c != name]
    return [min(numbered)[1]] if numbered else []


class MecanumError(Exception):
    """Base of every error this package raises on purpose.

    `files`: the result files written before the error (kept on disk, listed by the CLI)."""
    exit_code = 1

    def __init__(self, *args, files: list | None = None):
        super().__init__(*args)
        self.files: list = list(files or [])


@dataclass(frozen=True)
class Problem:
    """One thing wrong with the input, located as `file: place: message`."""
    file: str
    place: str
    message: str

    def __str__(self) -> str:
        text = f"{self.file}: {self.place}: {self.message}" if self.place else f"{self.file}: {self.message}"
        return printable(text)


class ScenarioError(MecanumError):
    """Bad input: every problem found, reported together (exit code 2)."""
    exit_code = 2

    def __init__(self, problems: list[Problem]):
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))

    @property
    def places(self) -> list[str]:
        return [p.place for p in self.problems]


class ArgumentError(ScenarioError, ValueError):
    """A Python API call got an argument it cannot use (exit code 2 like any bad input): each
    problem is placed as `function(): argument NAME: what is wrong and the fix`."""


class SimulationError(MecanumError):
    """A component failed during the run (exit code 1): which component, at what time, with
    what FMI status; `results` holds what was recorded up to the failure."""
    exit_code = 1

    def __init__(self, message: str, *, component: str | None = None, time: float | None = None,
                 status: str | None = None, results=None):
        self.component, self.time, self.status, self.results = component, time, status, results
        where = []
        if component is not None:
            where.append(f"component '{component}'")
        if time is not None:
            where.append(f"t = {time:.6g} s")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class Interrupted(MecanumError):
    """The user interrupted the run (Ctrl-C, exit code 130) or the process was asked to end
    (SIGTERM, `terminated`, exit code 143); `results` holds what was recorded."""
    exit_code = 130

    def __init__(self, time: float, results=None, terminated: bool = False):
        self.time, self.results, self.terminated = time, results, terminated
        if terminated:
            self.exit_code = 143
        super().__init__(f"{'terminated (SIGTERM)' if terminated else 'interrupted'} "
                         f"at t = {time:.6g} s")
