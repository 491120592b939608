"""Where every value lives while the FMUs run, and how it moves.

Values move through two flat NumPy buffers (one float64 for Real, one int32 for Integer and
Boolean) that the FMUs' get calls write into directly, so a step costs the FMI calls plus a
few NumPy copies: one batched get/set per FMU and type per step, nothing allocated per step.
"""
from __future__ import annotations

import ctypes
from collections.abc import Mapping
from types import MappingProxyType
from typing import Callable

import numpy as np

from ..scenario.graph import Graph, Instance, Port
from .instance import RunningInstance

_C_TYPES = {"Real": (ctypes.c_double, np.float64), "Integer": (ctypes.c_int, np.int32),
            "Boolean": (ctypes.c_int, np.int32)}


class Buffers:
    """One slot per value that moves or is recorded, contiguous per instance and type."""

    def __init__(self, graph: Graph, freeze: bool):
        self.real_slots: dict[Port, int] = {}
        self.int_slots: dict[Port, int] = {}
        self.outputs_of = _outputs_of(graph)
        for ports in self.outputs_of.values():
            for kind in ("Real", "Integer", "Boolean"):
                for p in ports:
                    if p.type == kind:
                        self.slots(p).setdefault(p, len(self.slots(p)))
        self.real = np.zeros(max(len(self.real_slots), 1), dtype=np.float64)
        self.int = np.zeros(max(len(self.int_slots), 1), dtype=np.int32)
        # Inputs are set from these. Jacobi: a copy of the values at t_k, frozen before anyone
        # steps, so every component sees t_k whatever the order; otherwise the live buffers.
        self.frozen = freeze
        self.real_in, self.int_in = ((self.real.copy(), self.int.copy()) if freeze
                                     else (self.real, self.int))
        # The discrete outputs an FMU with continuous outputs reads, at the step's start
        # (masters.Master.holds_samples): their values then, and their slots per kind
        self.real_held, self.int_held = self.real.copy(), self.int.copy()
        self.held_slots: dict[str, np.ndarray] = {}

    def slots(self, port: Port) -> dict[Port, int]:
        return self.real_slots if port.type == "Real" else self.int_slots

    def slot(self, port: Port) -> int:
        return self.slots(port)[port]

    def out(self, kind: str) -> np.ndarray:
        return self.real if kind == "Real" else self.int

    def inp(self, kind: str) -> np.ndarray:
        return self.real_in if kind == "Real" else self.int_in

    def held(self, kind: str) -> np.ndarray:
        return self.real_held if kind == "Real" else self.int_held

    def hold(self) -> None:
        """A step starts: the held discrete outputs' values over it."""
        self.real_held[:] = self.real
        self.int_held[:] = self.int

    def changed(self) -> bool:
        """Whether a held discrete output changed in the step (after hold())."""
        return any(bool((self.out(kind)[s] != self.held(kind)[s]).any())
                   for kind, s in self.held_slots.items())

    def freeze(self) -> None:
        """Jacobi: copy the values at t_k into the input buffers."""
        self.real_in[:] = self.real
        self.int_in[:] = self.int


def _outputs_of(graph: Graph) -> dict[str, list[Port]]:
    """Per instance, the outputs that feed a link, are recorded or are watched (Graph.watched:
    an error model reads them), without repeats."""
    outputs: dict[str, list[Port]] = {i.name: [] for i in graph.instances}
    for link in graph.links:
        outputs[link.source.ref.instance].append(link.source)
    for port in (*graph.recorded, *graph.watched):
        outputs[port.ref.instance].append(port)
    return {name: list(dict.fromkeys(ports)) for name, ports in outputs.items()}


def plan_transfers(running: list[RunningInstance], graph: Graph, buffers: Buffers,
                   hold: str, holds: "Holds | None" = None, samples: bool = False) -> Holds:
    """Preallocate, per instance and type, one batched get and one batched set (see
    _plan_writes). `hold`: "zoh" (Gauss-Seidel, Jacobi), "trapezoidal" or "quadratic";
    `holds`: where the blended inputs go (default: a Holds of that hold's fixed weights);
    `samples`: discrete outputs are held at the step's start (masters.Master.holds_samples)."""
    position = {r.name: i for i, r in enumerate(running)}
    holds = Holds(hold) if holds is None else holds
    for r in running:
        _plan_reads(r, buffers)
        held = [l for l in graph.held if l.target.ref.instance == r.name] if samples else []
        _plan_held(r, held, buffers)
        _plan_writes(r, graph, buffers, position, hold, holds, held)
    if buffers.held_slots:          # a settle's writes: a blend's inputs at their newest
        newest = {b.fill: b.newest for b in holds.blends}
        for r in running:
            if r.name in graph.settled:
                r.settles = [(newest.get(fill, fill), *rest) for fill, *rest in r.writes]
    return holds


