"""The true inputs of the embedded pair's steps, from the run's rows (PairRows' stencils): per
step and column, the true value's mean over the step and its values at the step's ends, from
the cubic (or lower) through the nearest nodes of its piece (late by d rows under Jacobi: node
j is row j + d), all lags in one NumPy pass of the uniform weights (stencils.weight_table);
the odd steps on their own nodes (a breakpoint inside: the pieces on either side; a shorter
last step); and where the pieces are too short for the rows, the tables (pair_known.py).
"""
from __future__ import annotations

import numpy as np

from .stencils import FOUR, means, values, weight_table


def with_branch(a: np.ndarray, branch: int) -> np.ndarray:
    """The per-step values `a` with their last `branch` again after them: the rows of a batch
    whose last steps are worked out a second time (PairRows._steps' branch); `a` itself
    without one (its readers do not write to it)."""
    return np.concatenate((a, a[len(a) - branch:])) if branch else a


class Stencils:
    """PairRows' stencils (a mixin: they read its window, pieces and breakpoints)."""

    def _tabled(self, ks: np.ndarray, branch: int = 0) -> dict:
        """Per lag and step: the true value's mean over it, and its values at its start and
        end, where the pieces are too short for the rows, from the tables (else
        _polynomials: from the cubic, or lower, through the nearest nodes of its piece,
        values late by d rows: node j is row j + d); with `branch`, the last that many
        steps again (_steps)."""
        fits = {d: self.known.check(self.window, self.lo, d, cols, self.needed[d])
                for d, cols in self.cols.items()}
        designs = self.known.designs(with_branch(ks, branch))
        out = {d: self.known.stencils(designs, d) for d in self.cols}
        # late outputs the tables do not tell: read at the nodes
        untold = {d: cols[~fits[d]] for d, cols in self.cols.items() if not fits[d].all()}
        for d, found in self._polynomials(ks, untold, branch).items():
            for o, p in zip(out[d], found):
                o[:, ~fits[d]] = p
        return out

    def _polynomials(self, ks: np.ndarray, cols_by_lag: dict | None = None, branch: int = 0
                     ) -> dict:
        """Per lag and step: the true value's mean over it, and its values at its start and
        end, from the cubic (or lower) through the run's rows, of its columns (`cols_by_lag`,
        by default self.cols: every lag's), the uniform stencils in one go; with `branch`,
        the last that many steps again after them, with the parabola."""
        cols_by_lag = self.cols if cols_by_lag is None else cols_by_lag
        rows = with_branch(ks, branch)
        three = rows >= self.tail
        three[len(ks):] = True
        lags, n = list(cols_by_lag), len(rows)
        if not lags:
            return {}
        s, m, found = self._uniform(rows, lags[0], three) if len(lags) == 1 else \
            self._uniform(np.concatenate((rows,) * len(lags)),
                          np.repeat(np.array(lags, dtype=np.int64), n),
                          np.concatenate((three,) * len(lags)))
        out = {}
        for i, d in enumerate(lags):
            part, cols = slice(i * n, (i + 1) * n), cols_by_lag[d]
            out[d] = [found[part, 0][:, cols], found[part, 1][:, cols], found[part, 2][:, cols]]
            if not self._odd:
                continue
            s_d, m_d = s[part], m[part]
            for at in (slice(0, len(ks)), slice(len(ks), n)) if branch else (slice(None),):
                self._odd_steps(rows[at], d, cols, (s_d[at], m_d[at]), [o[at] for o in out[d]])
        return out

    def _uniform(self, ks: np.ndarray, d, three: np.ndarray) -> tuple:
        """Per step (of lag d: one, or one per step): the first node of its stencil, how
        many (at most 3 where `three`, else 4), and the mean, start and end of every column
        from the uniform weights."""
        pc = self.pieces
        if len(pc.starts) == 1:     # one smooth piece
            a, b = pc.starts[0], np.minimum(pc.ends[0], self._told(d))
        else:
            piece = np.searchsorted(pc.starts, ks, side="right") - 1
            a, b = pc.starts[piece], np.minimum(pc.ends[piece], self._told(d))
        m = np.minimum(np.maximum(b - a + 1, 1), np.where(three, 3, 4))
        s = np.minimum(np.maximum(ks - 1, a), b + 1 - m)
        offsets = 5 + self.lag
        key = (m - 1) * offsets + np.minimum(ks - s, offsets - 1)
        first = s + (d - self.lo)       # the stencil's first node's row in the window
        rows = np.minimum(np.maximum(first[:, None] + FOUR, 0), len(self.window) - 1)
        return s, m, weight_table(offsets)[key] @ self.window[rows]   # (steps, 3, columns)

    def _told(self, d) -> int:
        """The last node whose true value the window holds for values late by d rows: n - d,
        or n where the run's end was settled (PairRows.settle_end)."""
        return self.n if self.ended else self.n - d

    @property
    def _odd(self) -> bool:
        """Whether some steps are odd (_odd_steps): a breakpoint inside one, a shorter last
        step."""
        return bool(len(self.across_k)) or abs(self.last - 1.0) > 1e-9

    def _odd_steps(self, ks, d, cols, stencil, out) -> None:
        """The steps the uniform stencils do not fit (where there are some, _odd): a step
        with a breakpoint inside (its mean split between the pieces on either side), and,
        where the last step is shorter, those whose stencil reaches its end (node n is
        nearer than a step)."""
        s, m = stencil
        first, last = int(ks[0]), int(ks[-1])
        # (a step whose right node is past the run's last true value (Jacobi's last d steps)
        # keeps the left piece's polynomial)
        lo, hi = np.searchsorted(self.across_k, [first, min(last, self._told(d) - 1) + 1])
        if hi > lo:
            jump = self.across_jump[lo:hi]
            self._across(self.across_k[lo:hi][jump], self.across_f[lo:hi][jump], first, d,
                         cols, out)
            self._kinked(self.across_k[lo:hi][~jump], self.across_f[lo:hi][~jump], first, d,
                         cols, out)
        if abs(self.last - 1.0) > 1e-9:     # a shorter last step: node n is nearer
            for i in np.flatnonzero((s + m - 1 >= self.n) | (ks == self.n - 1)):
                k = int(ks[i])
                if k in self.pieces.across:
                    continue
                length = self.last if k == self.n - 1 else 1.0
                nodes = tuple(float(j - k) if j < self.n else self.n - 1 - k + self.last
                              for j in range(s[i], s[i] + m[i]))
                known = self.window[np.arange(s[i], s[i] + m[i]) + d - self.lo][:, cols]
                out[0][i] = (means(nodes, [0.0], [length])[0] / length) @ known
                out[1][i], out[2][i] = values(nodes, [0.0, length]) @ known

    def _sides(self, ks: np.ndarray, d: int) -> tuple[np.ndarray, np.ndarray]:
        """For steps with a breakpoint inside: the first node of the piece on their left
        and the last usable node of the one on their right (values late by d rows)."""
        pc = self.pieces
        a = pc.starts[np.searchsorted(pc.starts, ks, side="right") - 1]
        right = np.searchsorted(pc.starts, ks + 1, side="right") - 1
        return a, np.minimum(pc.ends[right], self._told(d))

    def _kinked(self, ks, fs, first: int, d: int, cols, out: list) -> None:
        """Steps with a kink at fraction f inside (the value is continuous there): the mean
        of the two lines from u_k and u_k+1 to the value at the kink, the lines through two
        nodes of each piece extrapolated to it (their mean where both pieces have two; the
        chord where neither has)."""
        if not len(ks):
            return
        a, b = self._sides(ks, d)
        last = len(self.window) - 1
        row = lambda j: self.window[np.clip(j + d - self.lo, 0, last)][:, cols]  # noqa: E731
        u0, u1 = row(ks), row(ks + 1)
        f = fs[:, None]
        left = u0 + (u0 - row(ks - 1)) * f
        right = u1 - (row(ks + 2) - u1) * (1 - f)
        has_left, has_right = (ks - a >= 1)[:, None], (b - ks >= 2)[:, None]
        chord = u0 + (u1 - u0) * f
        kink = np.where(has_left & has_right, 0.5 * (left + right),
                        np.where(has_left, left, np.where(has_right, right, chord)))
        i = ks - first
        out[0][i] = 0.5 * f * (u0 + kink) + 0.5 * (1 - f) * (kink + u1)
        out[1][i], out[2][i] = u0, u1

    def _across(self, ks, fs, first: int, d: int, cols, out: list) -> None:
        """Steps with a jump at fraction f inside: the mean of the left piece's
        polynomial (through its nodes up to k, at most 3) over [0, f] and of the right one's
        (from node k + 1) over [f, 1]; their values at k and k + 1."""
        if not len(ks):
            return
        a, b = self._sides(ks, d)
        m_left = np.clip(ks - a + 1, 1, 3)
        m_right = np.clip(b - ks, 1, 3)
        mean, start, end = out
        for ml, mr in set(zip(m_left.tolist(), m_right.tolist())):
            sel = (m_left == ml) & (m_right == mr)
            k, f, i = ks[sel], fs[sel], ks[sel] - first
            lnodes = tuple(float(j) for j in range(1 - ml, 1))
            rnodes = tuple(float(j) for j in range(1, mr + 1))
            lvals = self.window[k[:, None] + np.arange(1 - ml, 1) + d - self.lo][:, :, cols]
            rvals = self.window[k[:, None] + np.arange(1, mr + 1) + d - self.lo][:, :, cols]
            mean[i] = (np.einsum("sn,snc->sc", means(lnodes, np.zeros_like(f), f), lvals)
                       + np.einsum("sn,snc->sc", means(rnodes, f, np.ones_like(f)), rvals))
            start[i] = lvals[:, -1]
            end[i] = rvals[:, 0]
