"""The adaptive master's holds (adaptive.py steps with them): over unequal steps, the mean
over the step of the cubic through u_k-2 ... u_k+1 on their own times where the third
differences of this step and the last agree in sign (a smooth input), else the quadratic
master's parabola through u_k-1, u_k, u_k+1, its second difference limited by the one before
(minmod); a loop's inputs predicted by the line through the last two; the held mean's signed
error for the embedded pair (the cubic's next term; a kink's, KINK, where no breakpoint
announces it); the pair's half steps (two-point Gauss on the whole step's polynomial) and end
passes (the mean less and plus half the step's change); and, on graphs with FMUs the
scenario layer knows nothing of, the tally of how smooth the held inputs move
(pair_rough.py)."""
from __future__ import annotations

import math

import numpy as np

from ..scenario.graph import Instance, Port
from .pair_rough import ADAPTIVE_ROUGH, rough_columns
from .plan import Holds

_GAUSS = (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0))   # two-point Gauss, on [0, 1]
# a kink among a held input's values (_VarBlend._kinked): its third difference JUMP times the
# one before or more (a smooth input's change by O(h) of themselves; a bouncing ball's height,
# a parabola between its bounces, by orders of magnitude), and its held mean's estimated error
# KINK of its change over this step and the one before or more (the ball's 4e-3 to 1.2e-2; a
# smooth input's cubic errs by about 0.013 h^3 u4 / u' of it): the hold's polynomial may be
# far from the input, and the step is taken once more without that error (_Loop._attempt)
KINK = 1e-3
JUMP = 8.0


