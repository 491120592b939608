"""Tables sampled in time: velocity profiles (``time,vx,vy,w``) and reference paths
(``time,x,y,theta``, theta optional), CSV text.

The text comes from a scenario's table file (read by the scenario loader) or from an FMU's
``table`` String parameter, so it is untrusted: it is only split and turned into floats.
Standard library only: this source is inlined verbatim into the standalone FMUs.

- The header names the columns; the needed ones in any order, other columns (a recorder's
  extras) are ignored. A UTF-8 byte order mark before the header is skipped. Blank lines and
  lines starting with ``#`` are skipped. A line is at most MAX_LINE characters.
- Time is strictly increasing; every needed cell is a finite number (SI units). Every bad row
  is found; the error lists the first MAX_REPORTED of them and counts the rest.
- ``linear`` interpolates between rows, ``hold`` keeps a row's values until the next row
  (the value at a row's own time is that row's). Before the first and after the last row
  the end values are held. A lookup is a bisection: O(log n) per sample.
- A path without ``theta`` faces along the path: the body's +Y (forward) axis points along
  the direction from the row before to the row after (at the ends: the end segment).
"""
import bisect
import math

TABLE_COLUMNS = ("time", "vx", "vy", "w")
PATH_COLUMNS = ("time", "x", "y", "theta")
INTERPOLATIONS = ("linear", "hold")
MAX_LINE = 4096            # characters per line: a row is a few numbers
MAX_REPORTED = 10          # bad rows listed in one error (the rest are counted)
_TABLE_MAX_ROWS = 1_000_000


class TableError(ValueError):
    """A table is malformed; ``line`` is the 1-based line of the text (0: the whole text).
    ``problems``: (line, message) of each listed bad row; ``count``: all bad rows."""

    def __init__(self, line, message, problems=None, count=1):
        self.line = line
        self.problems = problems if problems is not None else [(line, message)]
        self.count = count
        super().__init__(f"line {line}: {message}" if line else message)


def _table_lines(text):
    """(line number, stripped text) of the lines that carry data, comments skipped; a line
    longer than MAX_LINE is refused."""
    for number, raw in enumerate(text.split("\n"), start=1):
        if len(raw) > MAX_LINE:
            raise TableError(number, f"is longer than {MAX_LINE} characters; a table row is "
                             "a few numbers separated by commas (is this the right file?)")
        line = raw.strip()
        if line and not line.startswith("#"):
            yield number, line


def _said(text, quote):
    """' = <the text>' for a message, shortened; '' when the content must not be quoted."""
    return f" = {text[:40]!r}" if quote else ""


def _table_header(number, line, columns, optional, quote):
    names = [cell.strip().lower() for cell in line.split(",")]
    missing = [c for c in columns if c not in names and c not in optional]
    if missing:
        shown = f"the header {line[:80]!r}" if quote else f"the header (line {number})"
        extra = f" ({', '.join(optional)} may be left out)" if optional else ""
        raise TableError(number, f"{shown} lacks the column(s) {', '.join(missing)}; the "
                         f"first line must name the columns: {','.join(columns)}{extra} "
                         "(other columns are ignored)")
    return [names.index(c) if c in names else None for c in columns]


def _table_row(number, line, index, names, quote):
    cells = line.split(",")
    if len(cells) <= max(index):
        raise TableError(number, f"has {len(cells)} cells, the header needs at least "
                         f"{max(index) + 1}")
    row = []
    for name, i in zip(names, index):
        cell = cells[i].strip()
        try:
            value = float(cell)
        except ValueError:
            raise TableError(number, f"{name}{_said(cell, quote)} is not a number") from None
        if not math.isfinite(value):
            raise TableError(number, f"{name}{_said(cell, quote)} is not a finite number")
        row.append(value)
    return row


def _fast_row(line, index):
    """The values of the cells at `index` when each is a finite number, else None."""
    cells = line.split(",")
    try:
        row = [float(cells[i]) for i in index]
    except (ValueError, IndexError):
        return None
    return row if all(map(math.isfinite, row)) else None


