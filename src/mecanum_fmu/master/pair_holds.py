"""The held inputs of the embedded pair's steps as the master held them, rebuilt from the run's
rows (PairRows' holds, a mixin as pair_stencils.Stencils is for the true inputs: they read its
window, plan and pieces): per step and input the value the master's hold gave the FMU (Jacobi:
t_k's, late by the lag; zero-order: the newest; trapezoidal and quadratic: the blend of u_k and
u_k+1, less the limited parabola; a loop's inputs extrapolated where the master does not roll
back), its error against the true mean, and the true change over the step."""
from __future__ import annotations

import numpy as np

from .pair_parts import Group
from .probed_model import ProbedModel


class RebuiltHolds:
    """PairRows' held inputs (a mixin)."""

    def _gathered(self, i: int, stencils: dict) -> list:
        """Group i's inputs' (mean, start, end) per step from the stencils of their lags."""
        at = self.at[i]
        if len(at) == 1:
            (d, (_, index)), = at.items()
            return [a[:, index] for a in stencils[d]]
        rows, width = len(stencils[next(iter(at))][0]), len(self.plan.groups[i].cols)
        out = [np.empty((rows, width)) for _ in range(3)]
        for d, (places, index) in at.items():
            for o, a in zip(out, stencils[d]):
                o[:, places] = a[:, index]
        return out

    def _group(self, g: Group, ks: np.ndarray, stencils: list) -> tuple:
        """(held, held - true mean, the true change over the step) per step and input, from
        the true input's (mean, start, end) per step (_stencils)."""
        mean, start, end = stencils
        now = self._row(g, ks, 0)
        if self.plan.hold == "frozen":      # Jacobi: the values of t_k, late by the lag
            return now, now - mean, end - start
        seen = self._row(g, ks, 1)
        if len(self.pieces.cut):        # a step cut at a jump on its end sees the left value
            seen = np.where(self.cut[ks + 1][:, None], end, seen)
        if self.plan.hold == "zoh":         # the newest value: of t_k where a loop closes
            held = np.where(g.roles == "direct", seen, now)
            return held, held - mean, end - start
        trapezoid = 0.5 * (now + seen)
        since = self._since_restart(ks) if self.plan.hold == "quadratic" or g.ahead else None
        if self.plan.hold == "quadratic":
            trapezoid = trapezoid - self._parabola(since, now, seen, self._row(g, ks, -1),
                                                   self._row(g, ks, -2))
        if self.plan.rolled_back:       # the corrector, on the predicted end: the run's
            held = np.where((g.roles == "direct") | (g.roles == "fed_back"), seen, trapezoid)
        else:
            held = np.where(g.roles == "direct", seen, trapezoid)
            if g.ahead:
                held = self._extrapolated(g, ks, now, held, since)
        return held, held - mean, end - start

    def _row(self, g: Group, ks: np.ndarray, shift: int) -> np.ndarray:
        """Group g's input values in the rows `shift` from each step's start."""
        return self.window[np.maximum(ks + shift - self.lo, 0)][:, g.cols]

    def _extrapolated(self, g: Group, ks: np.ndarray, now: np.ndarray, held: np.ndarray,
                      since: np.ndarray | None = None) -> np.ndarray:
        """`held` with a loop's inputs extrapolated from u_k-1 and u_k, as the trapezoidal
        hold (plan.HOLDS) sets them where their end value is not known: the mean over the
        step (1.5 u_k - 0.5 u_k-1; "fed_back": the end value, 2 u_k - u_k-1); after a
        restart (the run's start, a jump), u_k alone. `since`: _since_restart(ks)."""
        since = self._since_restart(ks) if since is None else since
        slope = np.where((since >= 1)[:, None], now - self._row(g, ks, -1), 0.0)
        return np.where(g.roles == "state_ahead", now + 0.5 * slope,
                        np.where(g.roles == "fed_back", now + slope, held))

    @staticmethod
    def _parabola(since, now, seen, before, older) -> np.ndarray:
        """The quadratic master's correction to the trapezoid (plan._Blend): the second
        difference over the step, limited (minmod) by the one before, from the second step
        after a restart (the run's start, a jump) on (`since`: _since_restart's)."""
        a = (seen - now - now + before) * (1 / 12)
        b = (now - before - before + older) * (1 / 12)
        limited = np.minimum(np.maximum(b, np.minimum(a, 0.0)), np.maximum(a, 0.0))
        return np.where((since >= 2)[:, None], limited, 0.0)

    def _since_restart(self, ks: np.ndarray) -> np.ndarray:
        """Per step, the steps since the holds last restarted (the run's start, a cut at a
        jump): the history the master's blends have behind them."""
        if not len(self.pieces.cut):
            return ks
        restarts = np.concatenate(([0], self.pieces.cut))
        return ks - restarts[np.searchsorted(restarts, ks, side="right") - 1]


def lead_of(g: Group, gathered: list, own: np.ndarray) -> tuple | None:
    """Per step and input, what a measured model's direct part errs by less the hold's error
    against the true mean (ProbedModel.steps: held - true end = error - lead): the true end
    value less the mean; for a "through" input, whose end value the outputs see, the hold's
    own error (only an error forwarded from upstream is left). Then the true end less the
    mean alone: a lazy output's (ProbedModel.lazy), which reads the value held during the
    step, "through" or not. Third, the true (start + end) / 2 - mean, which a measured
    model's moments weigh past the change (probe_fit.bend). None for another group: its
    model takes none."""
    if not isinstance(g.model, ProbedModel):
        return None
    mean, start, end = gathered
    late = end - mean
    return np.where(g.roles == "through", own, late), late, 0.5 * (start + end) - mean
