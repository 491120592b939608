"""The embedded pair stepped over the run's rows (pair.py makes the plan, of pair_parts.py's
parts): the recorder's tap.

Every chunk of rows the recorder flushes passes through PairRows, which keeps the columns the
plan needs and works out each step's errors as soon as the values its stencil reads are in:
the rows of a window a few steps long, so that memory stays flat for any run length: the
true inputs from their stencils (pair_stencils.py), the held ones as the master held them
(pair_holds.py), the errors carried into the outputs by the groups' models. The cost is a
few NumPy operations per chunk of 4096 rows, not per step; around a loop (pair_loop.py) a
few more, log2 of the chunk's steps of them.
"""
from __future__ import annotations

import copy
import functools
import time as _time

import numpy as np

from ..results import cancelled, round_off
from .breakpoints import pieces
from .pair_parts import Group, PairPlan
from .pair_known import KnownInputs
from .pair_loop import LoopCarry
from .pair_network import NetworkCarry
from .pair_rough import ROUGH, Roughness
from .probe import ProbedResponse
from .probed_model import ProbedModel
from .pair_holds import RebuiltHolds, lead_of
from .pair_stencils import Stencils, with_branch
from .stencils import values

# a carried error over this share of the value an output divides by: its linearisation fails
ILL = 0.1
CANCELLED = cancelled(", finer than the linearisation resolves")
# a divisor that comes within this share of its largest |value| of 0: 1 / its square magnifies
# one row's error (the ICR's max on a path whose w crosses 0 read 7x over)
NEAR_ZERO = 0.01
NOT_SMOOTH = (f" do not move as smooth curves between the rows (their fourth differences "
              f"over {ROUGH:g}x their first: a staircase on an FMU's own grid, or faster than "
              "the step), which the pair's cubic does not follow")
# under Jacobi, a bulk of steps before the tail up to this long is worked out with it, twice
# (one pass fewer: a pass's fixed NumPy calls cost more than these steps' share)
BULK = 256



def _columns(plan: PairPlan) -> tuple[dict, list, list]:
    """Per lag, the columns whose true values the stencils rebuild once per batch (the held
    inputs', the late outputs'); where each group's are among them (per lag: the inputs'
    places in the group, their columns' places in that lag's); and Jacobi's late outputs by
    lag: (lag, names, where their columns are among that lag's)."""
    cols: dict[int, list] = {}
    for g in plan.groups:
        for c, d in zip(g.cols, g.lags.tolist()):
            if c not in cols.setdefault(d, []):
                cols[d].append(c)
    for _, c, d in plan.lagged:
        if c not in cols.setdefault(d, []):
            cols[d].append(c)
    at = []
    for g in plan.groups:
        places: dict[int, list] = {}        # per lag: (the input's place, its column's)
        for i, (c, d) in enumerate(zip(g.cols.tolist(), g.lags.tolist())):
            places.setdefault(d, []).append((i, cols[d].index(c)))
        at.append({d: (np.array([i for i, _ in p], dtype=np.intp), np.array([j for _, j in p]))
                   for d, p in places.items()})
    by_lag: dict[int, list] = {}
    for name, col, d in plan.lagged:
        by_lag.setdefault(d, []).append((name, cols[d].index(col)))
    lags = [(d, [n for n, _ in pairs], np.array([c for _, c in pairs]))
            for d, pairs in by_lag.items()]
    return {d: np.array(c, dtype=np.intp) for d, c in cols.items()}, at, lags


@functools.lru_cache(maxsize=None)
def _gap(d: int) -> np.ndarray:
    """The weights of the nodes n-d-2, n-d-1, n-d and n for the nodes between (n-d+1 ..
    n-1): the cubic through them (PairRows.settle_end)."""
    return values((-d - 2.0, -d - 1.0, -float(d), 0.0), np.arange(1 - d, 0, dtype=float))


