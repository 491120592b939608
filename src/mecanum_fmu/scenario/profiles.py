"""Velocity profiles in a scenario: a VelocitySource's `table` file and its `segments`.

The loader turns both into the FMU's `table` String parameter holding the CSV TEXT, not a
path, so the table travels with the component's parameters: an exported SSP runs the same in
another host with no file lookup at run time.

    source: {fmu: VelocitySource, parameters: {table: profiles/joystick.csv, interpolation: linear}}
    source: {fmu: VelocitySource, segments: [{duration: 1}, {duration: 2, vy: 0.3}]}

- `table`: a CSV file relative to the scenario file (blocks/profile_table.py says what it may
  hold). A value with a line break is taken as the CSV text itself (what an SSP carries).
- `segments`: piecewise-constant twist, one mapping per segment: `duration` [s] > 0 and any of
  `vx`, `vy` [m/s], `w` [rad/s] (left out: 0). They start at the scenario's start_time and
  become a hold table with one row per segment start and a last row of zeros at the end of
  the last segment: the car stops when the segments are over.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..models.blocks.profile_table import INTERPOLATIONS, TABLE_COLUMNS, TableError
from ..models.blocks.profile_table import _TABLE_MAX_ROWS as MAX_TABLE_ROWS  # the FMU's limit
from ..errors import Problem
from ..values import is_finite
from .bags import is_bag, read_bag_table
from .recorded import TableSource, check_options, mapped_table, read_table_file, \
    report_table_error
from .tables import COLUMNS, Table, read_table

SEGMENT_KEYS = ("duration", "vx", "vy", "w")
WAYPOINT_KEYS = ("points", "speed")
# the component keys that make a table, per model (besides its `table` parameter)
PROFILE_KEYS = {"VelocitySource": ("segments", "table"), "PathFollower": ("table", "waypoints")}
Report = Callable[[Problem], None]


def table_text(value: str, scenario_dir: Path, label: str, place: str, report: Report,
               model: str = "VelocitySource") -> Table | None:
    """The table behind a `table` parameter (a path or the CSV text itself), read and checked
    once; None (and reported problems) when it cannot be used."""
    if "\n" in value:
        source = TableSource(value, label, True)
    else:
        source = read_table_file(value, scenario_dir, label, place, report)
        if source is None:
            return None
    try:
        return read_table(source.text, model, source.quote)
    except TableError as err:
        report_table_error(err, source, label, place, report)
        return None


def _mapped(raw: Any, model: str, scenario_dir: Path, start_time: float, place: str,
            label: str, report: Report) -> Table | None:
    """The table of a `table: {file: ..., columns: ..., units: ...}` mapping (recorded.py),
    read once more in our columns: its times must still increase after units and offset."""
    columns, optional = COLUMNS[model]
    if not isinstance(raw, dict):
        report(Problem(label, place, f"expected a mapping like {{file: log.csv, columns: "
                                     f"{{{columns[1]}: ...}}}}"))
        return None
    if not check_options(raw, columns, place, label, report):
        return None
    if is_bag(raw, scenario_dir):
        found = read_bag_table(raw, columns, scenario_dir, start_time, label, place, report)
        if found is None:
            return None
        source, raw = found
    elif raw.get("start") == "bag_start" or "stamps" in raw:
        key = "stamps" if "stamps" in raw else "start"
        report(Problem(label, f"{place}.{key}", f"{raw[key]} is for a bag (give its topic); "
                                                "a CSV file names its time column"))
        return None
    else:
        source = read_table_file(raw["file"], scenario_dir, label, f"{place}.file", report)
        if source is None:
            return None
    try:
        return read_table(mapped_table(source, raw, columns, optional, start_time), model,
                          False)
    except TableError as err:
        report_table_error(err, source, label, place, report)
        return None


def segments_table(raw: Any, start_time: float, place: str,
                   report: Report, label: str) -> str | None:
    """The hold-table CSV text for a `segments:` list; None (and problems) when it is bad."""
    if not isinstance(raw, list) or not raw:
        report(Problem(label, place, "expected a list of segments like {duration: 2, vy: 0.3}"))
        return None
    if too_many_rows(len(raw) + 1, place, f"{len(raw)} segments and the final stop", report,
                     label):
        return None
    rows, t, ok = [], float(start_time), True
    for i, seg in enumerate(raw):
        where = f"{place}[{i}]"
        if not isinstance(seg, dict):
            report(Problem(label, where, "expected a mapping like {duration: 2, vy: 0.3}"))
            ok = False
            continue
        for key in seg:
            if key not in SEGMENT_KEYS:
                report(Problem(label, where, f"unknown key {str(key)[:40]!r} (allowed: "
                                             f"{', '.join(SEGMENT_KEYS)})"))
                ok = False
        values = [seg.get(k, 0.0) for k in SEGMENT_KEYS]
        for key, value in zip(SEGMENT_KEYS, values):
            if not is_finite(value):
                report(Problem(label, f"{where}.{key}", f"expected a finite number, got "
                                                        f"{str(value)[:40]!r}"))
                ok = False
        if "duration" not in seg or (is_finite(values[0]) and not values[0] > 0):
            report(Problem(label, f"{where}.duration", "needs a duration > 0 [s]"))
            ok = False
        if ok:
            rows.append((t, *values[1:]))
            t, ok = _segment_end(t, float(values[0]), f"{where}.duration", report, label)
    if not ok:
        return None
    rows.append((t, 0.0, 0.0, 0.0))
    return ",".join(TABLE_COLUMNS) + "\n" + "".join(
        ",".join(repr(float(v)) for v in row) + "\n" for row in rows)


def _segment_end(t: float, duration: float, place: str, report: Callable[[Problem], None],
                 label: str) -> tuple[float, bool]:
    """The end time of a segment starting at t, and whether it is usable: the sum of the
    durations must stay finite, and each segment must move time on (a duration far below
    t's precision adds nothing: t + duration == t)."""
    end = t + duration
    if not math.isfinite(end):
        report(Problem(label, place, f"the segments up to here end at {end} s: the sum of the "
                                     "durations must be a finite number of seconds"))
        return t, False
    if not end > t:
        report(Problem(label, place, f"duration {duration!r} s does not advance time from "
                                     f"t = {t!r} s (it is below that time's precision); give "
                                     "a longer duration or drop the segment"))
        return t, False
    return end, True


def waypoints_table(raw: Any, start_time: float, place: str, report: Report,
                    label: str) -> str | None:
    """The path table (time,x,y[,theta]) of `waypoints: {points: [[x, y], ...], speed: v}`:
    straight lines between the points at the speed v [m/s], from the start_time on."""
    if not isinstance(raw, dict) or not isinstance(raw.get("points"), list) \
            or len(raw["points"]) < 2:
        report(Problem(label, place, "expected {points: [[x, y], [x, y], ...], speed: v} "
                                     "with at least two points [m] (or [x, y, theta])"))
        return None
    ok = all(key in WAYPOINT_KEYS or _unknown(label, f"{place}.{str(key)[:40]}", report)
             for key in list(raw))
    speed = raw.get("speed")
    if not (is_finite(speed) and speed > 0):
        report(Problem(label, f"{place}.speed", "needs the speed along the path [m/s] > 0"))
        ok = False
    points = raw["points"]
    width = len(points[0]) if isinstance(points[0], list) else 0
    for i, point in enumerate(points):
        if not (isinstance(point, list) and len(point) == width and width in (2, 3)
                and all(is_finite(v) for v in point)):
            report(Problem(label, f"{place}.points[{i}]", "expected [x, y] or [x, y, theta] "
                                                          "of finite numbers, as the first"))
            return None
    if not ok:
        return None
    if too_many_rows(len(points), f"{place}.points", f"{len(points)} points", report, label):
        return None
    t, rows = float(start_time), []
    for i, point in enumerate(points):
        if i:
            t = _waypoint_time(t, points[i - 1], point, float(speed), f"{place}.points[{i}]",
                               report, label)
            if t is None:
                return None
        rows.append((t, *point))
    header = "time,x,y" + (",theta" if width == 3 else "")
    return header + "\n" + "".join(",".join(repr(float(v)) for v in row) + "\n"
                                   for row in rows)


def _waypoint_time(t: float, before: list, point: list, speed: float, place: str,
                   report: Report, label: str) -> float | None:
    """When the path reaches point, coming from before at t: a finite time after t, else
    None and a problem (the table's times must be finite and increase)."""
    step = math.hypot(point[0] - before[0], point[1] - before[1])
    if not step > 0:
        report(Problem(label, place, "repeats the point before; leave it out"))
        return None
    end = t + step / speed
    if math.isfinite(end) and end > t:
        return end
    why = ("is not a finite number of seconds" if not math.isfinite(end) else
           f"does not advance time from t = {t!r} s (below that time's precision)")
    report(Problem(label, place, f"reached at {end!r} s ({step!r} m from the point before at "
                                 f"{speed!r} m/s), which {why}; use a speed and coordinates "
                                 "that give each leg a finite, resolvable time"))
    return None


def too_many_rows(count: int, place: str, what: str, report: Report, label: str) -> bool:
    """A table of `count` rows (made of `what`) is longer than an FMU takes (profile_table's
    limit): report it (True)."""
    if count <= MAX_TABLE_ROWS:
        return False
    report(Problem(label, place, f"{what} make a table of {count} rows; an FMU takes at most "
                                 f"{MAX_TABLE_ROWS}: use fewer"))
    return True


def _unknown(label: str, place: str, report: Report) -> bool:
    report(Problem(label, place, f"unknown key (allowed: {', '.join(WAYPOINT_KEYS)})"))
    return False


def resolve_profile(model: str, spec: dict, params: dict, scenario_dir: Path,
                    start_time: float, place: str, label: str, report: Report
                    ) -> tuple[dict, Table | None]:
    """A VelocitySource's or PathFollower's parameters with its table (a path, segments,
    waypoints or a `table:` mapping) replaced by the CSV text, and the Table read from it
    (None when it has none or it is bad: then reported)."""
    params = dict(params)
    given = [k for k in PROFILE_KEYS[model] if k in spec]
    if len(given) + ("table" in params) > 1:
        report(Problem(label, f"{place}.{given[0]}", "give one of "
                       + ", ".join(PROFILE_KEYS[model])
                       + " or a table parameter, not several"))
        return params, None
    if "interpolation" in params and params["interpolation"] not in INTERPOLATIONS:
        report(Problem(label, f"{place}.parameters.interpolation",
                       f"{str(params['interpolation'])[:40]!r} is unknown; use "
                       f"{' or '.join(INTERPOLATIONS)}"))
    text, table = None, None
    if given == ["segments"]:
        text = segments_table(spec["segments"], start_time, f"{place}.segments", report, label)
        if text is not None:
            params["interpolation"] = "hold"
    elif given == ["waypoints"]:
        text = waypoints_table(spec["waypoints"], start_time, f"{place}.waypoints", report,
                               label)
    elif given == ["table"]:
        table = _mapped(spec["table"], model, scenario_dir, start_time, f"{place}.table",
                        label, report)
    elif isinstance(params.get("table"), str) and params["table"]:
        table = table_text(params["table"], scenario_dir, label, f"{place}.parameters.table",
                           report, model)
    if table is None and text is not None:
        table = read_table(text, model)     # made here from checked values: it reads
    if table is not None:
        params["table"] = table.text
    return params, table


def recorded_paths(raw: Any, poses: list[str], scenario_dir: Path, start_time: float,
                   label: str, report: Report) -> dict[str, str]:
    """The scenario's `recorded:` mapping, pose instance -> a path table (read as a
    PathFollower's: a bag's Odometry or PoseStamped topic, or a CSV of time,x,y[,theta])."""
    if not isinstance(raw, dict):
        report(Problem(label, "recorded", "expected a mapping like {pose: {file: day1, "
                                          "topic: /odom}}"))
        return {}
    out = {}
    for name, spec in raw.items():
        if name not in poses:
            report(Problem(label, f"recorded.{str(name)[:40]}", "names no PoseIntegrator "
                           f"(the scenario's: {', '.join(poses) or 'none'})"))
            continue
        table = _mapped(spec, "PathFollower", scenario_dir, start_time, f"recorded.{name}",
                        label, report)
        if table is not None:
            out[name] = table.text
    return out


MIN_MAX_STEP = 0.05    # [s] a row interval shorter than 8 of these is one solver step or a few


def integrate_piecewise(rhs, start, times: np.ndarray, breaks: np.ndarray, rtol: float,
                        atol: float) -> np.ndarray:
    """The pose at `times` (3 x n), solved interval by interval between the table's rows so
    that no solver step straddles a jump (hold) or a kink (linear)."""
    from scipy.integrate import solve_ivp
    t0, t1 = float(times[0]), float(times[-1])
    edges = np.unique(np.concatenate(([t0], breaks[(breaks > t0) & (breaks < t1)], [t1])))
    out = np.empty((3, len(times)))
    out[:, times <= t0] = np.asarray(start, dtype=float)[:, None]
    state = np.asarray(start, dtype=float)
    for a, b in zip(edges[:-1], edges[1:]):          # times are sorted: (a, b] is a slice
        inside = slice(*np.searchsorted(times, (a, b), side="right"))
        wanted = np.union1d(times[inside], [b])
        sol = solve_ivp(rhs, (a, b), state, t_eval=wanted, rtol=rtol, atol=atol,
                        method="DOP853", max_step=max((b - a) / 8, MIN_MAX_STEP))
        out[:, inside] = sol.y[:, np.searchsorted(wanted, times[inside])]
        state = sol.y[:, -1]
    return out
