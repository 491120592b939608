"""The value checks shared by the scenario and sweep loaders (and the SSP reader): what a
number, a scalar value, a usable name and an allowed key are, and how a value is shown in a
message. One home, so that a scenario file, a sweep file and the Python API refuse the same
things with the same words."""
from __future__ import annotations

import math
import re
import reprlib
from typing import Any, Callable

from .errors import did_you_mean

MAX_NAME = 100          # characters of a scenario or sweep name (it names the results folder)
SCALAR_TYPES = (bool, int, float, str)

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother = 3, 60, 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6


def show(value: Any, limit: int = 80) -> str:
    """A short repr for messages: bounded even for huge or deeply shared (alias bomb) values."""
    text = _REPR.repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_finite(value: Any) -> bool:
    """A number that is a finite float (an int too large for a float is not)."""
    try:
        return is_number(value) and math.isfinite(value)
    except OverflowError:
        return False


def type_name(value: Any) -> str:
    names = {dict: "a mapping", list: "a list", str: "text", bool: "true/false",
             int: "a number", float: "a number", type(None): "nothing"}
    return names.get(type(value), type(value).__name__)


def unknown_keys(mapping: dict, allowed, place: str, bad: Callable[[str, str], None]) -> None:
    """bad(place, message) for each key of mapping that is not allowed, with a suggestion."""
    for key in mapping:
        if key not in allowed:
            bad(place, f"unknown key {show(key)}{did_you_mean(str(key), allowed)} "
                       f"(allowed: {', '.join(allowed)})")


def scalar_problem(value: Any) -> str | None:
    """Why value cannot be a parameter value (a number, true/false or text), or None."""
    if not isinstance(value, SCALAR_TYPES):
        return f"expected a number, true/false or text, got {type_name(value)}"
    if is_number(value) and not is_finite(value):
        return f"{show(value)} is not a finite number"
    return None


def usable_name(text: str) -> str | None:
    """text made safe to name a results folder (letters, digits, _ . -; runs of anything else
    become _; at most MAX_NAME characters), or None when nothing usable is left (empty, or
    only dots such as '..': results/<name> must stay inside results/)."""
    name = re.sub(r"[^\w.-]+", "_", text).strip("_")[:MAX_NAME]
    return name if name.strip(".") else None


def name_problem(name: Any) -> str | None:
    """Why name cannot name a results folder, or None."""
    if isinstance(name, str) and usable_name(name) == name:
        return None
    return (f"{show(name)} is not a usable name (letters, digits, _ . - only, not only dots, "
            f"at most {MAX_NAME} characters; it names the results folder)")
