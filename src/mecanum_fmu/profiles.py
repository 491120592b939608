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

from .models.blocks.profile_table import INTERPOLATIONS, TABLE_COLUMNS, TableError, parse_table, \
    table_sampler
from .errors import Problem
from .values import is_finite

SEGMENT_KEYS = ("duration", "vx", "vy", "w")
MAX_TABLE_BYTES = 50_000_000


def table_text(value: str, scenario_dir: Path, label: str, place: str,
               report: Callable[[Problem], None]) -> str | None:
    """The CSV text behind a `table` parameter (a path or the text itself), checked; None
    (and a reported problem) when it cannot be used."""
    if "\n" in value:
        text, where = value, label
    else:
        path = scenario_dir / value
        where = str(path)
        try:
            if path.stat().st_size > MAX_TABLE_BYTES:
                report(Problem(label, place, f"{value}: larger than {MAX_TABLE_BYTES} bytes"))
                return None
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            report(Problem(label, place, f"table file {value!r} not found (looked for {path}; "
                                         "the path is relative to the scenario file)"))
            return None
        except (OSError, UnicodeDecodeError) as err:
            report(Problem(label, place, f"table file {value!r} cannot be read: "
                                         f"{getattr(err, 'strerror', None) or err}"))
            return None
    try:
        parse_table(text)
    except TableError as err:
        # file:line, as compilers write it
        report(Problem(f"{where}:{err.line}" if err.line else where, "",
                       str(err).removeprefix(f"line {err.line}: ")
                       + f" (the table of {label}: {place})"))
        return None
    return text


def segments_table(raw: Any, start_time: float, place: str,
                   report: Callable[[Problem], None], label: str) -> str | None:
    """The hold-table CSV text for a `segments:` list; None (and problems) when it is bad."""
    if not isinstance(raw, list) or not raw:
        report(Problem(label, place, "expected a list of segments like {duration: 2, vy: 0.3}"))
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


def resolve_profile(spec: dict, params: dict, scenario_dir: Path, start_time: float,
                    place: str, label: str, report: Callable[[Problem], None]) -> dict:
    """A VelocitySource's parameters with `table` (path or segments) replaced by CSV text."""
    params = dict(params)
    if "segments" in spec:
        if "table" in params:
            report(Problem(label, f"{place}.segments", "give either segments or a table "
                                                       "parameter, not both"))
            return params
        text = segments_table(spec["segments"], start_time, f"{place}.segments", report, label)
        if text is not None:
            params["table"] = text
            params["interpolation"] = "hold"
        return params
    if "interpolation" in params and params["interpolation"] not in INTERPOLATIONS:
        report(Problem(label, f"{place}.parameters.interpolation",
                       f"{str(params['interpolation'])[:40]!r} is unknown; use "
                       f"{' or '.join(INTERPOLATIONS)}"))
    table = params.get("table")
    if isinstance(table, str) and table:
        text = table_text(table, scenario_dir, label, f"{place}.parameters.table", report)
        if text is not None:
            params["table"] = text
    return params


def table_twist(text: str, interpolation: str = "linear"):
    """(twist function of t for arrays or scalars, breakpoints) of a table, with NumPy: an
    implementation independent of the FMU's (blocks/profile_table.py samples row by row)."""
    times, *cols = (np.asarray(c, dtype=float) for c in parse_table(text))
    if interpolation not in INTERPOLATIONS:
        table_sampler(text, interpolation)      # raises the message
    hold = interpolation == "hold"

    def twist(t):
        if hold:
            i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
            return tuple(c[i] for c in cols)
        return tuple(np.interp(t, times, c) for c in cols)
    return twist, times


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
    for a, b in zip(edges[:-1], edges[1:]):
        inside = (times > a) & (times <= b)
        wanted = np.union1d(times[inside], [b])
        sol = solve_ivp(rhs, (a, b), state, t_eval=wanted, rtol=rtol, atol=atol,
                        method="DOP853", max_step=(b - a) / 8)
        out[:, inside] = sol.y[:, np.searchsorted(wanted, times[inside])]
        state = sol.y[:, -1]
    return out