def _plan_reads(r: RunningInstance, buffers: Buffers) -> None:
    """A get writes straight into the output buffer: its slots are one contiguous run."""
    ports = buffers.outputs_of[r.name]
    for kind in ("Real", "Integer", "Boolean"):
        mine = [p for p in ports if p.type == kind]
        if mine:
            first = buffers.slot(mine[0])
            assert [buffers.slot(p) for p in mine] == list(range(first, first + len(mine)))
            r.reads.append((r.c_get[kind], _vr_array([p.vr for p in mine]), len(mine),
                            _pointer(buffers.out(kind), first, _C_TYPES[kind][0])))


def _plan_held(r: RunningInstance, held: list, buffers: Buffers) -> None:
    """The held links' sets: from the values at the step's start (Buffers.hold)."""
    for kind in ("Real", "Integer", "Boolean"):
        mine = [l for l in held if l.target.type == kind]
        if not mine:
            continue
        src = np.array([buffers.slot(l.source) for l in mine], dtype=np.intp)
        slots = buffers.held_slots.get(kind, np.zeros(0, dtype=np.intp))
        buffers.held_slots[kind] = np.union1d(slots, src).astype(np.intp)
        r.writes.append(_staged(buffers.held(kind), src, r.c_set[kind], mine, kind))


def _plan_writes(r: RunningInstance, graph: Graph, buffers: Buffers, position: dict,
                 hold: str, holds: Holds, held: list) -> None:
    """A set takes its values straight from the input buffer when its sources sit in one
    contiguous run in the right order (the usual chain), else from a staging array filled by
    one np.take. Real inputs that a hold blends (see HOLDS) get a staging array filled from
    their history."""
    links = [l for l in graph.links if l.target.ref.instance == r.name and l not in held]
    through = holds.through or holds_through(r.inst, r.name in graph.measured)
    roles = _blend_roles(r, links, position, through, r.name in holds.held_at_end,
                         r.name in holds.hidden) if hold != "zoh" else {}
    real = [l for l in links if l.target.type == "Real"]
    groups = (("Real", [l for l in real if l.target.ref.variable not in roles]),
              ("Blend", [l for l in real if l.target.ref.variable in roles]),
              ("Integer", [l for l in links if l.target.type == "Integer"]),
              ("Boolean", [l for l in links if l.target.type == "Boolean"]))
    for kind, mine in groups:
        if not mine:
            continue
        value_kind = "Real" if kind == "Blend" else kind
        ctype = _C_TYPES[value_kind][0]
        buf = buffers.inp(value_kind)
        src = np.array([buffers.slot(l.source) for l in mine], dtype=np.intp)
        vrs, c_set = _vr_array([l.target.vr for l in mine]), r.c_set[value_kind]
        if kind == "Blend":
            blend = holds.add(buf, src, [roles[l.target.ref.variable] for l in mine],
                              [l.target for l in mine], r.inst)
            r.writes.append((blend.fill, c_set, vrs, len(mine), _pointer(blend.staging, 0, ctype)))
            _plan_resets(r, [l for l in mine if roles[l.target.ref.variable] == "through"],
                         buffers)
        elif list(src) == list(range(src[0], src[0] + len(src))):
            r.writes.append((None, c_set, vrs, len(mine), _pointer(buf, int(src[0]), ctype)))
        else:
            r.writes.append(_staged(buf, src, c_set, mine, value_kind))


def _plan_resets(r: RunningInstance, links: list, buffers: Buffers) -> None:
    """The "through" inputs (held at their mean during doStep) set to their end values after
    it, before the outputs are read: the outputs that depend on them see u_k+1."""
    if not links:
        return
    src = np.array([buffers.slot(l.source) for l in links], dtype=np.intp)
    r.resets.append(_staged(buffers.inp("Real"), src, r.c_set["Real"], links, "Real"))