def _minmod(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.where(a * b > 0, np.sign(a) * np.minimum(np.abs(a), np.abs(b)), 0.0)


class AdaptiveHolds(Holds):
    """Holds over unequal steps: h (this step), g and f (the two before). `hold`: the
    registry's (masters.py) for the adaptive master, whose fixed weights the blends replace;
    `models`: Graph.error_models (per instance name, a factory of an error model for its
    held inputs). A "through" input (plan._blend_roles) is held as a "state" one, and set to
    its end value after the doStep."""
    through = True

    def __init__(self, hold: str, models: tuple = (), check: bool = False):
        super().__init__(hold)
        self.h = self.g = self.f = 1.0
        self.models = dict(models)
        # whether the held inputs are checked for smooth curves (pair_rough.py): the graph
        # holds FMUs the scenario layer knows nothing of (Graph.measured)
        self.check = check
        self.clients: list = []     # the error models handed a blend
        self.paired: list["_VarBlend"] = []   # the blends no model takes: the embedded pair's
        self.half = None        # the pair's half steps: which half is being taken (0, 1)
        # the pair's end passes (_Loop._ends): each held input at its mean less (0) or plus
        # (1) half its change over the step
        self.point = None
        # the share of each held mean's estimated error (_VarBlend.next) added to it: -1 in
        # the pass that takes the step without it (_Loop._attempt), the divisor in the
        # whole-step trajectory's (trajectory.py: its difference over the divisor then
        # carries that error through the dynamics), else 0
        self.kinks = 0.0
        self.since = None       # committed steps since the last breakpoint (None: none yet)
        # the next step ends on a jump (it started JUMP before it): until a step lands on a
        # stop (at_breakpoint), a rejected jump step cut in pieces ends on it in the last
        self.jump_next = False

    @property
    def history(self) -> int:
        """The committed steps whose values the holds may use: none from before the last
        breakpoint (a table's corner or jump), where the input is another polynomial."""
        return self.steps if self.since is None else min(self.steps, self.since)

    def not_smooth(self, n: int) -> list[str]:
        """The FMUs whose held inputs did not move as smooth curves over the run's n accepted
        steps (_VarBlend.tally)."""
        return sorted({b.owner for b in self.blends if len(rough_columns(
            b.sums[:2], b.sums[2], n, ADAPTIVE_ROUGH))})

    @property
    def richardson(self) -> float:
        """2^p - 1, p the order of the error the halves keep: (whole - halves) over it is
        theirs. 3 (the holds are second order); 1 where some FMU's inputs are held at their
        end values (held_at_end: first order)."""
        return 1.0 if self.held_at_end else 3.0

    def moved(self, share: float = 0.0) -> set[str]:
        """The FMUs whose inputs the pair holds and one of which moved over this step (by
        more than `share` of its size)."""
        return {b.owner for b in self.paired if (~(b.fed | b.end) & (np.abs(
            b.rows[0] - b.rows[1]) > share * np.maximum(np.abs(b.rows[0]), np.abs(b.rows[1])))
                                                  ).any()}

    def kinked(self) -> bool:
        """Whether a kink sits among the values of one of the pair's blends this step
        (_VarBlend._kinked)."""
        return any(b.next.any() for b in self.paired)

    def at_breakpoint(self, before_jump: bool) -> None:
        self.since, self.jump_next = 0, before_jump

    def add(self, buffer, src, roles, targets: list[Port], inst: Instance) -> "_VarBlend":
        blend = _VarBlend(self, buffer, src, roles)
        blend.owner = inst.name
        self.blends.append(blend)
        self.ahead = self.ahead or any(role not in ("state", "through", "end")
                                       for role in roles)
        model = self.models.get(inst.name)
        client = (model.stepwise(blend, [t.ref.variable for t in targets], inst) if model
                  else None)
        (self.paired if client is None else self.clients).append(blend if client is None
                                                                 else client)
        return blend

    def prime(self) -> None:
        super().prime()
        for b in self.blends:
            b.third_before[:] = 0.0

    def commit(self) -> None:
        if self.check and self.history >= 4 and not self.jump_next:
            for b in self.blends:
                b.tally()
        for b in self.blends:
            b.third_before[:] = b.third
        super().commit()
        self.f, self.g = self.g, self.h
        if self.since is not None:
            self.since += 1


class _VarBlend:
    """One group of blended inputs: history [now | u_k | u_k-1 | u_k-2] and its roles."""

    def __init__(self, holds: AdaptiveHolds, buffer: np.ndarray, src: np.ndarray, roles: list):
        m = len(src)
        self.holds, self.buffer, self.src = holds, buffer, src
        self.staging = np.zeros(m)
        self.history = np.zeros(4 * m)
        self.rows = self.history.reshape(4, m)          # views: now, u_k, u_k-1, u_k-2
        self.older, self.old = self.history[2 * m:], self.history[m:3 * m]
        roles = np.array(roles)
        self.ahead, self.fed = roles == "state_ahead", roles == "fed_back"
        self.end = roles == "end"       # held at the newest value, whole step and halves
        self.third = np.zeros(m)          # u''' over this step (limited in error())
        self.third_before = np.zeros(m)
        # the held polynomial's terms beyond the line through u_k, u_k+1 (fill): a s (s - h)
        # (the limited parabola's or the cubic's) and b s (s - h) (s + g) (the cubic's)
        self.a, self.b = np.zeros(m), np.zeros(m)
        # the held mean's signed error (held - true) where a kink sits among its values
        # (_kinked: against a V), else 0; _Loop._attempt takes the step once more without it
        self.next = np.zeros(m)
        self.shift = None   # added to the values now (the whole-step trajectory's, trajectory.py)
        self.owner = ""     # the FMU whose inputs these are
        # per input: sum h^4 |u4| (its fourth derivative), sum |the step's change|, the
        # largest |u| (tally)
        self.sums = np.zeros((3, m))

    def tally(self) -> None:
        """Add the accepted step's fourth difference and change (pair_rough.py's rule on
        unequal steps: u4 from this step's third difference and the one before, times the
        fourth power of the mean of the last three steps: steps that shrink around a jump
        they cross would make the step's own h^4 small enough to hide it)."""
        now, u = self.rows[0], self.rows[1]
        h, g, f = self.holds.h, self.holds.g, self.holds.f
        mean = (h + g + f) / 3
        self.sums[0] += mean ** 4 * np.abs(2 * (self.third - self.third_before) / (h + f))
        self.sums[1] += np.abs(now - u)
        np.maximum(self.sums[2], np.abs(now), out=self.sums[2])

    def fill(self) -> None:
        hs = self.holds
        if hs.half is not None:
            self._fill_half(hs.half)
            return
        np.take(self.buffer, self.src, out=self.rows[0])
        if self.shift is not None:
            self.rows[0] += self.shift
        now, u, u1, _ = self.rows
        h, g = hs.h, hs.g
        mean = 0.5 * (now + u)
        # the held polynomial, u + (now - u) s/h + a s (s - h) + b s (s - h) (s + g) on the
        # step's s in [0, h]: its mean is the trapezoid minus a h^2/6 + b h^2 (h + 2 g)/12
        self.a[:], self.b[:], self.next[:] = 0.0, 0.0, 0.0
        if hs.history >= 2:
            # the parabola's correction to the trapezoid, its second difference limited
            second = self._second()
            limited = _minmod(second, 2 * self._second_before())
            correction = limited * h * h / 12
            self.a[:] = limited / 2
            if hs.history >= 3:     # the cubic's where the third differences agree in sign
                third = self._third()
                cubic = second * h * h / 12 + third * h * h * (h + 2 * g) / 72
                smooth = third * self.third_before > 0
                correction = np.where(smooth, cubic, correction)
                self.a[:] = np.where(smooth, second / 2, self.a)
                self.b[:] = np.where(smooth, third / 6, 0.0)
                if hs.check:    # (the bundled FMUs announce their kinks: breakpoints)
                    self._kinked(second - limited, third, smooth, correction)
            mean = mean - correction
            if hs.kinks:        # (the kink passes alone: adaptive._Loop, trajectory.py)
                mean = mean + hs.kinks * self.next
        if hs.mode == hs.PREDICT:
            # no slope from before a breakpoint: across a jump's own step (1e-7 s) it is the
            # jump over that step, and a loop's predictor fed it on (the recorded path's
            # heading: 2.5e-3 rad in one step after a row)
            slope = (u - u1) / g if hs.history >= 1 else 0.0
            self.staging[:] = np.where(self.ahead, u + slope * h / 2,
                                       np.where(self.fed, u + slope * h,
                                                np.where(self.end, now, mean)))
        else:
            self.staging[:] = np.where(self.fed | self.end, now, mean)
        if hs.point is not None:    # the mean -+ half the step's change (_Loop._ends)
            self.staging += np.where(self.fed | self.end, 0.0, (hs.point - 0.5) * (now - u))

    def _kinked(self, dropped: np.ndarray, third: np.ndarray, smooth: np.ndarray,
                correction: np.ndarray) -> None:
        """self.next: per input, the held mean's signed error where a kink sits among its
        values, else 0. A kink: the third difference JUMP x the one before or more, and the
        polynomial's own error estimate (the cubic's next term, 19/720 h^4 u4, or what the
        limited parabola dropped of the full one's correction: `dropped`, the second
        differences' difference) KINK of the change over this step and the last or more.
        Its error: against a V, the line of the step before on to mid-step, then to the
        step's end value (the polynomial's own estimate read a ball's bounce 4x to 35x under:
        the samples do not show how deep the V goes): held - V = (the secant's slope - the
        slope before) h / 4 - `correction` (what the hold took off the trapezoid)."""
        hs, (now, u, u1, _) = self.holds, self.rows
        own = np.where(smooth, self._cubic_next(third), dropped * hs.h * hs.h / 12)
        kinked = (np.abs(third) >= JUMP * np.abs(self.third_before)) & (
            np.abs(own) > KINK * (np.abs(now - u) + np.abs(u - u1)))
        bend = ((now - u) / hs.h - (u - u1) / hs.g) * hs.h / 4
        self.next[:] = np.where(kinked, bend - correction, 0.0)

    def polynomial(self, kept: tuple | None = None) -> tuple:
        """The held polynomial of this step (its end values and terms, which the halves
        hold: _fill_half), a copy; with `kept`, that one set back."""
        if kept is not None:
            for mine, value in zip((self.rows[0], self.a, self.b, self.next), kept):
                mine[:] = value
        return tuple(v.copy() for v in (self.rows[0], self.a, self.b, self.next))

    @property
    def exact(self) -> bool:
        """Whether this step's error (error()) is exact: a jump's own step, h (new - old) / 2
        (an error model leaves it out of the terms it tests for cancellation)."""
        return self.holds.jump_next

    def _fill_half(self, which: int) -> None:
        """The pair's half steps: the mean over half `which` of the step of the polynomial the
        whole step held (two-point Gauss, exact for a cubic; u_k+1 as the whole step saw it);
        a fed-back input takes its value now."""
        now, u = self.rows[0], self.rows[1]
        h, g = self.holds.h, self.holds.g
        mean = np.zeros_like(now)
        for node in _GAUSS:
            s = (which + node) * h / 2
            mean += 0.5 * (u + (now - u) * s / h + self.a * s * (s - h)
                           + self.b * s * (s - h) * (s + g))
        self.staging[:] = np.where(self.fed | self.end, self.buffer[self.src], mean)

    def _second(self) -> np.ndarray:
        """u'', 2x the second divided difference over u_k-1, u_k, u_k+1."""
        now, u, u1, _ = self.rows
        h, g = self.holds.h, self.holds.g
        return 2 * ((now - u) / h + (u1 - u) / g) / (h + g)

    def _second_before(self) -> np.ndarray:
        """The second divided difference over u_k-2, u_k-1, u_k."""
        _, u, u1, u2 = self.rows
        g, f = self.holds.g, self.holds.f
        return ((u - u1) / g - (u1 - u2) / f) / (g + f)

    def _third(self) -> np.ndarray:
        """u''', 6x the third divided difference over u_k-2 ... u_k+1."""
        h, g, f = self.holds.h, self.holds.g, self.holds.f
        return 6 * (0.5 * self._second() - self._second_before()) / (h + g + f)

    def error(self) -> tuple[np.ndarray, np.ndarray]:
        """The signed error of this step's held mean (held - true), per input, (for the
        controller, for the estimate): where the hold is the cubic (the third differences
        agree in sign), its next term 19/720 h^4 u4 (uniform steps' form: the cubic through
        four points, its mean over the last interval; u4 the change of the third difference)
        for both; on the first steps none for the controller (they are short) and the
        trapezoids' for the estimate; where a kink no breakpoint announces sits among them,
        its error against a V (_kinked); elsewhere (the limited parabola where a kink or a
        jump sits among the last four values, or u3 crosses zero) nothing."""
        hs = self.holds
        self.third[:] = self._third()
        if hs.jump_next:       # held - true = (new - old) / 2 on the mean: the jump's own
            now, u, _, _ = self.rows   # step, for both (a huge jump gets a shorter step)
            return 0.5 * (now - u), 0.5 * (now - u)
        if hs.history < 3:     # no history yet: the step is kept short instead (first_step)
            return np.zeros_like(self.third), self._start_up()
        smooth = self.third * self.third_before > 0
        signed = np.where(smooth, self._cubic_next(self.third), 0.0)
        if hs.check:    # a kink's (_kinked: searched on such graphs alone)
            signed = np.where(self.next != 0.0, self.next, signed)
        return signed, signed

    def _cubic_next(self, third: np.ndarray) -> np.ndarray:
        """The cubic's next term, 19/720 h^4 u4, u4 from this step's third difference and the
        one before."""
        h = self.holds.h
        return 19 / 720 * h ** 4 * (2 * (third - self.third_before) / (h + self.holds.f))

    def _start_up(self) -> np.ndarray:
        """The signed error of the first two steps' held means, told at the second step (the
        first with a second difference): each a trapezoid, held - true = h^2 u'' / 12, the
        first step's (g long) carried on this step's mean as g^3 / h u'' / 12."""
        if self.holds.steps != 1:
            return np.zeros_like(self.third)
        h, g = self.holds.h, self.holds.g
        return self._second() * (h * h + g ** 3 / h) / 12

    def commit(self) -> None:
        self.older[:] = self.old
        np.take(self.buffer, self.src, out=self.rows[1])
