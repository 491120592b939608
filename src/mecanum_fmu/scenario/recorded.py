"""Recorded tables as they come: the file read under the input-file rules, the columns mapped,
units converted and the time shifted, into the CSV text an FMU's `table` parameter holds.

    table: {file: cmd_vel.csv, columns: {time: "%time", vx: -field.linear.y, vy: field.linear.x,
            w: field.angular.z}, units: {time: ns}, start: first_row}

- `file`: relative to the scenario file. Only a regular file of at most MAX_TABLE_BYTES is
  read (a FIFO or /dev/zero is refused before anything is read), decoded as UTF-8 with an
  optional byte order mark. A file from outside the scenario's folder is read too (logs live
  elsewhere), but no message quotes its content.
- `columns`: our column -> the file's column name; a leading `-` negates (ROS's y points left,
  our x right; not the time). Left out: the column of the same name (an optional one, such
  as a path's theta, may then be missing from the file; a mapped one must be there).
- `units`: time s, ms, us, ns; velocities m/s, cm/s, mm/s; yaw rate rad/s, deg/s; positions
  m, cm, mm; heading rad, deg (a velocity's `mm` means mm/s, `deg` deg/s).
- `start: first_row` puts the first row at the scenario's start_time; `offset` [s] is then
  added to every time (either or both).
- `topic` (and `stamps`, `start: bag_start`): `file` is a ROS bag; bags.py reads the topic
  into the same text.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

from ..errors import Problem
from ..models.blocks.profile_table import TableError, parse_table
from ..storage import NotARegularFile, read_regular
from ..values import is_finite

MAX_TABLE_BYTES = 50_000_000
# `topic` and `stamps` name a bag's topic and its time (bags.py)
TABLE_KEYS = ("file", "columns", "units", "start", "offset", "topic", "stamps")
_TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_SPEED = {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3, "cm": 1e-2, "mm": 1e-3, "m": 1.0}
_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
_TURN = {"rad/s": 1.0, "deg/s": math.pi / 180, "rad": 1.0, "deg": math.pi / 180}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180}
UNITS = {"time": _TIME, "vx": _SPEED, "vy": _SPEED, "w": _TURN, "x": _LENGTH, "y": _LENGTH,
         "theta": _ANGLE}

Report = Callable[[Problem], None]


class TableSource:
    """Where a table's text came from, for messages: `where` names it, `quote` says whether
    its content may be quoted (not for a file outside the scenario's folder)."""

    def __init__(self, text: str, where: str, quote: bool):
        self.text, self.where, self.quote = text, where, quote


def read_table_file(value: str, scenario_dir: Path, label: str, place: str,
                    report: Report) -> TableSource | None:
    """The text of the table file `value` (relative to the scenario's folder); None and a
    reported problem when it cannot be read."""
    path = scenario_dir / value
    try:
        data = read_regular(path, MAX_TABLE_BYTES, "a table (CSV text)")
        text = data.decode("utf-8-sig")
    except FileNotFoundError:
        report(Problem(label, place, f"table file {value[:200]!r} not found (looked for "
                                     f"{str(path)[:300]}; the path is relative to the "
                                     "scenario file)"))
        return None
    except NotARegularFile as err:
        report(Problem(label, place, f"table file {value[:200]!r} {err}"))
        return None
    except UnicodeDecodeError as err:
        report(Problem(label, place, f"table file {value[:200]!r} is not UTF-8 text (byte "
                                     f"{err.start}); save it as UTF-8 CSV"))
        return None
    except OSError as err:
        report(Problem(label, place, f"table file {value[:200]!r} cannot be read: "
                                     f"{err.strerror or err}"))
        return None
    return TableSource(text, str(path), _inside(path, scenario_dir))


def _inside(path: Path, folder: Path) -> bool:
    try:
        return path.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError):       # a symlink loop
        return False


