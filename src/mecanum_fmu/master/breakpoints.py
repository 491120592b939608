"""Where the sources' values jump or kink: the one reader of a graph's breakpoints for the
master (the graph carries them; this module knows no model). The adaptive master ends its
steps on every one of them (Stops, master/step_control.py); the fixed-step masters cut the step
that ends on a jump (step_cuts); the error estimate keeps all of them on its coarser grids
(master/richardson.py); the embedded pair reads the sources' smooth pieces on the grid
(pieces)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scenario.graph import Graph
from ..scenario.tables import Breaks, distinct

__all__ = ["Breaks", "Cut", "Pieces", "graph_breaks", "pieces", "step_cuts"]


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
    for b in (float(x) for x in distinct(breaks[(breaks > start) & (breaks <= stop)])):
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


@dataclass(frozen=True)
class Pieces:
    """The smooth pieces of the sources on the grid of nodes 0 .. n (true times, in steps):
    piece i starts at node starts[i] and its values are usable up to node ends[i] (a jump's
    node belongs to the piece after it); `cut`: the nodes at which a step ends on a jump (the
    master cuts it: the step sees the left value, the holds restart); `across`: step index ->
    (the fraction of it before a breakpoint inside it, whether that may be a jump)."""
    starts: np.ndarray
    ends: np.ndarray
    cut: np.ndarray
    across: dict
    # a piece with a kink at an end holds fewer than two nodes: the steps are longer than
    # the table's rows, and the values the run sees do not tell the input between them
    short: bool = False
    # some piece holds one node (a hold table's rows as close as the steps): its one value
    # says it all where the input is constant between the jumps, not where it may move (a
    # loop, an FMU with a state: estimate.LONE_PIECES)
    lone: bool = False


KINK, ACROSS_KINK, ACROSS_JUMP, JUMP = range(4)     # what starts a piece, weakest first


def pieces(breaks, start: float, h: float, n: int) -> Pieces:
    """The pieces of `breaks` (tables.Breaks) on a run of n steps of h from start: a kink on
    a node ends one piece there and starts the next; a jump (or what may be one: `others`)
    on a node starts the next piece there, the one before ending a node earlier; one inside
    a step ends a piece at the step's start and starts the next at its end. Where several
    fall on one node, the strongest says how (a jump over one across a step over a kink).
    (In plain floats: a run's breakpoints are few, and a NumPy call per line cost more.)"""
    if not (len(breaks.kinks) or len(breaks.jumps) or len(breaks.others)):
        return Pieces(np.zeros(1, dtype=np.int64), np.array([n]), np.zeros(0, dtype=np.int64),
                      {}, False, False)
    rank: dict[int, int] = {}       # per node, what starts a piece there
    across: dict[int, tuple] = {}   # per step, its first kink, or its last jump
    marked = [(b, False) for b in np.asarray(breaks.kinks, dtype=float).tolist()] + [
        (b, True) for b in breaks.taken_as_jumps().tolist()]
    for b, jump in marked:
        x = (b - start) / h
        j = round(x)
        if abs(x - j) < NEAR:
            if 0 < j <= n:
                rank[j] = max(rank.get(j, -1), JUMP if jump else KINK)
        elif 0 < x < n:
            k = math.floor(x)
            rank[k + 1] = max(rank.get(k + 1, -1), ACROSS_JUMP if jump else ACROSS_KINK)
            if k not in across or jump:
                across[k] = (x - k, jump)
    bounds = sorted(rank)
    starts = [0, *bounds]
    ends = [b if rank[b] == KINK else b - 1 for b in bounds] + [n]
    after_kink = [rank.get(s, -1) in (KINK, ACROSS_KINK) for s in starts]
    kinked = [a or b for a, b in zip(after_kink, after_kink[1:] + [False])]  # either end
    # (a piece that starts on the last node holds no step: a table's row at the stop time)
    lone = [e - s < 1 and s < n for s, e in zip(starts, ends)]
    return Pieces(np.array(starts, dtype=np.int64), np.array(ends, dtype=np.int64),
                  np.array([b for b in bounds if rank[b] == JUMP], dtype=np.int64), across,
                  any(l and k for l, k in zip(lone, kinked)), any(lone))
