"""Where every value lives while the FMUs run, and how it moves.

Values move through two flat NumPy buffers (one float64 for Real, one int32 for Integer and
Boolean) that the FMUs' get calls write into directly, so a step costs the FMI calls plus a
few NumPy copies: one batched get/set per FMU and type per step, nothing allocated per step.
"""
from __future__ import annotations

import ctypes
from typing import Callable

import numpy as np

from ..graph import Graph, Instance, Port
from .instance import RunningInstance

_C_TYPES = {"Real": (ctypes.c_double, np.float64), "Integer": (ctypes.c_int, np.int32),
            "Boolean": (ctypes.c_int, np.int32)}


class Buffers:
    """One slot per value that moves or is recorded, contiguous per instance and type."""

    def __init__(self, graph: Graph, jacobi: bool):
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
        self.real_in, self.int_in = ((self.real.copy(), self.int.copy()) if jacobi
                                     else (self.real, self.int))

    def slots(self, port: Port) -> dict[Port, int]:
        return self.real_slots if port.type == "Real" else self.int_slots

    def slot(self, port: Port) -> int:
        return self.slots(port)[port]

    def out(self, kind: str) -> np.ndarray:
        return self.real if kind == "Real" else self.int

    def inp(self, kind: str) -> np.ndarray:
        return self.real_in if kind == "Real" else self.int_in

    def freeze(self) -> None:
        """Jacobi: copy the values at t_k into the input buffers."""
        self.real_in[:] = self.real
        self.int_in[:] = self.int


def _outputs_of(graph: Graph) -> dict[str, list[Port]]:
    """Per instance, the outputs that feed a link or are recorded, without repeats."""
    outputs: dict[str, list[Port]] = {i.name: [] for i in graph.instances}
    for link in graph.links:
        outputs[link.source.ref.instance].append(link.source)
    for port in graph.recorded:
        outputs[port.ref.instance].append(port)
    return {name: list(dict.fromkeys(ports)) for name, ports in outputs.items()}


def plan_transfers(running: list[RunningInstance], graph: Graph, buffers: Buffers,
                   trapezoidal: bool) -> list[Callable[[], None]]:
    """Preallocate, per instance and type, one batched get and one batched set (see
    _plan_writes). Returns the functions that seed the blends' history at t0."""
    position = {r.name: i for i, r in enumerate(running)}
    primes: list[Callable[[], None]] = []
    for r in running:
        _plan_reads(r, buffers)
        primes += _plan_writes(r, graph, buffers, position, trapezoidal)
    return primes


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


def _plan_writes(r: RunningInstance, graph: Graph, buffers: Buffers, position: dict,
                 trapezoidal: bool) -> list[Callable[[], None]]:
    """A set takes its values straight from the input buffer when its sources sit in one
    contiguous run in the right order (the usual chain), else from a staging array filled by
    one np.take. With `trapezoidal`, a Real input that no output of its FMU depends on (it only
    drives the FMU's state over the step) takes the mean of its values at t_k and t_k+1: a
    trapezoidal hold, second order. t_k+1 is known when the source steps earlier in the
    Gauss-Seidel order; otherwise the mean is extrapolated from t_k and t_k-1
    (1.5 u_k - 0.5 u_k-1). A Real input fed back from an FMU that steps later (e.g. a heading
    from an integrator) takes its value at t_k+1 extrapolated, 2 u_k - u_k-1, so the feedback
    stays second order."""
    links = [l for l in graph.links if l.target.ref.instance == r.name]
    state_only = _state_only_inputs(r.inst) if trapezoidal else set()
    fed_back = ({l.target.ref.variable for l in links
                 if position[l.source.ref.instance] > position[r.name]} if trapezoidal else set())
    blended = state_only | fed_back
    real = [l for l in links if l.target.type == "Real"]
    groups = (("Real", [l for l in real if l.target.ref.variable not in blended]),
              ("Blend", [l for l in real if l.target.ref.variable in blended]),
              ("Integer", [l for l in links if l.target.type == "Integer"]),
              ("Boolean", [l for l in links if l.target.type == "Boolean"]))
    primes = []
    for kind, mine in groups:
        if not mine:
            continue
        value_kind = "Real" if kind == "Blend" else kind
        ctype, dtype = _C_TYPES[value_kind]
        buf = buffers.inp(value_kind)
        src = np.array([buffers.slot(l.source) for l in mine], dtype=np.intp)
        vrs, c_set = _vr_array([l.target.vr for l in mine]), r.c_set[value_kind]
        if kind == "Blend":
            weights = [_hold_weights(position[l.source.ref.instance] < position[r.name],
                                     l.target.ref.variable in state_only) for l in mine]
            fill, prime, staging = _blend(buf, src, weights)
            primes.append(prime)
            r.writes.append((fill, c_set, vrs, len(mine), _pointer(staging, 0, ctype)))
        elif list(src) == list(range(src[0], src[0] + len(src))):
            r.writes.append((None, c_set, vrs, len(mine), _pointer(buf, int(src[0]), ctype)))
        else:
            staging = np.zeros(len(mine), dtype=dtype)
            r.writes.append((_take(buf, src, staging), c_set, vrs, len(mine),
                             _pointer(staging, 0, ctype)))
    return primes


def _take(buffer: np.ndarray, src: np.ndarray, staging: np.ndarray) -> Callable[[], None]:
    """Inputs take the newest values (zero-order hold), gathered from scattered slots."""
    return lambda: np.take(buffer, src, out=staging)


def _hold_weights(upstream_first: bool, state_only: bool) -> tuple[float, float]:
    """(w_new, w_old): the mean over the step of a state-only input (known at t_k+1, or
    extrapolated), else a fed-back input's value at t_k+1 extrapolated."""
    if state_only:
        return (0.5, 0.5) if upstream_first else (1.5, -0.5)
    return 2.0, -1.0


def _blend(buffer: np.ndarray, src: np.ndarray, pairs: list[tuple[float, float]]):
    """Inputs take w_new * (value now) + w_old * (value at the previous fill): one take, one
    dot, one copy per step. Returns (fill, prime, staging); prime() records the values at t0."""
    m = len(src)
    staging = np.zeros(m)
    weights = np.zeros((m, 2 * m))
    for i, (new, old) in enumerate(pairs):
        weights[i, i], weights[i, m + i] = new, old
    picked = np.empty(2 * m)          # [values now | values at the previous fill]
    now, old = picked[:m], picked[m:]

    def fill():
        np.take(buffer, src, out=now)
        np.dot(weights, picked, out=staging)
        old[:] = now

    def prime():
        np.take(buffer, src, out=old)
    return fill, prime, staging


def _vr_array(vrs: list[int]) -> ctypes.Array:
    return (ctypes.c_uint * len(vrs))(*vrs)


def _pointer(array: np.ndarray, offset: int, ctype):
    """A C pointer to array[offset:], keeping the array alive as long as the pointer."""
    pointer = ctypes.cast(array.ctypes.data + offset * array.itemsize, ctypes.POINTER(ctype))
    pointer._keep = array
    return pointer


def _state_only_inputs(inst: Instance) -> set[str]:
    """Inputs that no output depends on directly (per the FMU's ModelStructure). Undeclared
    dependencies mean 'depends on every input', so such an FMU has no state-only inputs."""
    inputs = {v.name for v in inst.model.modelVariables if v.causality == "input"}
    for unknown in inst.model.outputs:
        if unknown.dependencies is None:
            return set()
        inputs -= {d.name for d in unknown.dependencies}
    return inputs