def _staged(buffer: np.ndarray, src: np.ndarray, c_set, links: list, kind: str) -> tuple:
    """A batched set of the `links`' targets from a staging array that one np.take fills
    from buffer[src] before the set: (fill, c_set, vrs, n, pointer)."""
    ctype, dtype = _C_TYPES[kind]
    staging = np.zeros(len(links), dtype=dtype)
    return (_take(buffer, src, staging), c_set, _vr_array([l.target.vr for l in links]),
            len(links), _pointer(staging, 0, ctype))


def _take(buffer: np.ndarray, src: np.ndarray, staging: np.ndarray) -> Callable[[], None]:
    """Inputs take the newest values (zero-order hold), gathered from scattered slots."""
    return lambda: np.take(buffer, src, out=staging)


def _blend_roles(r: RunningInstance, links: list, position: dict, through: bool = False,
                 at_end: bool = False, hidden: bool = False) -> dict[str, str]:
    """The Real inputs a hold blends, by role: "state" (no output of the FMU depends on it,
    its source stepped first: its value at t_k+1 is known), "state_ahead" (the same, but its
    source steps later: a loop closing into the FMU's state) and "fed_back" (an input with
    direct feedthrough whose source steps later). With `through` (the adaptive master's
    holds), "through": an input with direct feedthrough into an FMU with a state (an output
    that depends on no input), its source stepped first: held at its mean during doStep (for
    the state, as "state"), set to its end value after it (for the outputs): otherwise the
    state integrates the end value held over the step, an error of the first order. With
    `at_end` (Holds.held_at_end: an output worked out in doStep alone), "end" instead: held
    at its end value, a first-order hold the adaptive master's pair measures. `hidden`: the
    FMU holds a state its outputs' dependencies do not say (Holds.hidden), taken as it."""
    state_only = state_only_inputs(r.inst)
    stateful = through and (has_state(r.inst) or hidden)
    roles = {}
    for l in links:
        name, later = l.target.ref.variable, position[l.source.ref.instance] > position[r.name]
        if name in state_only:
            roles[name] = "state_ahead" if later else "state"
        elif later and l.target.type == "Real":
            roles[name] = "fed_back"
        elif stateful and l.target.type == "Real":
            roles[name] = "end" if at_end else "through"
    return roles


def has_state(inst: Instance) -> bool:
    """It may hold a state: some output depends on no input (declared: an empty dependency
    list), or some output's dependencies are not declared (FMI 2.0: it may then depend on
    every input and on a state; pythonfmu's and pythonfmu3's FMUs declare none). Only an FMU
    whose every output declares a dependency on an input is taken to hold none."""
    return any(not u.dependencies for u in inst.model.outputs)


def holds_through(inst: Instance, measured: bool) -> bool:
    """Whether a fixed-step master that blends holds this FMU's direct-feedthrough inputs
    "through" (_blend_roles): a third-party FMU (`measured`: Graph.measured) with a state
    whose every output declares its dependencies, so that its outputs that read an input
    are known to (FMI 2.0: an output that depends on an input follows it when it is set
    after doStep). The bundled FMUs keep the end value (their runs unchanged)."""
    return measured and has_state(inst) and all(u.dependencies is not None
                                                for u in inst.model.outputs)


def state_undeclared(inst: Instance) -> bool:
    """It may hold a state only because some output's dependencies are not declared (every
    declared list names an input): a probe may find that it holds none (memory.py)."""
    outputs = inst.model.outputs
    return any(u.dependencies is None for u in outputs) and \
        all(u.dependencies is None or u.dependencies for u in outputs)


