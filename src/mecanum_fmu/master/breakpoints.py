"""Where the sources' values jump or kink: the one reader of a graph's breakpoints for the
master (the graph carries them; this module knows no model). The
adaptive master ends its steps on the twist tables' (Stops, master/adaptive.py); the fixed-step
masters cut the step that ends on a jump (step_cuts); the error estimate keeps all of them on
its coarser grids (master/richardson.py)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scenario.graph import Graph
from ..scenario.tables import Breaks

__all__ = ["Breaks", "Cut", "graph_breaks", "step_cuts"]


def graph_breaks(graph: Graph) -> Breaks:
    """The breakpoints of every source in the graph: what the graph carries (Graph.breaks,
    computed by the scenario layer from its tables and expressions, tables.py)."""
    return graph.breaks


NEAR = 1e-3     # [steps] a breakpoint this close to a communication point is on it (as
                # master/richardson.py's _on_grid: a recorded 0.049999872 s is on the 0.05 s grid)
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
    first. At or before the end of the step that ends on t_j (as stepping computes it:
    t_j-1 + h, the last one stop), that step is cut at b - delta: its first piece ends on the
    left value, the short second one on t_j, after which the holds restart. Just after it,
    the next step is cut at b - delta and at b, the holds restarting at b. A breakpoint inside
    a step (off the grid) is left alone: O(h) for a fixed step."""
    pieces: dict[int, dict[float, bool]] = {}
    for b in (float(x) for x in np.unique(breaks[(breaks > start) & (breaks <= stop)])):
        j = n_steps if abs(b - stop) <= NEAR * h else int(round((b - start) / h))
        if j < 1 or abs(b - (stop if j >= n_steps else start + j * h)) > NEAR * h:
            continue
        delta = max(CUT * h, 64 * float(np.spacing(b)))
        end_before = stop if j >= n_steps else start + (j - 1) * h + h
        k = j - 1 if b <= end_before else j
        t_k = start + k * h
        mine = pieces.setdefault(k, {})
        if b - delta > t_k:
            mine.setdefault(b - delta, False)
        if k == j - 1:
            mine[np.inf] = True                 # the restart at the step's end
        else:
            mine[b if b > t_k else t_k + delta] = True
    return {k: _cut(p) for k, p in pieces.items()}


def _cut(pieces: dict[float, bool]) -> Cut:
    times = sorted(pieces)
    inside = tuple(t for t in times if t != np.inf)
    return Cut(inside, tuple(pieces[t] for t in inside) + (pieces.get(np.inf, False),))