def _bad_rows(problems, count):
    line, message = problems[0]
    more = f" (and {count - 1} more bad row(s))" if count > 1 else ""
    return TableError(line, message + more, problems, count)


def _rows(lines, where, columns, quote):
    """The good rows (values of the present columns) and the bad ones' (line, message)."""
    index = [i for i in where if i is not None]
    present = [c for c, i in zip(columns, where) if i is not None]
    rows, problems, count, last = [], [], 0, -math.inf
    for number, line in lines:
        if len(rows) + count >= _TABLE_MAX_ROWS:
            raise TableError(number, f"more than {_TABLE_MAX_ROWS} rows")
        row = _fast_row(line, index)
        try:
            if row is None:                   # the careful path names what is wrong
                row = _table_row(number, line, index, present, quote)
            if not row[0] > last:
                raise TableError(number, f"time {row[0]!r} does not increase (the row before "
                                 f"has {last!r}); times must be strictly increasing")
        except TableError as err:
            count += 1
            if len(problems) < MAX_REPORTED:
                problems.append((number, str(err).removeprefix(f"line {number}: ")))
            continue
        rows.append(row)
        last = row[0]
    if problems:
        raise _bad_rows(problems, count)
    return rows


def parse_table(text, columns=TABLE_COLUMNS, optional=(), quote=True):
    """CSV text -> one list per column (None for an optional column the header lacks).
    Raises TableError naming the line(s). quote=False keeps the file's content out of the
    messages (a file from outside the scenario's folder)."""
    if not isinstance(text, str):
        raise TableError(0, "a table is CSV text")
    text = text[1:] if text.startswith("\ufeff") else text
    if "\n" not in text:                      # old Mac line ends
        text = text.replace("\r", "\n")
    lines = _table_lines(text)
    first = next(lines, None)
    if first is None:
        raise TableError(0, f"the table is empty; it needs the header {','.join(columns)} "
                         "and at least one row")
    where = _table_header(*first, columns, optional, quote)
    rows = _rows(lines, where, columns, quote)
    if not rows:
        raise TableError(first[0], "the table has a header but no rows")
    present = iter(list(column) for column in zip(*rows))
    return [next(present) if i is not None else None for i in where]


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


def path_heading(times, xs, ys):
    """The heading along a path at each row: body +Y (forward) along the direction from the
    row before to the row after, unwrapped (no jumps of 2 pi)."""
    n = len(times)
    if n < 2:
        return [0.0] * n
    out, previous = [], None
    for i in range(n):
        a, b = max(i - 1, 0), min(i + 1, n - 1)
        dx, dy = xs[b] - xs[a], ys[b] - ys[a]
        heading = math.atan2(dy, dx) - math.pi / 2 if (dx or dy) else previous or 0.0
        if previous is not None:      # the nearest turn to the heading before
            heading = previous + math.atan2(math.sin(heading - previous),
                                            math.cos(heading - previous))
        out.append(heading)
        previous = heading
    return out


def path_table(text, quote=True):
    """(times, xs, ys, thetas) of a reference path table, theta along the path when absent."""
    times, xs, ys, thetas = parse_table(text, PATH_COLUMNS, ("theta",), quote)
    return times, xs, ys, thetas if thetas is not None else path_heading(times, xs, ys)


def path_sampler(text):
    """A function t -> ((x, y, theta), (x', y', theta')) of a reference path table: linear
    between rows; the rates are the slopes of the row interval t lies in (a row's own time
    belongs to the interval after it), zero before the first row and from the last row on."""
    times, *columns = path_table(text)
    rows = list(zip(*columns))
    last = len(times) - 1
    rest = (0.0, 0.0, 0.0)

    def sample(t):
        i = bisect.bisect_right(times, t) - 1
        if i < 0:
            return rows[0], rest
        if i >= last:
            return rows[last], rest
        span = times[i + 1] - times[i]
        u = (t - times[i]) / span
        a, b = rows[i], rows[i + 1]
        return (tuple(p + u * (q - p) for p, q in zip(a, b)),
                tuple((q - p) / span for p, q in zip(a, b)))
    return sample
