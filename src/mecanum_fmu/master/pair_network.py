"""The embedded pair across FMUs with a state that feed one another: a network of linearised
error models (a drive train: motors, the floor, the pose), with FMUs without a state between
them (their responses, as pair_loop.py carries them).

Each FMU with a state and a linear error model (Graph.error_models: `linearised`, models/
drive_error.py) has its state's error x; the pose's model (`linear`, PoseBatch) its own. All
of them together are X, but the integrals (the energies: no rate depends on them and no FMU
reads them), which are summed after. At each node of the run the error of every value the
network makes is S X (its sensitivity): an FMU's outputs C x + D (the error of its inputs
there), an FMU without a state's J (the error of its inputs). The pair's hold error of an
input (held - the mean of the cubic through the run's values) is taken against the run's
values, which carry an error: against the truth it adds that error's mean over the step,
u = (S_k X_k + S_k+1 X_k+1) / 2. Over the step an FMU whose linearisation is x' = A x + B u
(A, B the mean of the step's two ends) moves its error in trapezoidal form,

    (I - h A / 2) x_k+1 = (I + h A / 2) x_k + h B (the input's error) + (h^2 / 12) A B (the
    input's change over the step: the share of it within the step that a fast state follows,
    against the mean-held input),

and the PoseIntegrator by its own step (PoseBatch.linear). Together, L X_k+1 = R X_k + G (the
hold errors + u) + made: (L - G S_k+1 / 2) X_k+1 = (R + G S_k / 2) X_k + made_k, one inverse
per step, then X_k+1 = P_k X_k + q_k step by step (a few microseconds each). An integral adds
h/2 A_ic (x_k + x_k+1) + h B_i (its inputs' error) per step; where what it adds up to is under
CANCELS of the sum of its terms' sizes, it is unresolved (its largest, or its end): the
linearisation is good to 7% on the robot circle, to about 20% on the hard start at twice its
step.

Under Jacobi every FMU computes its outputs with its inputs of the row before: a value with
direct feedthrough at row r errs, beyond its sensitivity, by D (its inputs' time part - their
change from row r - 1 to row r) (an FMU without a state: J for D), and an input from outside
the network that arrives d rows late by row r - row r + d (rows past the last node
extrapolated as a line). That time part is carried with S X, in the hold errors and in the
outputs' errors.

Not followed here: where the quadratic master rolls back, the predicted end values' own error
(second order: the drive train's error is first order, its inputs with direct feedthrough
held at their newest values).
"""
from __future__ import annotations

import copy

import numpy as np

from ..results import CANCELS
from .pair_parts import Group, Network, Node

SUB = 1024          # the steps worked out at once (memory: S is (rows, columns, X) per batch)
# CANCELS (results.py): an integral's error under that share of the sum of its terms' |values|
# is unresolved (the terms are good to about 20% where the linearisation is worst, on the hard
# start at twice its step: what is left of them under a tenth of their sum may be off by over
# 2x)
SPREAD = 8          # that sum is taken on every SPREAD-th step (times SPREAD)