# How a hold sets a blended input, per role, in each mode (Holds.mode: single pass or
# predictor, corrector): weights over (value in the buffer now, u_k, u_k-1) and whether the
# parabola's correction is added. While a step runs, the buffer holds u_k+1 for "state" inputs
# (their source stepped first) and u_k for the others (in the corrector pass: u_k+1 as the
# predictor pass produced it).
#   trapezoidal: the mean of u over the step, (u_k + u_k+1)/2; where u_k+1 is not known yet,
#     extrapolated 1.5 u_k - 0.5 u_k-1; a fed-back input's value at t_k+1, 2 u_k - u_k-1.
#   quadratic: the mean over the step of the parabola through u_k-1, u_k, u_k+1: the trapezoid
#     minus (u_k+1 - 2 u_k + u_k-1)/12, that second difference limited (minmod) by the previous
#     one, so that a kink or a jump in the input (a table's breakpoint) adds nothing and a
#     piecewise-linear input is integrated exactly, as by the trapezoid. Where u_k+1 is not
#     known, the step is taken twice: predicted with trapezoidal's extrapolation, rolled back
#     (fmi2SetFMUstate) and corrected with the predicted u_k+1 (docs/masters.md).
_TRAPEZOID, _NOW = (0.5, 0.5, 0.0), (1.0, 0.0, 0.0)
_AHEAD, _FED_BACK = (0.0, 1.5, -0.5), (0.0, 2.0, -1.0)
HOLDS = {
    "trapezoidal": {"state": ((_TRAPEZOID, False),) * 2, "state_ahead": ((_AHEAD, False),) * 2,
                    "fed_back": ((_FED_BACK, False),) * 2},
    "quadratic": {"state": ((_TRAPEZOID, True),) * 2,
                  "state_ahead": ((_AHEAD, False), (_TRAPEZOID, True)),
                  "fed_back": ((_FED_BACK, False), (_NOW, False))},
}
for _rules in HOLDS.values():      # held as a state's during doStep, then its end value
    _rules["through"] = _rules["state"]


class Holds:
    """The history of every blended input and the pass a step is in. Per step: fill() of
    each blend (through the instances' writes), then commit() once the step is final."""
    PREDICT, CORRECT = 0, 1
    through = False     # no "through" role (_blend_roles): the fixed-step masters'
    # the FMUs whose inputs an output reads are held at their end values ("end"), not
    # "through", and those outputs (worked out in doStep alone: memory.lazy_at_start)
    held_at_end: Mapping[str, list[str]] = MappingProxyType({})
    # the FMUs whose outputs declare inputs only that the probes found holding a state
    # (memory.hidden_at_start): their inputs are held as a state's (_blend_roles)
    hidden: frozenset = frozenset()

    def __init__(self, hold: str):
        self.hold = hold
        self.blends: list[_Blend] = []
        self.mode = self.PREDICT
        self.steps = 0          # committed steps: the parabola needs two behind it
        self.ahead = False      # some input's next value is unknown when its FMU steps (a loop)

    def add(self, buffer: np.ndarray, src: np.ndarray, roles: list[str], targets: list[Port],
            inst: Instance) -> "_Blend":
        """A blend of inputs `targets` of `inst` (from buffer[src]), by role (_blend_roles)."""
        self.blends.append(_Blend(self, buffer, src, [HOLDS[self.hold][r] for r in roles]))
        self.ahead = self.ahead or any(role not in ("state", "through") for role in roles)
        return self.blends[-1]

    def prime(self) -> None:
        """Record the values at t0 as the whole history."""
        for b in self.blends:
            for _ in range(3):
                b.commit()
        self.steps = 0

    def shift(self) -> None:
        """The inputs jumped (a discrete output changed): the history moves by the jump, its
        slope and curvature kept (the step before held the left values)."""
        for b in self.blends:
            b.shift()
        self.mode = self.PREDICT

    def commit(self) -> None:
        """The step is final: its end values become u_k, and the history moves back one."""
        for b in self.blends:
            b.commit()
        self.steps += 1
        self.mode = self.PREDICT


