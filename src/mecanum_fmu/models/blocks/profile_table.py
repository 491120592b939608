"""Velocity profiles as tables: CSV text with the header ``time,vx,vy,w``, sampled in time.

The text comes from a scenario's table file (read by the scenario loader) or from the
VelocitySource's ``table`` String parameter, so it is untrusted: it is only split and turned
into floats. Standard library only: this source is inlined verbatim into the standalone FMU.

- The header names the columns; ``time``, ``vx``, ``vy`` and ``w`` are needed, in any order,
  other columns (a recorder's extras) are ignored. Blank lines and lines starting with ``#``
  are skipped.
- Time is strictly increasing; every needed cell is a finite number (SI units).
- ``linear`` interpolates between rows, ``hold`` keeps a row's values until the next row
  (the value at a row's own time is that row's). Before the first and after the last row
  the end values are held.
"""
import bisect
import math

TABLE_COLUMNS = ("time", "vx", "vy", "w")
INTERPOLATIONS = ("linear", "hold")
_TABLE_MAX_ROWS = 1_000_000


class TableError(ValueError):
    """A table is malformed; ``line`` is the 1-based line of the text (0: the whole text)."""

    def __init__(self, line, message):
        self.line = line
        super().__init__(f"line {line}: {message}" if line else message)


def _table_lines(text):
    """(line number, stripped text) of the lines that carry data, comments skipped."""
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield number, line


def _table_header(number, line):
    names = [cell.strip().lower() for cell in line.split(",")]
    missing = [c for c in TABLE_COLUMNS if c not in names]
    if missing:
        raise TableError(number, f"the header {line[:80]!r} lacks the column(s) "
                         f"{', '.join(missing)}; the first line must name the columns: "
                         f"{','.join(TABLE_COLUMNS)} (other columns are ignored)")
    return [names.index(c) for c in TABLE_COLUMNS]


def _table_row(number, line, where):
    cells = line.split(",")
    if len(cells) <= max(where):
        raise TableError(number, f"has {len(cells)} cells, the header needs at least "
                         f"{max(where) + 1}")
    row = []
    for name, index in zip(TABLE_COLUMNS, where):
        cell = cells[index].strip()
        try:
            value = float(cell)
        except ValueError:
            raise TableError(number, f"{name} = {cell[:40]!r} is not a number") from None
        if not math.isfinite(value):
            raise TableError(number, f"{name} = {cell[:40]!r} is not a finite number")
        row.append(value)
    return row


def parse_table(text):
    """CSV text -> (times, vx, vy, w) lists. Raises TableError naming the line."""
    if not isinstance(text, str):
        raise TableError(0, "a table is CSV text")
    lines = _table_lines(text)
    first = next(lines, None)
    if first is None:
        raise TableError(0, f"the table is empty; it needs the header {','.join(TABLE_COLUMNS)} "
                         "and at least one row")
    where = _table_header(*first)
    columns = ([], [], [], [])
    for number, line in lines:
        row = _table_row(number, line, where)
        if columns[0] and not row[0] > columns[0][-1]:
            raise TableError(number, f"time {row[0]!r} does not increase (the row before "
                             f"has {columns[0][-1]!r}); times must be strictly increasing")
        if len(columns[0]) >= _TABLE_MAX_ROWS:
            raise TableError(number, f"more than {_TABLE_MAX_ROWS} rows")
        for column, value in zip(columns, row):
            column.append(value)
    if not columns[0]:
        raise TableError(first[0], "the table has a header but no rows")
    return columns


def table_sampler(text, interpolation="linear"):
    """A function t -> (vx, vy, w) for the table text. Raises TableError on a bad table or
    an unknown interpolation."""
    if interpolation not in INTERPOLATIONS:
        raise TableError(0, f"interpolation {str(interpolation)[:40]!r} is unknown; use "
                         f"{' or '.join(INTERPOLATIONS)}")
    times, *values = parse_table(text)
    rows = list(zip(*values))
    last = len(times) - 1
    hold = interpolation == "hold"

    def sample(t):
        i = bisect.bisect_right(times, t) - 1     # the last row with time <= t
        if i < 0:
            return rows[0]
        if i >= last or hold:
            return rows[i]
        u = (t - times[i]) / (times[i + 1] - times[i])
        a, b = rows[i], rows[i + 1]
        return tuple(p + u * (q - p) for p, q in zip(a, b))
    return sample
