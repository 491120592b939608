"""The embedded pair around a loop: one error model's error carried through FMUs without a
state (their responses, Graph.responses) and back into its own held inputs (pair_parts.Loop).

Per step k (nodes k and k + 1 of the run), the model's outputs carry the error E_k; every
carried value v carries S_v,k E_k, S its sensitivity to them, the chain's Jacobians at the
run's own values at node k; the model's held inputs (through S = C) carry C E. The pair's
hold error of an input (held - the mean of the cubic through the run's values) is taken
against the run's values, which carry that error: against the truth it adds the error's mean
over the step, (C_k E_k + C_k+1 E_k+1) / 2. The model's step, linearised in its own error
(PoseBatch.linear: E_k+1 = A_k E_k + made_k + B_k (the input's further error)), then gives
a linear recurrence E_k+1 = P_k E_k + q_k, E_k+1 predicted explicitly (the step with C_k E_k
held), solved per chunk by doubling (_recurrence).

Under Jacobi each FMU of the chain is a row late (its depth d: row r carries S_r E_r-d), and
its row r is f(the inputs of row r - 1, t_r): its own change with t over the step is taken
out of the "true" values too (LoopCarry.sensitivities' time part).

Where the quadratic master predicts, rolls back and corrects, it holds the predicted end
value of a loop's input, the carried values of the predicted outputs: those differ from the
run's (corrected) ones by C_k+1 delta_k, delta_k = B_k (predictor's hold - corrector's), which
the corrector's trapezoid weighs by one half (a fed-back input's "now" by one).
"""
from __future__ import annotations

import numpy as np

from .pair_parts import Group, Loop

# the share of the predicted end value in the corrector's hold, per role (plan.HOLDS)
_END_WEIGHT = {"state_ahead": 0.5, "fed_back": 1.0}


