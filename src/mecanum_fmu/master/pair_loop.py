"""The embedded pair around a loop: one error model's error carried through FMUs without a
state (their responses, Graph.responses) and back into its own held inputs (pair.Loop).

Per step k (nodes k and k + 1 of the run), the model's outputs carry the error E_k; every
carried value v carries S_v,k E_k, S its sensitivity to them, the chain's Jacobians at the
run's own values at node k; the model's held inputs (through S = C) carry C E. The pair's
hold error of an input (held - the mean of the cubic through the run's values) is taken
against the run's values, which carry that error: against the truth it adds the error's mean
over the step, (C_k E_k + C_k+1 E_k+1) / 2. The model's step, linearised in its own error
(PoseBatch.linear: E_k+1 = A_k E_k + B_k (input error)), then gives a linear recurrence
E_k+1 = P_k E_k + q_k, E_k+1 predicted explicitly (the step with C_k E_k held): the
model's own error, with the open-loop part kept as its model steps it (no linearisation of
what it makes alone), and the loop's part D = E - O on top, one 3x3 product per step.

Where the quadratic master predicts, rolls back and corrects, it holds the predicted end
value of a loop's input, the carried values of the predicted outputs: those differ from the
run's (corrected) ones by C_k+1 delta_k, delta_k = B_k (predictor's hold - corrector's), which
the corrector's trapezoid weighs by one half (a fed-back input's "now" by one).
"""
from __future__ import annotations

import numpy as np

from .pair import Group, Loop

# the share of the predicted end value in the corrector's hold, per role (plan.HOLDS)
_END_WEIGHT = {"state_ahead": 0.5, "fed_back": 1.0}


class LoopCarry:
    """The carried error of one run, batch by batch (its running totals carried on)."""

    def __init__(self, loop: Loop, group: Group):
        self.loop, self.n = loop, len(group.model.outputs)
        self.error = np.zeros(self.n)       # the model's outputs' error at the last node
        self.end_weight = np.array([_END_WEIGHT.get(r, 0.0) for r in group.roles])
        self.errors: dict[int, np.ndarray] = {}     # per carried column, this batch's errors

    def sensitivities(self, rows: np.ndarray) -> dict[int, np.ndarray]:
        """Per carried column, d value / d (the model's outputs) at each row, (rows, n)."""
        sens = {}
        for c, index in self.loop.starts:
            unit = np.zeros((len(rows), self.n))
            unit[:, index] = 1.0
            sens[c] = unit
        zero = np.zeros((len(rows), self.n))
        for t in self.loop.chain:
            jac = t.response.jacobian(rows[:, t.ins], rows[:, t.outs])
            s_in = np.stack([sens.get(c, zero) for c in t.ins], axis=1)
            s_out = jac @ s_in
            for k, c in enumerate(t.outs):
                sens[c] = s_out[:, k]
        return sens

    def steps(self, g: Group, h: np.ndarray, hold: tuple, rows: np.ndarray,
              predicted: np.ndarray | None) -> np.ndarray:
        """The signed error of the model's outputs after each step (as its model's steps),
        the loop's share included. `hold`: the pair's (held, error, change) per step;
        `rows`: the run's rows at nodes k .. k_last + 1; `predicted`: the predictor's hold
        where the run rolls back (else None)."""
        held, error, change = hold
        sens = self.sensitivities(rows)
        zero = np.zeros((len(rows), self.n))
        c = np.stack([sens.get(col, zero) for col in g.cols], axis=1)     # (nodes, in, n)
        a, b, made = g.model.linear(h, held, error, change)
        if predicted is not None:       # the predicted end values the corrector held
            delta = np.einsum("kni,ki->kn", b, predicted - held)
            extra = self.end_weight * np.einsum("kin,kn->ki", c[1:], delta)
            made = made + np.einsum("kni,ki->kn", b, extra)
        bc0, bc1 = b @ c[:-1], b @ c[1:]
        p = a + 0.5 * bc0 + 0.5 * bc1 @ (a + bc0)
        q = made + 0.5 * np.einsum("kmn,kn->km", bc1, made)
        total = np.empty_like(made)
        now = self.error
        for k in range(len(made)):
            now = p[k] @ now + q[k]
            total[k] = now
        self.error = now
        self.errors = {col: np.einsum("kn,kn->k", s[1:], total) for col, s in sens.items()}
        return total
