"""Where the sources' values jump or kink: the one reader of a graph's breakpoints. The
adaptive master ends its steps on the twist tables' (Stops, master/adaptive.py); the fixed-step
masters cut the step that ends on a jump (step_cuts); the error estimate keeps all of them on
its coarser grids (master/estimate.py)."""
from __future__ import annotations

import ast
from dataclasses import dataclass

import numpy as np

from ..graph import Graph
from ..models.blocks.profile_table import TableError, parse_table
from ..models.catalog import bundled_model
from ..profiles import table_columns


@dataclass(frozen=True)
class Breaks:
    kinks: np.ndarray    # a twist table's value turns: the corners of a linear table
    jumps: np.ndarray    # a twist table's value jumps: a hold table's changes (segments)
    others: np.ndarray   # either, or neither: the numbers an expression compares t with
    # (`where(t < 8, ...)`) and the rows of any other table (a path's)

    def times(self) -> np.ndarray:
        """Every breakpoint, sorted, once."""
        return np.unique(np.concatenate((self.kinks, self.jumps, self.others)))


def graph_breaks(graph: Graph) -> Breaks:
    """The breakpoints of every source in the graph."""
    kinks, jumps, others = [np.array([])], [np.array([])], [np.array([])]
    for inst in graph.instances:
        model = bundled_model(inst.model)
        for name, value in inst.start_values.items():
            if name == "table" and isinstance(value, str) and value.strip():
                if model is not None and model.name == "VelocitySource":
                    kink, jump = table_breaks(value, str(inst.value("interpolation")))
                    kinks.append(kink)
                    jumps.append(jump)
                else:
                    others.append(_row_times(value))
            elif name.endswith("_expr") and isinstance(value, str):
                others.append(np.array(compared_times(value), dtype=float))
    return Breaks(*(np.unique(np.concatenate(p)) for p in (kinks, jumps, others)))


def table_breaks(text: str, interpolation: str) -> tuple[np.ndarray, np.ndarray]:
    """(kinks, jumps) of a twist table: under `hold`, the rows where a value changes (jumps);
    else the rows between two rows where a slope changes (kinks)."""
    times, *columns = table_columns(text)
    values = np.stack(columns, axis=1)
    if interpolation == "hold":
        return np.array([]), times[1:][np.any(values[1:] != values[:-1], axis=1)]
    slopes = np.diff(values, axis=0) / np.diff(times)[:, None]
    return times[1:-1][np.any(slopes[1:] != slopes[:-1], axis=1)], np.array([])


def _row_times(text: str) -> np.ndarray:
    """The time column of a table that is no twist table (a path's)."""
    try:
        return np.asarray(parse_table(text, columns=("time",), quote=False)[0], dtype=float)
    except TableError:
        return np.array([])        # the loader refused it already; nothing to add here


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


NEAR = 1e-3     # [steps] a breakpoint this close to a communication point is on it (as
                # master/estimate.py's _on_grid: a recorded 0.049999872 s is on the 0.05 s grid)
CUT = 1e-9      # [steps] the piece of a step between the left value and a jump on its end


@dataclass(frozen=True)
class Cut:
    """How step k is taken in pieces: it ends at each of `inside` (times between its ends)
    and then at its own end; after a piece whose `restart` flag is set (one per inside
    time, then one for the step's end) the holds' history starts afresh."""
    inside: tuple[float, ...]
    restart: tuple[bool, ...]


def step_cuts(breaks: np.ndarray, start: float, h: float, n_steps: int, stop: float
              ) -> dict[int, Cut]:
    """The steps to cut, by index, for breakpoints `breaks` (jumps, or any that may be one):
    a breakpoint b on a communication point t_j (within NEAR steps) is reached from the left
    first. At or before t_j, the step that ends there is cut at b - delta: its first piece
    ends on the left value, the short second one on t_j, after which the holds restart. Just
    after t_j, the next step is cut at b - delta and at b, the holds restarting at b. A
    breakpoint inside a step (off the grid) is left alone: O(h) for a fixed step."""
    pieces: dict[int, dict[float, bool]] = {}
    for b in np.unique(breaks[(breaks > start) & (breaks <= stop)]):
        j = int(round((b - start) / h))
        t_j = stop if j >= n_steps else start + j * h
        if abs(b - t_j) > NEAR * h:
            continue
        before = float(b - max(CUT * h, 64 * np.spacing(b)))
        k, end = (j - 1, True) if b <= t_j else (j, False)
        t_k = start + k * h
        mine = pieces.setdefault(k, {})
        if before > t_k:
            mine.setdefault(before, False)
        if end:
            mine[np.inf] = True
        elif float(b) > t_k:
            mine[float(b)] = True
    return {k: _cut(p) for k, p in pieces.items()}


def _cut(pieces: dict[float, bool]) -> Cut:
    times = sorted(pieces)
    inside = tuple(t for t in times if t != np.inf)
    return Cut(inside, tuple(pieces[t] for t in inside) + (pieces.get(np.inf, False),))
