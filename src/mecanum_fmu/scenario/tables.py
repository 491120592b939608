"""A scenario's tables, read once, and the breakpoints of a graph's sources.

A `Table` is a VelocitySource's twist table (time, vx, vy, w) or a PathFollower's path (time,
x, y[, theta]) as the scenario loader read it (profiles.py: a file, a `table:` mapping,
segments, waypoints): its CSV text, which the FMU receives as its `table` parameter, and its
times and columns as arrays. The graph carries it (graph.Instance.table); the ground truth
(report/), the breakpoints (master/breakpoints.py) and the plausibility checks read it there,
and nothing parses the text again outside the FMU (blocks/profile_table.py, inside the slave).

`Breaks` are the times where a graph's sources jump or kink, under each table's interpolation
and from the numbers the expressions compare t with; the graph carries them too (Graph.breaks).
`Known` is a twist table as the source's outputs over time (Graph.known): the embedded pair
reads the input between the run's values there where they do not tell it (master/pair_known.py).
"""
from __future__ import annotations

import ast
from dataclasses import dataclass

import numpy as np

from ..models.blocks.profile_table import PATH_COLUMNS, TABLE_COLUMNS, TableError, \
    parse_table, path_heading

# the columns of a table, per model that takes one: (required, optional)
COLUMNS = {"VelocitySource": (TABLE_COLUMNS, ()), "PathFollower": (PATH_COLUMNS, ("theta",))}


@dataclass(frozen=True, eq=False)
class Table:
    text: str                       # the CSV text, as the FMU receives it
    times: np.ndarray               # [s], increasing
    columns: dict[str, np.ndarray]  # by name (vx, vy, w or x, y[, theta]), one value per time

    @property
    def is_twist(self) -> bool:
        return "vx" in self.columns

    @property
    def span(self) -> tuple[float, float]:
        """(first, last) time."""
        return float(self.times[0]), float(self.times[-1])

    def values(self, names: tuple[str, ...]) -> np.ndarray:
        """The columns `names` side by side: rows x len(names)."""
        return np.stack([self.columns[n] for n in names], axis=1)

    def breaks(self, interpolation: str) -> tuple[np.ndarray, np.ndarray]:
        """(kinks, jumps) of a twist table: under `hold`, the rows where a value changes
        (jumps); else the rows between two rows where a slope changes (kinks)."""
        times, values = self.times, self.values(TABLE_COLUMNS[1:])
        if interpolation == "hold":
            return np.array([]), times[1:][np.any(values[1:] != values[:-1], axis=1)]
        slopes = np.diff(values, axis=0) / np.diff(times)[:, None]
        return times[1:-1][np.any(slopes[1:] != slopes[:-1], axis=1)], np.array([])

    def path(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(times, x, y, theta) of a path, theta along the path when the table has none."""
        x, y = self.columns["x"], self.columns["y"]
        theta = self.columns.get("theta")
        if theta is None:
            theta = np.asarray(path_heading(self.times.tolist(), x.tolist(), y.tolist()))
        return self.times, x, y, theta


def read_table(text: str, model: str = "VelocitySource", quote: bool = True) -> Table:
    """The Table of a CSV text for `model` (COLUMNS). Raises TableError naming the line(s);
    quote=False keeps the file's content out of the messages."""
    required, optional = COLUMNS[model]
    parsed = parse_table(text, required, optional, quote)
    names = required + optional
    columns = {n: np.asarray(c, dtype=float) for n, c in zip(names, parsed) if c is not None}
    return Table(text, columns.pop("time"), columns)


def table_or_none(text, model: str) -> Table | None:
    """The Table of a start value that the loader did not read (an SSP's): None when there is
    none or it is not one (the FMU then reports it at initialisation)."""
    if not isinstance(text, str) or not text.strip() or model not in COLUMNS:
        return None
    try:
        return read_table(text, model)
    except TableError:
        return None


def distinct(times) -> np.ndarray:
    """The times sorted, each once: np.unique's result for a 1-D float array, without its
    first call's cost (numpy imports numpy.ma then: 15-30 ms once per process, which landed
    in the first run's error estimate)."""
    times = np.sort(np.asarray(times, dtype=float).ravel())
    return times[np.concatenate(([True], times[1:] != times[:-1]))] if times.size else times


@dataclass(frozen=True)
class Breaks:
    kinks: np.ndarray    # a twist table's value turns: the corners of a linear table
    jumps: np.ndarray    # a twist table's value jumps: a hold table's changes (segments)
    others: np.ndarray   # either, or neither: the numbers an expression compares t with
    # (`where(t < 8, ...)`) and the rows of any other table (a path's)

    def times(self) -> np.ndarray:
        """Every breakpoint, sorted, once."""
        return distinct(np.concatenate((self.kinks, self.jumps, self.others)))

    def taken_as_jumps(self) -> np.ndarray:
        """The jumps and the breakpoints that may be one (`others`), sorted, once: what the
        masters treat as a jump (the fixed-step cuts, the adaptive stops, the pair's pieces)."""
        return distinct(np.concatenate((self.jumps, self.others)))


def source_breaks(instances) -> Breaks:
    """The breakpoints of every source among `instances` (graph.Instance: .table,
    .start_values, .value(name))."""
    kinks, jumps, others = [np.array([])], [np.array([])], [np.array([])]
    for inst in instances:
        table = inst.table
        if table is not None and table.is_twist:
            kink, jump = table.breaks(str(inst.value("interpolation")))
            kinks.append(kink)
            jumps.append(jump)
        elif table is not None:
            others.append(table.times)
        for name, value in inst.start_values.items():
            if name.endswith("_expr") and isinstance(value, str):
                others.append(np.array(compared_times(value), dtype=float))
    return Breaks(*(distinct(np.concatenate(p)) for p in (kinks, jumps, others)))


@dataclass(frozen=True, eq=False)
class Known:
    """Source outputs known at every time apart from the run: a twist table's columns, linear
    between its rows or held (`hold`: each row's value until the next row), its first and
    last rows' values before and after it (as the FMU and the ground truth read it)."""
    times: np.ndarray       # [s], increasing
    values: np.ndarray      # one row per time, one column per output
    hold: bool


def source_known(instances) -> tuple[Known, ...]:
    """The twist tables of the sources among `instances`, as Known signals."""
    return tuple(Known(inst.table.times, inst.table.values(TABLE_COLUMNS[1:]),
                       str(inst.value("interpolation")) == "hold")
                 for inst in instances if inst.table is not None and inst.table.is_twist)


def compared_times(text: str) -> list[float]:
    """The numbers t is compared with in an expression (t < 8, 2 <= t): plain literals only."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError):
        return []               # the loader refused it already; nothing to add here
    times = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(isinstance(n, ast.Name) and n.id == "t" for n in sides):
                times += [float(n.value) for n in sides if isinstance(n, ast.Constant)
                          and isinstance(n.value, (int, float))]
    return times