class _Blend:
    """Inputs set to weights . (values now | u_k | u_k-1), minus the limited parabola
    correction where the rule says so: a handful of NumPy calls per fill, no allocation, and
    elementwise only, so the same bits on every CPU (a matrix product goes to the BLAS,
    whose kernel, chosen by the CPU, orders and fuses the sums)."""

    def __init__(self, holds: Holds, buffer: np.ndarray, src: np.ndarray, rules: list):
        m = len(src)
        self.holds, self.buffer, self.src = holds, buffer, src
        self.staging = np.zeros(m)
        self.history = np.zeros(4 * m)     # [values now | u_k | u_k-1 | u_k-2]
        self.now, self.u_k = self.history[:m], self.history[m:2 * m]
        self.older, self.old = self.history[2 * m:], self.history[m:3 * m]   # for the shift
        # Per mode: the weights of (now | u_k | u_k-1), and 1/12 (or 0) per input for the
        # second differences (now - 2 u_k + u_k-1)/12 and, before it, (u_k - 2 u_k-1 +
        # u_k-2)/12 of the inputs the rule corrects.
        self.weights = [np.zeros(3 * m) for _ in range(2)]
        self.second = [np.zeros(2 * m) for _ in range(2)]
        for i, per_mode in enumerate(rules):
            for mode, ((w_now, w_k, w_km1), parabola) in enumerate(per_mode):
                self.weights[mode][[i, m + i, 2 * m + i]] = w_now, w_k, w_km1
                if parabola:
                    self.second[mode][[i, m + i]] = 1 / 12
        self.limited = [bool(d.any()) for d in self.second]
        self.terms = np.zeros(3 * m)
        self.parts = self.terms[:m], self.terms[m:2 * m], self.terms[2 * m:]
        self.d = np.zeros(2 * m)
        self.a, self.b = self.d[:m], self.d[m:]
        self.low, self.high = np.zeros(m), np.zeros(m)
        # the views of the history that fill reads, made once (a slice per call cost as much
        # as the arithmetic on these few values)
        self.first3, self.first2 = self.history[:3 * m], self.history[:2 * m]
        self.middle2, self.last2 = self.history[m:3 * m], self.history[2 * m:]
        self.behind, self.jump = self.history[m:].reshape(3, m), np.zeros(m)     # (shift)

    def fill(self) -> None:
        self.buffer.take(self.src, out=self.now)     # np.take without its Python wrapper
        mode = self.holds.mode
        np.multiply(self.weights[mode], self.first3, out=self.terms)
        now, u_k, u_km1 = self.parts
        np.add(now, u_k, out=self.staging)
        self.staging += u_km1
        if self.limited[mode] and self.holds.steps >= 2:
            # the second differences of (now, u_k, u_k-1) and of (u_k, u_k-1, u_k-2) at once
            np.subtract(self.first2, self.middle2, out=self.d)
            self.d -= self.middle2
            self.d += self.last2
            self.d *= self.second[mode]
            # minmod(a, b) = b clipped to [min(a, 0), max(a, 0)]: the one nearer zero when
            # both have the same sign, else 0
            np.minimum(self.a, 0.0, out=self.low)
            np.maximum(self.a, 0.0, out=self.high)
            np.maximum(self.b, self.low, out=self.low)
            np.minimum(self.low, self.high, out=self.low)
            np.subtract(self.staging, self.low, out=self.staging)

    def newest(self) -> None:
        """The inputs at their newest values (a settle: plan.Buffers.hold)."""
        self.buffer.take(self.src, out=self.staging)

    def shift(self) -> None:
        self.buffer.take(self.src, out=self.jump)
        self.jump -= self.u_k
        self.behind += self.jump            # u_k, u_k-1 and u_k-2 each move by the jump

    def commit(self) -> None:
        self.older[:] = self.old            # u_k-1 -> u_k-2, u_k -> u_k-1 (numpy copies
        self.buffer.take(self.src, out=self.u_k)         # overlapping views safely)


def _vr_array(vrs: list[int]) -> ctypes.Array:
    return (ctypes.c_uint * len(vrs))(*vrs)


def _pointer(array: np.ndarray, offset: int, ctype):
    """A C pointer to array[offset:], keeping the array alive as long as the pointer."""
    pointer = ctypes.cast(array.ctypes.data + offset * array.itemsize, ctypes.POINTER(ctype))
    pointer._keep = array
    return pointer


def state_only_inputs(inst: Instance) -> set[str]:
    """Inputs that no output depends on directly (per the FMU's ModelStructure). Undeclared
    dependencies mean 'depends on every input', so such an FMU has no state-only inputs."""
    inputs = {v.name for v in inst.model.modelVariables if v.causality == "input"}
    for unknown in inst.model.outputs:
        if unknown.dependencies is None:
            return set()
        inputs -= {d.name for d in unknown.dependencies}
    return inputs
