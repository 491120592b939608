"""The embedded pair stepped over the run's rows (pair.py holds the plan): the recorder's tap.

Every chunk of rows the recorder flushes passes through PairRows, which keeps the columns the
plan needs and works out each step's errors as soon as the values its stencil reads are in:
the rows of a window a few steps long, so that memory stays flat for any run length. The
cost is a few NumPy operations per chunk of 4096 rows, not per step.
"""
from __future__ import annotations

import time as _time

import numpy as np

from .pair import Group, PairPlan, _unit, _weights, pieces

_FLOOR = 8 * np.finfo(float).eps     # per step and unit of size: results.round_off's


class PairRows:
    """The pair over the rows of one run of n steps (Recorder.tap, then finish())."""

    def __init__(self, plan: PairPlan, exp, n_steps: int, breaks):
        self.plan, self.n, self.h = plan, n_steps, exp.step_size
        self.last = (exp.stop_time - exp.start_time) / exp.step_size - (n_steps - 1)
        self.pieces = pieces(breaks, exp.start_time, exp.step_size, n_steps)
        self.window = np.empty((0, len(plan.slots)))
        self.lo, self.k = 0, 0      # the row window[0] holds; the next step to work out
        lags = [g.lag for g in plan.groups] + [d for _, _, d in plan.lagged]
        self.reach = 4 + max(lags, default=0)   # an across step's right nodes
        self.worst = {name: 0.0 for name in (*plan.covered, *(n for n, _, _ in plan.lagged))}
        self.end = dict.fromkeys(self.worst, 0.0)
        self.moved = [np.zeros(len(g.cols)) for g in plan.groups]
        self.size = np.zeros(len(plan.slots))
        self.seconds = 0.0

    @property
    def may_fail(self) -> bool:
        """Whether the pair may find, after the run, that it does not hold (an FMU with a
        state and no error model): the run then keeps its t0 for Richardson's coarser runs."""
        return any(g.model is None for g in self.plan.groups)

    def __call__(self, rows: np.ndarray, first: int) -> None:
        """A chunk of whole buffer rows, the first being row `first` of the run."""
        tick = _time.perf_counter()
        new = rows[:, self.plan.slots]
        self.window = np.concatenate((self.window, new))
        np.maximum(self.size, np.max(np.abs(new), axis=0, initial=0.0), out=self.size)
        self._steps(min(self.n - 1, self.lo + len(self.window) - 1 - self.reach))
        self.seconds += _time.perf_counter() - tick

    def finish(self) -> dict:
        """results.extra["pair"]: per output the largest |error| and the end's, the seconds
        it took, and why the estimate falls back to Richardson (None: it does not)."""
        tick = _time.perf_counter()
        self._steps(self.n - 1)
        for name, col, d in self.plan.lagged:      # the last row, against its true value
            _, start, end = self._stencils(np.array([self.n - 1]), d, np.array([col]))
            self._keep(name, self.window[self.n - self.lo, col] - end[:, 0])
        self.seconds += _time.perf_counter() - tick
        return {"estimate": {n: (self.worst[n], self.end[n]) for n in self.worst},
                "seconds": self.seconds, "failed": self._moved(), "lagged": bool(
                    self.plan.lagged) or any(g.lag for g in self.plan.groups),
                "models": [f"{g.name}'s" for g in self.plan.groups if g.model is not None]}

    def _moved(self) -> str | None:
        """Why the pair does not hold: an FMU with a state and no error model whose held
        inputs moved within the steps (beyond their round-off)."""
        for g, moved in zip(self.plan.groups, self.moved):
            floor = _FLOOR * np.maximum(1.0, self.size[g.cols]) * max(self.n, 1)
            if g.model is None and (moved > floor).any():
                return (f"{g.name} has a state and no error model, and its held inputs move "
                        "within the steps")
        return None

    def _keep(self, name: str, errors: np.ndarray) -> None:
        if len(errors):
            self.worst[name] = max(self.worst[name], float(np.max(np.abs(errors))))
            self.end[name] = abs(float(errors[-1]))

    def _steps(self, k_hi: int) -> None:
        """Work out steps self.k .. k_hi, then drop the rows no later step reads."""
        ks = np.arange(self.k, k_hi + 1)
        if not len(ks):
            return
        h = np.full(len(ks), self.h)
        if ks[-1] == self.n - 1:
            h[-1] = self.last * self.h
        for i, g in enumerate(self.plan.groups):
            held, error, change = self._group(g, ks)
            if g.model is None:
                np.maximum(self.moved[i], np.max(np.abs(error), axis=0), out=self.moved[i])
                continue
            signed = g.model.steps(h, held, error, change)
            for name, (j, index) in self.plan.covered.items():
                if j == i:
                    self._keep(name, signed[:, index])
        for name, col, d in self.plan.lagged:
            _, start, _ = self._stencils(ks, d, np.array([col]))
            self._keep(name, self.window[ks - self.lo, col] - start[:, 0])
        self.k = k_hi + 1
        drop = max(0, self.k - 4 - self.lo)
        self.window, self.lo = self.window[drop:], self.lo + drop

    def _group(self, g: Group, ks: np.ndarray) -> tuple:
        """(held, held - true mean, the true change over the step) per step and input."""
        mean, start, end = self._stencils(ks, g.lag, g.cols)
        row = lambda shift: self.window[np.maximum(ks + shift - self.lo, 0)][:, g.cols]  # noqa
        now = row(0)
        if self.plan.hold == "frozen":      # Jacobi: the values of t_k, late by the lag
            return now, now - mean, end - start
        seen = np.where(np.isin(ks + 1, self.pieces.cut)[:, None], end, row(1))
        held = np.where(g.roles == "direct", seen, 0.5 * (now + seen))
        if self.plan.hold == "quadratic":
            held = held - np.where(g.roles == "direct", 0.0,
                                   self._parabola(ks, now, seen, row(-1), row(-2)))
        return held, held - mean, end - start

    def _parabola(self, ks, now, seen, before, older) -> np.ndarray:
        """The quadratic master's correction to the trapezoid (plan._Blend): the second
        difference over the step, limited (minmod) by the one before, from the second step
        after a restart (the run's start, a jump) on."""
        restarts = np.concatenate(([0], self.pieces.cut))
        since = ks - restarts[np.searchsorted(restarts, ks, side="right") - 1]
        a = (seen - now - now + before) * (1 / 12)
        b = (now - before - before + older) * (1 / 12)
        limited = np.minimum(np.maximum(b, np.minimum(a, 0.0)), np.maximum(a, 0.0))
        return np.where((since >= 2)[:, None], limited, 0.0)

    def _stencils(self, ks: np.ndarray, d: int, cols: np.ndarray) -> tuple:
        """Per step: the true value's mean over it, and its values at its start and end,
        from the cubic (or lower) through the nearest nodes of its piece (values late by d
        rows: node j is row j + d)."""
        pc = self.pieces
        piece = np.searchsorted(pc.starts, ks, side="right") - 1
        a, b = pc.starts[piece], np.minimum(pc.ends[piece], self.n - d)
        m = np.clip(b - a + 1, 1, 4)
        s = np.minimum(np.maximum(ks - 1, a), b - m + 1)
        o = ks - s
        out = [np.empty((len(ks), len(cols))) for _ in range(3)]
        for mm, oo in set(zip(m.tolist(), o.tolist())):
            sel = (m == mm) & (o == oo)
            nodes = _unit(mm)
            rows = s[sel][:, None] + np.arange(mm) + d - self.lo
            values = self.window[rows][:, :, cols]
            for target, w in zip(out, (_weights(nodes, oo, oo + 1.0), _weights(nodes, oo, None),
                                       _weights(nodes, oo + 1.0, None))):
                target[sel] = np.tensordot(values, w, axes=([1], [0]))
        self._odd_steps(ks, d, cols, (a, b, s, m), out)
        return tuple(out)

    def _odd_steps(self, ks, d, cols, stencil, out) -> None:
        """The steps the uniform stencils do not fit: the last one when it is shorter, and a
        step with a breakpoint inside (its mean split between the pieces on either side)."""
        a, b, s, m = stencil
        first, last = int(ks[0]), int(ks[-1])
        odd = [k for k in self.pieces.across if first <= k <= last]
        if last == self.n - 1 and abs(self.last - 1.0) > 1e-9 and last not in odd:
            odd.append(last)
        for k in odd:
            i = k - first
            if k in self.pieces.across:
                self._across(k, d, cols, (int(a[i]), int(m[i])), [o[i] for o in out])
                continue
            nodes = tuple(float(j) if j < self.n else k + self.last
                          for j in range(s[i], s[i] + m[i]))
            values = self.window[np.arange(s[i], s[i] + m[i]) + d - self.lo][:, cols]
            for target, w in zip(out, (_weights(nodes, k, k + self.last),
                                       _weights(nodes, k, None),
                                       _weights(nodes, k + self.last, None))):
                target[i] = w @ values

    def _across(self, k: int, d: int, cols, left: tuple, out: list) -> None:
        """A step with a breakpoint at fraction f inside: f of the left piece's polynomial
        (through the nodes up to k), 1 - f of the right one's (from node k + 1)."""
        f = self.pieces.across[k]
        a, _ = left
        m_left = max(1, min(k - a + 1, 4))
        nxt = int(np.searchsorted(self.pieces.starts, k + 1, side="right") - 1)
        m_right = max(1, min(int(min(self.pieces.ends[nxt], self.n - d)) - k, 4))
        lnodes = tuple(float(j) for j in range(k - m_left + 1, k + 1))
        rnodes = tuple(float(j) for j in range(k + 1, k + 1 + m_right))
        lvals = self.window[np.arange(k - m_left + 1, k + 1) + d - self.lo][:, cols]
        rvals = self.window[np.arange(k + 1, k + 1 + m_right) + d - self.lo][:, cols]
        mean, start, end = out
        mean[:] = (f * (_weights(lnodes, k, k + f) @ lvals)
                   + (1 - f) * (_weights(rnodes, k + f, k + 1.0) @ rvals))
        start[:] = _weights(lnodes, float(k), None) @ lvals
        end[:] = _weights(rnodes, k + 1.0, None) @ rvals