class PairRows(Stencils, RebuiltHolds):
    """The pair over the rows of one run of n steps (Recorder.tap, then finish())."""

    def __init__(self, plan: PairPlan, exp, n_steps: int, breaks, known=()):
        self.plan, self.n, self.h = plan, n_steps, exp.step_size
        self.last = (exp.stop_time - exp.start_time) / exp.step_size - (n_steps - 1)
        self.pieces = pieces(breaks, exp.start_time, exp.step_size, n_steps)
        # where the pieces are too short for the run's rows, the tables tell the inputs
        self.known = KnownInputs(known, exp, n_steps, self.last) if self.pieces.short \
            else None
        self.across_k = np.array(sorted(self.pieces.across), dtype=np.int64)
        self.across_f = np.array([self.pieces.across[k][0] for k in self.across_k])
        self.across_jump = np.array([self.pieces.across[k][1] for k in self.across_k], dtype=bool)
        self.window = np.empty((0, len(plan.slots)))
        self.lo, self.k = 0, 0      # the row window[0] holds; the next step to work out
        self.lag = max([g.lag for g in plan.groups] + [d for _, _, d in plan.lagged],
                       default=0)
        self.reach = 4 + self.lag       # the rows past a step its stencils read
        self.cols, self.at, self.lags = _columns(plan)
        self.roughness = Roughness(self.cols, self.pieces.starts, self.pieces.ends, n_steps,
                                   len(plan.slots)) \
            if plan.unknown else None
        self.needed, self.late_names, self.late_cols = self._held_and_late()
        loop, net = plan.loop, plan.network
        self.carry = LoopCarry(loop, plan.groups[loop.origin], plan.hold == "frozen") \
            if loop is not None else None
        self.net = NetworkCarry(net, plan.groups, n_steps, plan.hold == "frozen") \
            if net is not None else None
        # Jacobi's late outputs of the loop's chain: their lag's error and the carried one
        self.late = {name: c for name, c, _ in plan.lagged} if loop is not None else {}
        self.late_chain = self._late_in_chain(loop)
        # the chain's recorded outputs that are not late: their names and columns
        early = [(n, c) for n, c in (loop.recorded if loop else ()) if n not in self.late]
        self.chain_recorded = ([n for n, _ in early], [c for _, c in early])
        self.worst = {name: 0.0 for name in (*plan.covered, *(n for n, _, _ in plan.lagged),
                                             *(n for n, _ in (loop.recorded if loop else ())),
                                             *(n for n, _ in (net.recorded if net else ())))}
        self.end = dict.fromkeys(self.worst, 0.0)
        self.moved = [np.zeros(len(g.cols)) for g in plan.groups]
        self.size = np.zeros(len(plan.slots))
        self.seconds = 0.0
        self.probe_calls = 0    # the doStep calls of the probes before the run (memory.py)
        self.tail = n_steps     # from this step on, the stencils' nodes are 3 (else 4)
        self.ended = False      # the late outputs' nodes up to n in the window (settle_end)
        self.branch_end: dict[str, float] = {}      # Jacobi's end with the parabola
        # the nodes a step ends on a jump at (the master cuts it: it sees the left value)
        self.cut = np.zeros(n_steps + 2, dtype=bool)
        self.cut[self.pieces.cut] = True
        # per group, the outputs its model covers and their columns in its signed errors
        self.covers = [([n for n, (j, _) in plan.covered.items() if j == i],
                        [k for n, (j, k) in plan.covered.items() if j == i])
                       for i in range(len(plan.groups))]
        # the models' outputs other FMUs read: their largest |error|
        self.fed = {name: 0.0 for name, *_ in (*plan.fed, *(loop.checked if loop else ()),
                                                *(net.checked if net else ()))}
        # per group whose outputs' error is forwarded (PairPlan.forwarded): its signed
        # errors of the last batch, and of the row before it
        self.sent: dict[int, np.ndarray] = {}
        self.sent_before = {i: np.zeros(len(plan.groups[i].model.outputs))
                            for i, *_ in plan.forwarded}
        self.ill: dict[str, str] = {}      # the chain's outputs whose linearisation fails
        self.divisors: dict[str, tuple] = {}    # their divisors' smallest and largest |value|
        self.failed: str | None = None

    def _held_and_late(self) -> tuple[dict, list, np.ndarray]:
        """Per lag, which of its columns the groups hold (not only Jacobi's late outputs);
        Jacobi's late outputs, every lag's side by side: their names and window columns."""
        none = np.array([], dtype=np.intp)
        needed = {d: np.zeros(len(c), dtype=bool) for d, c in self.cols.items()}
        for at in self.at:
            for d, (_, places) in at.items():
                needed[d][places] = True
        return needed, [n for _, names, _ in self.lags for n in names], np.concatenate(
            [self.cols[d][at] for d, _, at in self.lags] or [none])

    def _late_in_chain(self, loop) -> tuple[list, list]:
        """Those of Jacobi's late outputs in the loop's chain: their places among late_names,
        their columns."""
        chain = {name for name, _ in loop.recorded} if loop is not None else set()
        return ([i for i, n in enumerate(self.late_names) if n in chain],
                [self.late[n] for n in self.late_names if n in chain])

    @property
    def may_fail(self) -> bool:
        """Whether the pair may find, after the run, that it does not hold (an FMU with a
        state and no error model, a model's output that another FMU reads): the run then
        keeps its t0 for Richardson's coarser runs."""
        return bool(self.plan.fed or (self.plan.loop and self.plan.loop.checked) or (
            self.plan.network and self.plan.network.checked) or self.known) or any(
            g.model is None or isinstance(g.model, ProbedModel) for g in self.plan.groups)

    @property
    def held_move(self) -> bool:
        """Whether a held input may move between two jumps of a table (a loop, an FMU with a
        state): estimate.LONE_PIECES."""
        return self.may_fail or self.plan.loop is not None or self.plan.network is not None

    def __call__(self, rows: np.ndarray, first: int) -> None:
        """A chunk of whole buffer rows, the first being row `first` of the run."""
        if self.failed:         # the pair does not hold: Richardson estimates
            return
        tick = _time.perf_counter()
        new = rows[:, self.plan.slots]
        self.window = np.concatenate((self.window, new))
        np.maximum(self.size, np.abs(new, out=new).max(axis=0, initial=0.0), out=self.size)
        if self.roughness is not None:
            self.roughness.tally(self.window, self.lo, first, len(rows))
        if first + len(rows) <= self.n:     # not the last chunk (finish works that out)
            self._steps(min(self.n - 1, self.lo + len(self.window) - 1 - self.reach))
        self.seconds += _time.perf_counter() - tick

    @property
    def wants_end(self) -> bool:
        """Whether the run's settled end would tell late outputs' nodes (settle_end): under
        Jacobi, where the rows do not already tell everything (the tables, a still run), on
        a chain, not around a loop or a network. Row j + d stands for node j, while an FMU
        whose output moves with time by itself made that row at t_j+1: its value settled
        at t_n is no row's, and the cubic through both goes astray. Around the loops that
        FMU is the PathFollower (the figure eight's ends at 2x and 4x came out 3.8x and 12x
        off); on the bundled chains only sources move with time, and they are not late (a
        third-party FMU in a chain that did would be read so too)."""
        return bool(self.lag) and not self.failed and self.known is None \
            and self.carry is None and self.net is None and not self._still()

    def settle_end(self, real: np.ndarray) -> None:
        """Under Jacobi, the pair's columns after the run with every FMU set its sources'
        newest values (stepping.settled_end): a late column's value there is its true value
        at node n, which its rows would show d rows later. Its nodes between (a lag over 1)
        are the cubic through that and the three before. The window gets them as rows past
        n, and the stencils read the late columns up to node n instead of extrapolating past
        node n - d. Left alone where a breakpoint falls among those nodes, a value is not
        finite, or the read looks stale (_stale)."""
        start = max(0, self.n - self.lag - 3)
        if not self.wants_end or self.lo > start or self.pieces.starts[-1] > start \
                or (self.across_k >= start).any() or not np.isfinite(real).all() \
                or self._stale(real):
            return
        extra = np.repeat(self.window[-1:], self.lag, axis=0)
        rows = self.window[self.n - 2 - self.lo:self.n + 1 - self.lo]   # nodes n-d-2 .. n-d
        for d, cols in self.cols.items():
            if d:
                extra[d - 1, cols] = real[cols]
                if d > 1:
                    extra[:d - 1, cols] = _gap(d) @ np.vstack((rows[:, cols], real[cols]))
        self.window = np.concatenate((self.window, extra))
        self.ended = True

    def _stale(self, real: np.ndarray) -> bool:
        """Whether a late column moved on the last step but its read is its last row to the
        bit: an FMU that works its output out in its doStep only (against FMI 2.0: an input
        set after the step does not move it), whose read would pass the row for node n."""
        now, before = self.window[self.n - self.lo], self.window[self.n - 1 - self.lo]
        return any(((real[c] == now[c]) & (now[c] != before[c])).any()
                   for d, c in self.cols.items() if d)

    def finish(self) -> dict:
        """results.extra["pair"]: per output the largest |error| and the end's, the seconds
        it took, and why the estimate falls back to Richardson (None: it does not). Under
        Jacobi the last steps' true inputs lie past the run's values (node j is row j + d):
        read after the run on a chain (settle_end), else extrapolated, the end worked out
        with the cubic and with the parabola there (the estimate's third value per output;
        estimate.py words an end the two do not agree on within half of it as
        unresolved). "rough": held inputs that do not move as smooth curves, or a measured
        response that a probe's move did not move (an input that saturates or is quantized):
        jumps or kinks the master does not know of (richardson.FINER_ROUGH)."""
        tick = _time.perf_counter()
        parabola = self._rest()
        self.seconds += _time.perf_counter() - tick
        not_smooth = self._rough()
        rough = self._not_smooth(not_smooth)
        deaf = any(m.deaf for m in self._measured())
        return {"estimate": {n: (self.worst[n], self.end[n], parabola[n]) for n in self.worst},
                "unresolved": self._ill(not_smooth),
                "unresolved_end": dict.fromkeys(self.net.cancelled(self.end), CANCELLED)
                if self.net is not None else {},
                "seconds": self.seconds,
                "probe_calls": self.probe_calls,
                "failed": self.failed or self._moved() or self._probe_failed() or rough,
                "rough": rough is not None or deaf,
                "lagged": bool(self.lag),
                "tables": self.known is not None,
                "models": [f"{g.name}: {g.model_name}" for g in self.plan.groups
                           if g.model is not None],
                "through": self._through()}

    def _rest(self) -> dict:
        """Work out the steps left; the end's second value per output (Jacobi's with the
        parabola on the last steps, else the end itself)."""
        if self._still():
            self.k = self.n     # every error is 0: nothing to work out
        if self.failed or self.k >= self.n:
            return self.end
        if not self.lag or (self.known and self.known.told()) or self.ended:
            self._steps(self.n - 1)     # (a settled end: nothing extrapolated past the rows)
            return self.end
        if self._branchable:    # the parabola's steps a branch of the same pass
            self._steps(self.n - 1, branch=min(self.reach + 1, self.n - self.k))
            return {**self.end, **self.branch_end}
        if self.n - 1 - self.reach - self.k > BULK:
            self._steps(self.n - 2 - self.reach)    # a long bulk once, before the tail
        # what is left twice: the cubic, then the parabola on the tail's steps
        before = self._state()
        self._steps(self.n - 1)
        after = self._state()
        self._restore(before)
        self.tail = self.n - 1 - self.reach
        self._steps(self.n - 1)
        parabola = dict(self.end)
        self._restore(after)
        self.tail = self.n
        return parabola

    def _through(self) -> list[str]:
        """The FMUs without a state the error is carried through (a loop's chain, a network's
        FMUs between its models), for the method's words."""
        return [t.name + (" (measured)" if isinstance(t.response, ProbedResponse) else "")
                for t in self.plan.throughs()]

    def _ill(self, not_smooth: np.ndarray) -> dict[str, str]:
        """The chain's outputs whose estimate is unresolved: their divisor's error is not
        small against it on some row, or it comes near 0 (within NEAR_ZERO of its largest
        |value|), where 1 / its square magnifies the error of one row; Jacobi's late outputs
        among the columns `not_smooth` (_rough)."""
        ill = {**self.plan.unresolved, **self.ill}
        rough = set(not_smooth.tolist())
        for name, c, _ in self.plan.lagged:     # Jacobi's late outputs
            if c in rough:
                ill.setdefault(name, f"unresolved (its values{NOT_SMOOTH})")
        for name in self.net.cancelled(self.worst) if self.net is not None else ():
            ill[name] = CANCELLED
        for name, (low, high) in self.divisors.items():
            if name not in ill and low < NEAR_ZERO * high:
                divisor = next(d for n, d, *_ in self.plan.loop.divided if n == name)
                ill[name] = (f"unresolved (it divides by {divisor}, which comes within "
                             f"{NEAR_ZERO:g} of its largest value of 0)")
        return ill

    def _state(self) -> tuple:
        """What the tail changes (the models' running totals are replaced, not changed in
        place: a shallow copy keeps them; the window is sliced, never written)."""
        return ([copy.copy(g.model) for g in self.plan.groups], dict(self.worst),
                dict(self.end), self.k, self.lo, self.window, [m.copy() for m in self.moved],
                dict(self.fed), copy.copy(self.carry), self.net and self.net.copy(),
                dict(self.sent_before))

    def _restore(self, state: tuple) -> None:
        models, worst, end, self.k, self.lo, self.window, moved, fed, carry, net, sent = state
        self.sent_before = dict(sent)
        self.carry, self.net = copy.copy(carry), net and net.copy()
        for g, model in zip(self.plan.groups, models):
            g.model = copy.copy(model)
        self.worst, self.end, self.moved = dict(worst), dict(end), [m.copy() for m in moved]
        self.fed = dict(fed)

    def _moved(self) -> str | None:
        """Why the pair does not hold: an FMU with a state and no error model whose held
        inputs moved within the steps (beyond their round-off)."""
        for g, moved in zip(self.plan.groups, self.moved):
            if g.model is not None:
                continue
            floor = np.array([round_off([size], self.n) for size in self.size[g.cols]])
            if (moved > floor).any():
                return (f"{g.name} has a state and no error model, and its held inputs move "
                        "within the steps")
        return None

    def _rough(self) -> np.ndarray:
        """The columns whose values are not smooth curves at this step (pair_rough.py)."""
        return self.roughness.rough(self.size, self.n) if self.roughness is not None else \
            np.zeros(0, dtype=np.intp)

    def _not_smooth(self, rough: np.ndarray) -> str | None:
        """Why the pair does not hold: held inputs among the columns that are not smooth
        curves at this step (`rough`: _rough)."""
        held = [g.name for g in self.plan.groups if np.isin(g.cols, rough).any()] \
            if len(rough) else []
        return f"the held inputs of {', '.join(held)}{NOT_SMOOTH}" if held else None

    def _probe_failed(self) -> str | None:
        """Why the pair does not hold: a measured response (probe.py) that could not be
        measured."""
        for m in self._measured():
            if m.failed or not m.found:
                return m.failed or (f"{m.name}'s response is measured, and the run is too "
                                    "short to probe it")
        return None

    def _measured(self) -> list:
        """The measured responses (probe.py): the groups' models and the throughs'."""
        return [g.model for g in self.plan.groups if isinstance(g.model, ProbedModel)] + [
            t.response for t in self.plan.throughs() if isinstance(t.response, ProbedResponse)]

    def _fed_error(self) -> str | None:
        """Why the pair does not hold: a model's output that another FMU reads carries an
        error (beyond its round-off), which the pair would have to carry through that FMU."""
        checked = [*(self.plan.loop.checked if self.plan.loop else ()),
                   *(self.plan.network.checked if self.plan.network else ())]
        for name, c, readers in [(f[0], f[3], f[4]) for f in self.plan.fed] + checked:
            if self.fed[name] > round_off([self.size[c]], self.n):
                return (f"{name} carries an error into {', '.join(readers)}; the pair "
                        "carries an error only through FMUs without a state whose response "
                        "it knows")
        return None

    def _forwarded_into(self, j: int, error: np.ndarray) -> np.ndarray:
        """Group j's held inputs' errors with the errors its sources' models forward into
        them (PairPlan.forwarded): per step, the source's error at the step's start (Jacobi:
        the value it holds) or its mean over the step (the other masters'), read off the
        source's signed errors after each step."""
        mine = [(i, index, places) for i, index, jj, places in self.plan.forwarded if jj == j]
        if not mine:
            return error
        error = error.copy()
        for i, index, places in mine:
            after = self.sent[i][:, index]
            before = np.concatenate(([self.sent_before[i][index]], after[:-1]))
            value = before if self.plan.hold == "frozen" else 0.5 * (before + after)
            error[:, places] += value[:, None]
        return error

    def _check_fed(self, i: int, signed: np.ndarray) -> None:
        """Keep the largest |error| of group i's outputs that other FMUs read."""
        for name, j, index, *_ in self.plan.fed:
            if j == i and len(signed):
                self.fed[name] = max(self.fed[name], float(np.max(np.abs(signed[:, index]))))

    def _carried(self, g: Group, ks: np.ndarray, h: np.ndarray, hold: tuple, branch: int = 0
                 ) -> np.ndarray:
        """Group g's signed errors with the loop's carried in (pair_loop.py); the chain's
        recorded outputs' (but Jacobi's late ones: _steps) and the checked values' errors
        kept; with a `branch` (_steps; h and hold with its rows), its end apart."""
        predicted = self._extrapolated(g, ks, self._row(g, ks, 0), hold[0]) \
            if self.plan.rolled_back else None
        signed = self.carry.steps(g, h, hold, with_branch(ks, branch), self._rows, predicted,
                                  branch)
        names, cols = self.chain_recorded
        if names:
            self._keep(names, self.carry.carried(cols, ks + 1))
            if branch:
                ends = self.carry.carried(cols, ks[-1:] + 1, branch=True)
                self.branch_end.update(zip(names, np.abs(ends[0]).tolist()))
        self._divisors(ks, branch)
        checked = self.plan.loop.checked
        if checked:
            worst = np.max(np.abs(self.carry.carried([c for _, c, _ in checked], ks + 1)),
                           axis=0)
            for (name, _, _), w in zip(checked, worst.tolist()):
                self.fed[name] = max(self.fed[name], w)
        return signed

    def _divisors(self, ks: np.ndarray, branch: int) -> None:
        """Check the chain's divisors on the nodes after steps `ks` (and the branch's): an
        error not small against the divisor marks its output ill; keep their |values|."""
        divided = self.plan.loop.divided
        if not divided:
            return
        cols = sorted({c for _, _, c, _ in divided})     # the ICR's x and y divide by one w
        errors = self.carry.carried(cols, ks + 1)
        if branch:
            errors = np.concatenate((errors, self.carry.carried(
                cols, ks[len(ks) - branch:] + 1, branch=True)))
        errors = np.abs(errors)
        values = np.abs(self.window[(with_branch(ks, branch) + 1 - self.lo)[:, None], cols])
        # per divisor's column and floor: whether its error is not small against it on some
        # node, its smallest |value| where it divides, its largest
        found = {}
        for c, floor in {(c, floor) for _, _, c, floor in divided}:
            error, value = errors[:, cols.index(c)], values[:, cols.index(c)]
            near = (value + error >= floor)
            found[c, floor] = (bool(((error > ILL * value) & near).any()),
                               float(value[near].min(initial=np.inf)),
                               float(value.max(initial=0.0)))
        for name, divisor, c, floor in divided:
            ill, low, high = found[c, floor]
            if ill and name not in self.ill:
                self.ill[name] = (f"unresolved (it divides by {divisor}, whose error is not "
                                  f"small against it: over {ILL:g} of it)")
            before = self.divisors.get(name, (np.inf, 0.0))
            self.divisors[name] = (min(before[0], low), max(before[1], high))

    def _network(self, ks: np.ndarray, h: np.ndarray, holds: dict) -> None:
        """The network's errors (pair_network.py): its recorded outputs' kept, and the
        largest of those it hands to FMUs outside it."""
        errors = self.net.steps(ks, h, holds, self._rows)
        net = self.plan.network
        self._keep([n for n, _ in net.recorded], errors[:, self.net.recorded_at])
        for (name, _, _), j in zip(net.checked, self.net.checked_at):
            self.fed[name] = max(self.fed[name], float(np.max(np.abs(errors[:, j]))))

    def _late_carried(self, nodes: np.ndarray, branch: bool = False) -> np.ndarray | float:
        """The error the loop carries into Jacobi's late outputs (late_names) at `nodes` (0
        for those outside the loop's chain; `branch`: the branch's nodes): the true value at
        node j is the run's d rows later, less the error that row carries."""
        places, cols = self.late_chain
        if not places:
            return 0.0
        found = self.carry.carried(cols, nodes, branch)
        if len(places) == len(self.late_names):     # every one of them, in order
            return found
        out = np.zeros((len(nodes), len(self.late_names)))
        out[:, places] = found
        return out

    def _rows(self, first: int, last: int) -> np.ndarray:
        """The run's rows first .. last, those before the first or past the last it has
        standing in for them (the first row; the last: node n)."""
        rows = np.arange(first - self.lo, last + 1 - self.lo)
        return self.window[np.minimum(np.maximum(rows, 0), len(self.window) - 1)]

    def _keep(self, names: list[str], errors: np.ndarray) -> None:
        """The signed errors of outputs `names` (a column each) on a batch of rows."""
        if len(errors):
            size = np.abs(errors)
            worst, end = size.max(axis=0).tolist(), size[-1].tolist()
            for name, w, e in zip(names, worst, end):
                self.worst[name] = max(self.worst[name], w)
                self.end[name] = e

    def _steps(self, k_hi: int, branch: int = 0) -> None:
        """Work out steps self.k .. k_hi, then drop the rows no later step reads. With
        `branch` (_branchable), the last that many steps are worked out again after them
        with the parabola, for the end's second value (self.branch_end)."""
        ks = np.arange(self.k, k_hi + 1)
        if not len(ks):
            return
        h = np.full(len(ks), self.h)
        if ks[-1] == self.n - 1:
            h[-1] = self.last * self.h
        stencils = self._polynomials(ks, branch=branch) if self.known is None else \
            self._tabled(ks, branch)
        holds = {}
        for i, g in enumerate(self.plan.groups):
            if branch:
                self._branched_group(i, g, ks, h, stencils, branch)
                continue
            gathered = self._gathered(i, stencils)
            held, own, change = self._group(g, ks, gathered)
            error = self._forwarded_into(i, own)
            if g.model is None:
                self._note_moved(i, error)
                continue
            if self.net is not None:
                holds[i] = (held, error, change)
                continue
            self._kept(i, self._signed(i, g, ks, h, (held, error, change),
                                       lead=lead_of(g, gathered, own)))
        if self.net is not None:
            self._network(ks, h, holds)
        if self.lags:
            self._keep_late(ks, stencils, k_hi == self.n - 1, branch)
        self.failed = self._fed_error() or (self.known.failed if self.known else None)
        for i, signed in self.sent.items():
            self.sent_before[i] = signed[-1]
        self.k = k_hi + 1
        drop = max(0, self.k - 4 - self.lo)
        self.window, self.lo = self.window[drop:], self.lo + drop

    def _signed(self, i: int, g: Group, ks: np.ndarray, h: np.ndarray, hold: tuple,
                branch: int = 0, lead: tuple | None = None) -> np.ndarray:
        """Group i's signed errors after each step (with a `branch`, its rows after them):
        its model's (a branch only to a model that takes one: _branchable), or around the
        loop it starts (_carried). `lead`: lead_of's (pair_holds.py), for a measured model's
        direct part (ProbedModel: held - true end = error - lead)."""
        if self.carry is not None and i == self.plan.loop.origin:
            return self._carried(g, ks, h, hold, branch)
        more = {"lead": lead} if lead is not None else {}
        return g.model.steps(h, *hold, branch=branch, **more) if branch else \
            g.model.steps(h, *hold, **more)

    def _kept(self, i: int, signed: np.ndarray) -> None:
        """Keep group i's signed errors after each step: its covered outputs', those other
        FMUs read, those it forwards."""
        names, index = self.covers[i]
        self._keep(names, signed[:, index])
        self._check_fed(i, signed)
        if i in self.sent_before:
            self.sent[i] = signed

    def _branched_group(self, i: int, g: Group, ks, h, stencils: dict, branch: int) -> None:
        """Group i's steps with a branch (_steps): the steps kept, the branch's end apart."""
        gathered = self._gathered(i, stencils)
        held, error, change = self._group(g, with_branch(ks, branch), gathered)
        if g.model is None:
            self._note_moved(i, error[:len(ks)])
            return
        signed = self._signed(i, g, ks, with_branch(h, branch), (held, error, change), branch,
                              lead=lead_of(g, gathered, error))
        self._kept(i, signed[:len(ks)])
        names, index = self.covers[i]
        self.branch_end.update(zip(names, np.abs(signed[-1, index]).tolist()))

    def _note_moved(self, i: int, error: np.ndarray) -> None:
        """Keep how far group i's held inputs (an FMU with a state and no error model) moved
        from their true means within the steps (_moved)."""
        np.maximum(self.moved[i], np.max(np.abs(error), axis=0), out=self.moved[i])

    def _still(self) -> bool:
        """Whether every column the pair reads holds one value over the whole run (none
        worked out yet, every row in the window) and nothing moves between the nodes (no
        breakpoint inside a step, no table stepped across): every hold is then exact and
        every error 0, under any master (the bicycle on constant commands)."""
        return self.k == 0 and self.lo == 0 and len(self.window) == self.n + 1 and not (
            len(self.across_k) or self.known) and not (self.window != self.window[0]).any()

    @property
    def _branchable(self) -> bool:
        """Whether Jacobi's end with the parabola can be a branch of the same pass: every
        model takes one, and no error is carried between groups but around a loop (not
        through a network, nor forwarded; nor a loop's predicted end values)."""
        return not (self.net or self.plan.forwarded or (self.carry and self.plan.rolled_back)
                    ) and all(
            getattr(g.model, "branches", False) for g in self.plan.groups if g.model is not None)

    def _keep_late(self, ks: np.ndarray, stencils: dict, last: bool, branch: int = 0) -> None:
        """Jacobi's late outputs' errors on a batch of rows: the row against the true value
        of its node d rows before (less the error the loop carries into it), and with the
        `last` batch the last row, against the last step's end (the branch's: branch_end)."""
        names, cols = self.late_names, self.late_cols
        true = np.concatenate([stencils[d][1][:len(ks), at] for d, _, at in self.lags], axis=1)
        errors = self.window[(ks - self.lo)[:, None], cols] - true + self._late_carried(ks)
        if last:
            end = np.concatenate([stencils[d][2][[len(ks) - 1, -1]][:, at] for d, _, at
                                  in self.lags], axis=1)
            ends = self.window[[self.n - self.lo]][:, cols] - end
            ends[:1] += self._late_carried(ks[-1:] + 1)
            errors = np.concatenate((errors, ends[:1]))
            if branch:
                ends[1:] += self._late_carried(ks[-1:] + 1, branch=True)
                self.branch_end.update(zip(names, np.abs(ends[1]).tolist()))
        self._keep(names, errors)