class LoopCarry:
    """The carried error of one run, batch by batch (its running totals carried on). Under
    Jacobi (`frozen`) an FMU's output row r comes from its inputs' row r - 1: a value d FMUs
    down the chain (its `depth`) at row r carries S_r E_(r-d)."""

    def __init__(self, loop: Loop, group: Group, frozen: bool):
        self.loop, self.n, self.frozen = loop, len(group.model.outputs), frozen
        self.error = np.zeros(self.n)       # the model's outputs' (or state's) error at the
        # last node: its state's where its linear form has one (two poles, E = H X)
        self.end_weight = np.array([_END_WEIGHT.get(r, 0.0) for r in group.roles])
        self.depth = {c: 0 for c, _ in loop.starts}
        for t in loop.chain:
            self.depth.update({c: t.lag for c in t.outs})
        self.reach = max(self.depth.values())   # the deepest: the rows before a step it reads
        self.where = {c: i for i, c in enumerate(self.depth)}    # a column's place in table
        self.depths = np.array(list(self.depth.values()))   # per place, its column's depth
        self.places = np.arange(len(self.where))
        self.at: dict[tuple, np.ndarray] = {}   # carried columns' places (_at)
        # the starts' places and indices in the model's outputs; per FMU of the chain, its
        # inputs' and outputs' places, and (_direct) its inputs' indices in the model's
        # outputs where it reads those alone; the held inputs' places (_places)
        self.starts = (self._places([c for c, _ in loop.starts]),
                       np.array([i for _, i in loop.starts], dtype=np.intp))
        self.chain = [(t, self._places(t.ins), self._places(t.outs),
                       _direct(t.ins, dict(loop.starts))) for t in loop.chain]
        self.held = self._places(group.cols)
        # this batch's, on rows first .. (sensitivities): S, and (Jacobi) the time's part
        self.sens = np.zeros((1, len(self.where) + 1, self.n))
        self.times: np.ndarray | None = None
        self.first, self.nodes, self.at_nodes = 0, 0, np.zeros((1, self.n))
        self.table = np.zeros((1, len(self.where)))     # this batch's carried errors (_table)
        # its branch's (steps): the first node, the carried errors, the errors at the nodes
        self.branch_nodes, self.branch_table, self.branch_at = 0, self.table, self.at_nodes

    def _places(self, cols) -> np.ndarray:
        """The places of columns `cols` among the carried ones (self.where; a column the loop
        does not carry: the place past them, whose sensitivity is 0)."""
        return np.array([self.where.get(c, len(self.where)) for c in cols], dtype=np.intp)

    def sensitivities(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Per carried column (self.where's places, then a 0 for the columns it does not
        carry), d value / d (the model's outputs) at each of `rows` (the run's rows in order;
        under Jacobi the first row's inputs stand for the row before it), (rows, places, n);
        and (Jacobi, else None) the time's part of it, (rows, places): a late FMU's row r is
        f(inputs of row r - 1, t_r), its true value at t_r-1 f(the same inputs, t_r-1), less
        its explicit change over the step, out_r - out_r-1 - J (in_r-1 - in_r-2), carried on
        through the chain."""
        sens = np.zeros((len(rows), len(self.where) + 1, self.n))
        sens[:, self.starts[0], self.starts[1]] = 1.0
        times = np.zeros(sens.shape[:2]) if self.frozen else None
        for t, ins_at, outs_at, direct in self.chain:
            ins, outs = rows[:, t.ins], rows[:, t.outs]
            before = _late(ins) if self.frozen else ins     # Jacobi: the row before's
            jac = t.response.jacobian(before, outs)
            if direct is not None:      # of unit sensitivities (and no time's part): J's columns
                sens[:, outs_at[:, None], direct] = jac
            else:
                s_in = sens[:, ins_at]
                sens[:, outs_at] = jac @ (_late(s_in) if self.frozen else s_in)
            if self.frozen:
                own = outs - _late(outs) - np.einsum("rij,rj->ri", jac, before - _late(before))
                times[:, outs_at] = own if direct is not None else own + np.einsum(
                    "rij,rj->ri", jac, _late(times.take(ins_at, axis=1)))   # rows' order
        return sens, times

    def carried(self, cols: list[int], nodes: np.ndarray, branch: bool = False) -> np.ndarray:
        """The errors that columns `cols` carry at `nodes` (this batch's: the steps' starts
        through the last one's end; `branch`: its branch's nodes), (nodes, cols)."""
        table, first = (self.branch_table, self.branch_nodes) if branch else \
            (self.table, self.nodes)
        return table[(nodes - first)[:, None], self._at(cols)]

    def _at(self, cols: list[int]) -> np.ndarray:
        """The places of carried columns `cols` in table (worked out once per list)."""
        key = tuple(cols)
        if key not in self.at:
            self.at[key] = np.array([self.where[c] for c in cols], dtype=np.intp)
        return self.at[key]

    def _table(self, nodes: np.ndarray, at_nodes: np.ndarray) -> np.ndarray:
        """Every carried column's error at `nodes`, (nodes, columns in self.where's order): S
        at the node + the column's depth (at most the last row) times E at the node
        (`at_nodes`, a row per node)."""
        rows = np.minimum(nodes[:, None] + (self.depths - self.first), len(self.sens) - 1)
        found = np.einsum("kmn,kn->km", self.sens[rows, self.places], at_nodes)
        if self.times is not None:
            found += self.times[rows, self.places]
        return found

    def steps(self, g: Group, h: np.ndarray, hold: tuple, ks: np.ndarray, window,
              predicted: np.ndarray | None, branch: int = 0) -> np.ndarray:
        """The signed error of the model's outputs after each step (as its model's steps),
        the loop's share included. `hold`: the pair's (held, error, change) per step; `ks`
        the steps; window(first, last) the run's rows first .. last (clipped to those it
        has); `predicted`: the predictor's hold where the run rolls back (else None); with a
        `branch`, the last that many rows are the steps before them again (Jacobi's end with
        the parabola, PairRows._steps), carried on from the error before those."""
        held, error, change = hold
        d = g.lag
        self.first = int(ks[0]) - self.reach
        rows = window(self.first, int(ks[-1]) + d + 1)
        self.sens, self.times = self.sensitivities(rows)
        at = (ks + d - self.first)[:, None]
        c0, c1 = self.sens[at, self.held], self.sens[at + 1, self.held]     # (steps, in, n)
        if self.times is not None:      # Jacobi: the true input less the time's part too
            error = error + 0.5 * (self.times[at, self.held] + self.times[at + 1, self.held])
        a, b, made, *hidden = g.model.linear(h, held, error, change, branch)
        if hidden:      # the model's state X, its outputs' error E = H X (two poles)
            c0, c1 = c0 @ hidden[0], c1 @ hidden[0]
            if len(self.error) != b.shape[1]:
                self.error = np.zeros(b.shape[1])
        if predicted is not None:       # the predicted end values the corrector held
            delta = np.einsum("kni,ki->kn", b, predicted - held)
            extra = self.end_weight * np.einsum("kin,kn->ki", c1, delta)
            made = made + np.einsum("kni,ki->kn", b, extra)
        bc0, bc1 = b @ c0, b @ c1
        p = a + 0.5 * bc0 + 0.5 * bc1 @ (a + bc0)
        q = made + 0.5 * np.einsum("kmn,kn->km", bc1, made)
        self.nodes, kept = int(ks[0]), len(ks) - branch
        out = hidden[0].T if hidden else None       # X -> E, rows
        states = np.concatenate((self.error[None], _recurrence(p[:kept], q[:kept], self.error)))
        self.at_nodes = states @ out if out is not None else states
        if branch:
            self._branch(p[kept:], q[kept:], states[kept - branch], int(ks[kept]), out)
        self.error = states[-1]
        self.table = self._table(np.arange(self.nodes, self.nodes + kept + 1), self.at_nodes)
        total = self.at_nodes[1:]
        return np.concatenate((total, self.branch_at[1:])) if branch else total

    def _branch(self, p: np.ndarray, q: np.ndarray, start: np.ndarray, node: int,
                out: np.ndarray | None) -> None:
        """The branch's errors from `start`, the error (the model's state: X, `out` its
        outputs' map) at its first step's start `node`: at its nodes (branch_at) and carried
        (branch_table, branch_nodes)."""
        states = np.concatenate((start[None], _recurrence(p, q, start)))
        self.branch_at = states @ out if out is not None else states
        self.branch_nodes = node
        self.branch_table = self._table(np.arange(node, node + len(p) + 1), self.branch_at)


def _recurrence(p: np.ndarray, q: np.ndarray, start: np.ndarray) -> np.ndarray:
    """e_k+1 = p_k e_k + q_k from e_0 = start, for k = 0 .. len(p) - 1: the rows e_1 ...
    By doubling (a scan of the affine maps: after the round of offset m, map k takes e_k-2m+1
    to e_k+1), log2 of the steps NumPy calls rather than one per step. From a start of 0 (a
    run's first batch) the maps' p only carry the q of later rounds: the last round's
    products, which would only multiply the start, are left out."""
    p, q = p.copy(), q[:, :, None].copy()     # q as columns, for the products
    m, zero = 1, not start.any()
    while m < len(p):
        q[m:] += p[m:] @ q[:-m]
        if 2 * m < len(p) or not zero:
            p[m:] = p[m:] @ p[:-m]
        m *= 2
    return q[..., 0] if zero else p @ start + q[..., 0]


def _direct(ins, starts: dict) -> np.ndarray | None:
    """The indices in the model's outputs of an FMU's inputs `ins` where it reads those alone,
    each once (its sensitivities then are its Jacobian's columns), else None."""
    index = [starts.get(c) for c in ins]
    if None in index or len(set(index)) < len(index):
        return None
    return np.array(index, dtype=np.intp)


def _late(values: np.ndarray) -> np.ndarray:
    """The values of the row before each row (the first standing for its own)."""
    return np.concatenate((values[:1], values[:-1]))