def report_table_error(err: TableError, source: TableSource, label: str, place: str,
                       report: Report) -> None:
    """Each listed bad row as a problem at file:line, and how many more there are."""
    for line, message in err.problems:
        # file:line, as compilers write it
        report(Problem(f"{source.where}:{line}" if line else source.where, "",
                       f"{message} (the table of {label}: {place})"))
    if err.count > len(err.problems):
        report(Problem(source.where, "", f"{err.count - len(err.problems)} more bad row(s) "
                                         f"not listed (the first {len(err.problems)} are "
                                         f"above; the table of {label}: {place})"))


def check_options(raw: dict, columns: tuple[str, ...], place: str, label: str,
                  report: Report) -> bool:
    """True when the `table:` mapping's keys and values are usable (problems reported)."""
    ok = True

    def bad(where: str, message: str) -> None:
        nonlocal ok
        ok = False
        report(Problem(label, f"{place}.{where}", message))

    for key in raw:
        if key not in TABLE_KEYS:
            bad(str(key)[:40], f"unknown key (allowed: {', '.join(TABLE_KEYS)})")
    if not isinstance(raw.get("file"), str) or not raw.get("file"):
        bad("file", "needs the table file, relative to the scenario file")
    for key, kind in (("columns", str), ("units", str)):
        value = raw.get(key, {})
        if not isinstance(value, dict):
            bad(key, f"expected a mapping like {{{columns[1]}: ...}}")
            continue
        for name, item in value.items():
            if name not in columns:
                bad(f"{key}.{str(name)[:40]}", f"unknown column (ours: {', '.join(columns)})")
            elif not isinstance(item, kind) or not item.strip("- "):
                bad(f"{key}.{name}", "expected a name" if key == "columns" else "expected a unit")
            elif key == "units" and item not in UNITS[name]:
                bad(f"{key}.{name}", f"{item[:20]!r} is not a unit of {name}; use "
                                     f"{', '.join(UNITS[name])}")
            elif key == "columns" and name == columns[0] and item.strip().startswith("-"):
                bad(f"{key}.{name}", f"{item[:40]!r}: the time column cannot be negated "
                                     "(times must increase); drop the '-'")
    if "start" in raw and raw["start"] not in ("first_row", "bag_start"):
        bad("start", "the only choice is first_row (the first row at the start_time; a bag "
                     "also takes bag_start: its first message of any topic there)")
    offset = raw.get("offset", 0.0)
    if not is_finite(offset):
        bad("offset", "expected a finite number of seconds added to the table's times")
    return ok


def mapped_table(source: TableSource, raw: dict, columns: tuple[str, ...],
                 optional: tuple[str, ...], start_time: float) -> str:
    """The table text with our header `columns`, in SI units and shifted in time (whose
    times the caller checks again: tables.read_table). Raises TableError (about the file's
    own columns and lines)."""
    mapping = raw.get("columns", {})
    names = [str(mapping.get(c, c)).strip() for c in columns]
    signs = [-1.0 if n.startswith("-") else 1.0 for n in names]
    names = [n.lstrip("-").strip().lower() for n in names]
    # an optional column may be missing from the file, unless `columns:` maps it
    wanted = tuple(name for name, c in zip(names, columns) if c in optional and c not in mapping)
    data = parse_table(source.text, tuple(names), wanted, source.quote)
    units = raw.get("units", {})
    scales = [UNITS[c][units.get(c, next(iter(UNITS[c])))] for c in columns]
    times = data[0]
    zero = times[0] if raw.get("start") == "first_row" else 0.0
    shift = (start_time if raw.get("start") == "first_row" else 0.0) + float(raw.get("offset", 0))
    data[0] = [(t - zero) * scales[0] + shift for t in times]
    present = [i for i, column in enumerate(data) if column is not None]
    for i in present[1:]:
        data[i] = [signs[i] * scales[i] * v for v in data[i]]
    header = ",".join(columns[i] for i in present)
    rows = zip(*(data[i] for i in present))
    return header + "\n" + "".join(",".join(map(repr, row)) + "\n" for row in rows)