class NetworkCarry:
    """The network's error over one run, batch by batch (X and the integrals carried on)."""

    def __init__(self, net: Network, groups: list[Group], n_steps: int, frozen: bool = False):
        self.net, self.groups, self.n, self.frozen = net, groups, n_steps, frozen
        # under Jacobi: per node, its inputs from outside the network that arrive late (their
        # places and lags), and the most rows past a node those need
        self.late_in = {n.group: [(k, int(d)) for k, d in enumerate(groups[n.group].lags)
                                  if d > 0] for n in net.nodes}
        self.ahead = max([d for pairs in self.late_in.values() for _, d in pairs], default=0)
        self.x, self.e = np.zeros(net.size), np.zeros(len(net.integrals))
        self.spread = np.zeros(len(net.integrals))     # the sum of each integral's |terms|
        integral = {c: k for k, (_, c) in enumerate(net.integrals) if c is not None}
        self.cols = sorted({c for _, c in net.recorded} | {c for _, c, _ in net.checked})
        self.of_x = [c for c in self.cols if c not in integral]
        self.of_e = [integral[c] for c in self.cols if c in integral]
        self.where = np.array([c in integral for c in self.cols])
        # where steps() puts the recorded outputs and the checked values among self.cols
        at = {c: j for j, c in enumerate(self.cols)}
        self.recorded_at = np.array([at[c] for _, c in net.recorded], dtype=np.intp)
        self.checked_at = [at[c] for _, c, _ in net.checked]

    def steps(self, ks: np.ndarray, h: np.ndarray, holds: dict, window) -> np.ndarray:
        """The errors of self.cols at nodes ks + 1 (steps, columns). `holds`: per node's group
        the pair's (held, error, change) per step; window(first, last): the run's rows."""
        out = []
        for lo in range(0, len(ks), SUB):
            part = slice(lo, lo + SUB)
            out.append(self._part(ks[part], h[part], {i: tuple(a[part] for a in hold)
                                                      for i, hold in holds.items()}, window))
        return np.concatenate(out)

    def cancelled(self, sizes: dict) -> list[str]:
        """The recorded integrals whose |error| `sizes` (the largest, or the end's) is under
        CANCELS of the sum of the |terms| it is made of: what is left of terms that cancel,
        which the linearisation does not resolve (CANCELS)."""
        return [name for k, (name, _) in enumerate(self.net.integrals)
                if name in sizes and sizes[name] < CANCELS * self.spread[k]]

    def copy(self) -> "NetworkCarry":
        """A copy whose running totals are its own (PairRows' Jacobi tail)."""
        other = copy.copy(self)
        other.x, other.e, other.spread = self.x.copy(), self.e.copy(), self.spread.copy()
        return other

    def _part(self, ks, h, holds, window) -> np.ndarray:
        first, last = int(ks[0]), int(ks[-1]) + 1       # nodes first .. last
        around = window(first - 1, last + self.ahead)   # and the row before, the rows after
        past = np.arange(first - 1, last + self.ahead + 1) - self.n
        if self.ahead and past[-1] > 0:     # past the last node: extrapolated, as a line
            end = np.flatnonzero(past == 0)[0]
            slope = around[end] - around[end - 1]
            around = around.copy()
            around[end + 1:] = around[end] + past[end + 1:, None] * slope
        rows = around[1:last - first + 2]
        sens, times, maps = self._sensitivities(rows, around)
        n = len(ks)
        left, right, gain, made, s0, s1, late = self._maps(sens, maps, h, holds, len(rows))
        if times:                   # Jacobi: the values' own lag, carried with their error
            t = self._own(times, [c for node in self.net.nodes
                                  for c in self.groups[node.group].cols], len(rows))
            carried = 0.5 * (t[:-1] + t[1:])
            made = made + _apply(gain, carried)
            late = (late[0], late[1], late[2] + _apply(late[1], carried))
        inverse = np.linalg.inv(left - 0.5 * gain @ s1)
        p = inverse @ (right + 0.5 * gain @ s0)
        q = _apply(inverse, made)
        xs = np.empty((n + 1, self.net.size))
        xs[0] = x = self.x
        for k in range(n):
            x = p[k] @ x + q[k]
            xs[k + 1] = x
        self.x = x
        es = self._integrals(late, s0, s1, xs)
        out = np.empty((n, len(self.cols)))
        zero = np.zeros((len(rows), self.net.size))
        table = np.stack([sens.get(c, zero)[1:] for c in self.of_x], axis=1)  # (steps, cols, X)
        out[:, ~self.where] = np.einsum("kcx,kx->kc", table, xs[1:])
        if times:
            out[:, ~self.where] += self._own(times, self.of_x, len(rows))[1:]
        out[:, self.where] = es[:, self.of_e]
        return out

    def _integrals(self, late: tuple, s0, s1, xs) -> np.ndarray:
        """The integrals' errors after each step: per step h/2 A_ic (x_k + x_k+1) + h B_i (the
        input's error: the carried share's mean over the step, with made the rest); the sum of
        their terms' |values| kept (a term per state and per input, on every SPREAD-th step:
        a share against it decides, not a digit)."""
        arm, gain, made = late
        both = xs[:-1] + xs[1:]
        carried = 0.5 * (_apply(s0, xs[:-1]) + _apply(s1, xs[1:]))
        es = self.e + np.cumsum(_apply(arm, both) + _apply(gain, carried) + made, axis=0)
        few = slice(None, None, SPREAD)
        self.spread += SPREAD * (np.abs(arm[few] * both[few, None]).sum(axis=(0, 2))
                                 + np.abs(gain[few] * carried[few, None]).sum(axis=(0, 2))
                                 + np.abs(made[few]).sum(axis=0))
        self.e = es[-1]
        return es

    def _maps(self, sens: dict, maps: dict, h, holds: dict, rows: int) -> tuple:
        """Per step, each node's step as L x_k+1 = R x_k + G (its inputs' error) + made, block
        diagonal over X; those inputs' sensitivities at the step's start and end; and the
        integrals' (h/2 A_ic, h B_i, made)."""
        n, size, count = len(h), self.net.size, len(self.net.integrals)
        inputs = sum(len(self.groups[node.group].cols) for node in self.net.nodes)
        left, right = np.zeros((n, size, size)), np.zeros((n, size, size))
        gain, made = np.zeros((n, size, inputs)), np.zeros((n, size))
        arm, i_gain, i_made = (np.zeros((n, count, size)), np.zeros((n, count, inputs)),
                               np.zeros((n, count)))
        s = np.zeros((rows, inputs, size))
        m = 0
        for node in self.net.nodes:
            g = self.groups[node.group]
            block, ins = slice(node.offset, node.offset + node.size), slice(m, m + len(g.cols))
            at = slice(node.first, node.first + len(node.integral))
            left[:, block, block], right[:, block, block], gain[:, block, ins], \
                made[:, block], late = self._discrete(node, g, maps.get(node.group), h,
                                                      holds[node.group])
            if late is not None:
                arm[:, at, block], i_gain[:, at, ins], i_made[:, at] = late
            for k, c in enumerate(g.cols):
                if c in sens:
                    s[:, m + k] = sens[c]
            m += len(g.cols)
        return left, right, gain, made, s[:-1], s[1:], (arm, i_gain, i_made)

    def _discrete(self, node: Node, g: Group, lin, h, hold) -> tuple:
        """(L, R, G, made, the integrals' (h/2 A_ic, h B_i, made) or None) per step of one node:
        its model's own step (`linear`: L = I), or its linearisation at the step's two ends,
        averaged, in trapezoidal form: L = I - h A / 2, R = I + h A / 2, G = h B, made = G
        (the hold's error) + (h^2 / 12) A B (the input's change over the step): L^-1 of that
        is Gamma1's share, as the module says."""
        held, error, change = hold
        if lin is None:
            a, b, made = g.model.linear(h, held, error, change)
            return np.eye(node.size), a, b, made, None
        a, b = 0.5 * (lin[0][:-1] + lin[0][1:]), 0.5 * (lin[1][:-1] + lin[1][1:])
        kept, integral = node.kept, node.integral
        a_cc, b_c = a[:, kept][:, :, kept], b[:, kept]
        a_ic, b_i = a[:, integral][:, :, kept], b[:, integral]
        hk = h[:, None, None]
        half, gain = 0.5 * hk * a_cc, hk * b_c
        ramp = (h * h / 12.0)[:, None] * change
        eye = np.eye(node.size)
        made = _apply(gain, error) + _apply(a_cc @ b_c, ramp)
        i_made = _apply(hk * b_i, error) + _apply(a_ic @ b_c, ramp)
        return eye - half, eye + half, gain, made, (0.5 * hk * a_ic, hk * b_i, i_made)

    def _late(self, cols, around: np.ndarray, lags=()) -> np.ndarray:
        """Under Jacobi, what the inputs `cols` of an FMU with direct feedthrough add to its
        outputs' error beyond their own (sensitivities'), per row r: it computed them with
        its inputs of row r - 1: their time part (the network's values') or their lag (an
        input from outside, d rows late: row r - row r + d), less their change, row r -
        row r - 1."""
        rows = len(around) - 1 - self.ahead
        now, before = around[1:rows + 1][:, cols], around[:rows][:, cols]
        late = -(now - before)
        for k, d in lags:
            late[:, k] += now[:, k] - around[1 + d:rows + 1 + d][:, cols[k]]
        return late

    def _sensitivities(self, rows: np.ndarray, around: np.ndarray) -> tuple[dict, dict, dict]:
        """Per column the network makes (but the integrals), d value / d X at each row; under
        Jacobi its time part (what its row's value errs beyond that, from the rows: its
        inputs' lag and change); and per linearised node its (A, B) at each row."""
        size, zero = self.net.size, np.zeros((len(rows), self.net.size))
        sens, times, maps = {}, {}, {}
        for kind, item in self.net.steps:
            if kind == "through":
                s_in = np.stack([sens.get(c, zero) for c in item.ins], axis=1)
                jac = item.response.jacobian(rows[:, item.ins], rows[:, item.outs])
                s_out = jac @ s_in
                sens.update({c: s_out[:, k] for k, c in enumerate(item.outs)})
                if self.frozen:
                    tau = self._late(item.ins, around) + self._own(times, item.ins, len(rows))
                    times.update({c: t for c, t in zip(item.outs, _apply(jac, tau).T)})
                continue
            g = self.groups[item.group]
            if item.reads is None:          # its outputs are its state
                for k, c in enumerate(item.outs):
                    if c is not None:
                        sens[c] = np.zeros((len(rows), size))
                        sens[c][:, item.offset + k] = 1.0
                continue
            a, b, c_map, d_map = g.model.linearised(rows[:, g.cols], rows[:, item.reads])
            maps[item.group] = (a, b)
            s_out = np.zeros((len(rows), len(item.outs), size))
            if any(c in sens for c in g.cols):      # its inputs carry an error there
                s_out = d_map @ np.stack([sens.get(c, zero) for c in g.cols], axis=1)
            s_out[:, :, item.offset:item.offset + item.size] += c_map[:, :, item.kept]
            sens.update({c: s_out[:, k] for k, c in enumerate(item.outs) if c is not None})
            if self.frozen:
                tau = self._late(g.cols, around, self.late_in[item.group]) + self._own(
                    times, g.cols, len(rows))
                times.update({c: t for c, t in zip(item.outs, _apply(d_map, tau).T)
                              if c is not None})
        return sens, times, maps

    @staticmethod
    def _own(times: dict, cols, rows: int) -> np.ndarray:
        """The time parts the columns `cols` carry (0 for those that have none), (rows, cols)."""
        return np.column_stack([times.get(c, np.zeros(rows)) for c in cols])


def _apply(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """matrices[k] @ vectors[k] for every k."""
    return (matrices @ vectors[:, :, None])[:, :, 0]
