"""The co-simulation master: instantiate, initialize, step, record, always clean up.

Values move through two flat NumPy buffers (one float64 for Real, one int32 for Integer and
Boolean) that the FMUs' get calls write into directly, so a step costs the FMI calls plus a
few NumPy copies: one batched get/set per FMU and type per step, nothing allocated per step.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import signal
import sys
import tempfile
import threading
import time as _time
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, NoReturn

import numpy as np
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, defaultCallbacks

from .errors import Interrupted, SimulationError
from .graph import Graph, Instance, Port
from .results import Results
from .scenario import Experiment

STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
_fmi2Terminated = 3    # fmi2StatusKind

# ---------------------------------------------------------------------------------------------
# Process-wide FMU handling: one extraction per FMU content, libraries never unloaded.
# pythonfmu's shared library crashes when unloaded and loaded again in one process.
_EXTRACTED: dict[str, str] = {}
_LOG: dict[str, list[str]] = {}
# Instances that ended a run cleanly are kept and reused after fmi2Reset instead of being
# freed: every fmi2Instantiate of a pythonfmu FMU runs its slave script again, and the class
# it makes and a sys.path entry are never released (~18 KB per instance; 1,000 runs of four
# FMUs grew by 70 MB). A reset costs ~0.4 KB. Keyed by extracted FMU, GUID and instance name.
_POOL: dict[tuple[str, str, str], list[tuple[FMU2Slave, object]]] = {}
_POOL_MAX = 4      # instances kept per key


def _on_log(env, instance_name, status, category, message):
    name = instance_name.decode("utf-8", "replace") if instance_name else "?"
    text = " ".join((message.decode("utf-8", "replace") if message else "").split())
    messages = _LOG.setdefault(name, [])
    messages.append(f"[{STATUS.get(status, status)}] {text}")
    del messages[:-20]


_CALLBACKS = fmi2CallbackFunctions()
_CALLBACKS.logger = fmi2CallbackLoggerTYPE(_on_log)
_CALLBACKS.allocateMemory = defaultCallbacks.allocateMemory
_CALLBACKS.freeMemory = defaultCallbacks.freeMemory


def release_instances() -> int:
    """Free every pooled instance (see _POOL); the next run instantiates afresh. Returns how
    many were freed. For a long-lived process that is done simulating."""
    freed = 0
    for pool in _POOL.values():
        while pool:
            fmu, component = pool.pop()
            fmu._functions["fmi2FreeInstance"](component)
            freed += 1
    return freed


@contextmanager
def _ctrl_c_latched() -> Iterator[list[bool]]:
    """While the FMUs run, Ctrl-C only sets a flag that the stepping loop checks once per step.

    The bundled FMUs run Python code on this thread, so Python's default SIGINT handler would
    raise KeyboardInterrupt inside an FMU call about 2 times in 3, and pythonfmu turns that
    into fmi2Fatal (the run fails instead of stopping, the instance cannot even be freed).
    Only on the main thread with the default handler installed; elsewhere the flag stays
    False and Ctrl-C behaves as usual."""
    flag = [False]
    install = (threading.current_thread() is threading.main_thread()
               and signal.getsignal(signal.SIGINT) is signal.default_int_handler)
    if install:
        signal.signal(signal.SIGINT, lambda signum, frame: flag.__setitem__(0, True))
    try:
        yield flag
    finally:
        if install:
            signal.signal(signal.SIGINT, signal.default_int_handler)


def remove_extractions() -> None:
    """Delete the extraction folders. Only for a process about to leave with os._exit (which
    skips every clean-up): the loaded libraries stay mapped, pooled instances are abandoned."""
    for folder in _EXTRACTED.values():
        shutil.rmtree(folder, ignore_errors=True)


def exit_now(code: int) -> NoReturn:
    """Leave the process without interpreter shutdown: with pythonfmu FMUs loaded, CPython's
    finalization aborts now and then ("corrupted double-linked list", ~1 run in 30, after
    every file was written). Flushes the standard streams and removes the extraction folders
    first, the only clean-up that matters once every result file is closed."""
    sys.stdout.flush()
    sys.stderr.flush()
    remove_extractions()
    os._exit(code)


def extracted(path: Path) -> str:
    digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    if digest not in _EXTRACTED:
        _EXTRACTED[digest] = extract(str(path), tempfile.mkdtemp(prefix=f"mecanum_{Path(path).stem}_"))
    return _EXTRACTED[digest]


class FmuCallError(Exception):
    def __init__(self, function: str, status: int):
        self.function, self.status = function, status
        super().__init__(f"{function} returned {STATUS.get(status, status)}")


# ---------------------------------------------------------------------------------------------
class _Slave:
    """One running instance: the fmpy object, raw C functions and preallocated transfer plans."""

    def __init__(self, inst: Instance):
        self.inst = inst
        self.name = inst.name
        md = inst.model
        unzipped = extracted(inst.fmu_path)
        self.key = (unzipped, md.guid, inst.name)
        pooled = _POOL.get(self.key)
        self.fmu, self.component = pooled.pop() if pooled else (FMU2Slave(
            guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=inst.name), None)
        f = self.fmu._functions
        self.c_get_real, self.c_set_real = f["fmi2GetReal"], f["fmi2SetReal"]
        self.c_get_int, self.c_set_int = f["fmi2GetInteger"], f["fmi2SetInteger"]
        self.c_get_bool, self.c_set_bool = f["fmi2GetBoolean"], f["fmi2SetBoolean"]
        self.c_do_step = f["fmi2DoStep"]
        self.broken = 0       # worst status returned: Error (3) or Fatal (4) limit what may follow
        self.failed = False   # returned Discard or worse: freed, never pooled
        # filled by _plan(): (c_get, vrs, n, pointer) and (fill, c_set, vrs, n, pointer)
        self.reads: list = []
        self.writes: list = []

    def check(self, function: str, status: int) -> None:
        if status > 1:
            raise FmuCallError(function, status)

    def instantiate(self) -> None:
        _LOG.pop(self.name, None)
        if self.component is not None:           # from the pool: back to just instantiated
            status = self.fmu._functions["fmi2Reset"](self.component)
            if status <= 1:
                return
            if status < 4:
                self.fmu._functions["fmi2FreeInstance"](self.component)
            self.component = None
        # loggingOn: pythonfmu drops every message otherwise, errors included; _on_log keeps
        # the last few per instance so a failure can quote the FMU's own reason.
        self.fmu.instantiate(callbacks=_CALLBACKS, loggingOn=True)
        self.component = self.fmu.component

    def terminate(self) -> None:
        # FMI 2.0: after Error an instance may only be freed; after Fatal, not even that.
        if self.component is not None and not self.broken:
            self.fmu._functions["fmi2Terminate"](self.component)

    def free(self) -> None:
        # Back to the pool if it ended cleanly (see _POOL), else fmi2FreeInstance only: never
        # unload the library (see _EXTRACTED). An instance that returned Fatal is left alone
        # (pythonfmu crashes the process if it is touched again).
        pool = _POOL.setdefault(self.key, [])
        if self.component is not None and not self.failed and len(pool) < _POOL_MAX:
            pool.append((self.fmu, self.component))
        elif self.component is not None and self.broken < 4:
            self.fmu._functions["fmi2FreeInstance"](self.component)
        self.component = None

    def last_log(self) -> str:
        messages = _LOG.get(self.name, [])
        return "; ".join(messages[-3:])


def _take(buffer: np.ndarray, src: np.ndarray, staging: np.ndarray) -> Callable[[], None]:
    """Inputs take the newest values (zero-order hold), gathered from scattered slots."""
    return lambda: np.take(buffer, src, out=staging)


def _blend(buffer: np.ndarray, src: np.ndarray, weights: np.ndarray,
           staging: np.ndarray) -> tuple[Callable[[], None], Callable[[], None]]:
    """Inputs take w_new * (value now) + w_old * (value at the previous fill): one take, one
    dot, one copy per step. Returns (fill, prime); prime() records the values at t0."""
    m = len(src)
    picked = np.empty(2 * m)          # [values now | values at the previous fill]
    now, old = picked[:m], picked[m:]

    def fill():
        np.take(buffer, src, out=now)
        np.dot(weights, picked, out=staging)
        old[:] = now

    def prime():
        np.take(buffer, src, out=old)
    return fill, prime


def _vr_array(vrs: list[int]) -> ctypes.Array:
    return (ctypes.c_uint * len(vrs))(*vrs)


def _setup_start_values(slave: _Slave) -> None:
    inst, fmu = slave.inst, slave.fmu
    by_name = {v.name: v for v in inst.model.modelVariables}
    for name, value in inst.start_values.items():
        var = by_name[name]
        kind = "Integer" if var.type == "Enumeration" else var.type
        setter = {"Real": fmu.setReal, "Integer": fmu.setInteger,
                  "Boolean": fmu.setBoolean, "String": fmu.setString}[kind]
        setter([var.valueReference], [value])


def simulate(graph: Graph, experiment: Experiment,
             progress: Callable[[float], None] | None = None) -> Results:
    """Run the graph. Raises SimulationError (with the partial Results) when an FMU fails,
    Interrupted on Ctrl-C; every instance is terminated and freed in all cases."""
    start, stop, h = experiment.start_time, experiment.stop_time, experiment.step_size
    n_steps = int(round((stop - start) / h))
    if start + n_steps * h < stop - 1e-9 * h:
        n_steps += 1          # a last step reaches (or passes) stop_time
    jacobi = experiment.master == "jacobi"
    trapezoidal = experiment.master == "trapezoidal"

    # Buffers: every value that moves or is recorded has one slot.
    real_slots: dict[Port, int] = {}
    int_slots: dict[Port, int] = {}

    def slot(port: Port) -> int:
        table = real_slots if port.type == "Real" else int_slots
        return table.setdefault(port, len(table))

    outputs_of: dict[str, list[Port]] = {i.name: [] for i in graph.instances}
    for link in graph.links:
        outputs_of[link.source.ref.instance].append(link.source)
    for port in graph.recorded:
        outputs_of[port.ref.instance].append(port)
    for name, ports in outputs_of.items():      # contiguous per instance and type
        unique = list(dict.fromkeys(ports))
        outputs_of[name] = unique
        for kind in ("Real", "Integer", "Boolean"):
            for p in unique:
                if p.type == kind:
                    slot(p)
    real_buf = np.zeros(max(len(real_slots), 1), dtype=np.float64)
    int_buf = np.zeros(max(len(int_slots), 1), dtype=np.int32)
    # Recording copies the whole buffers (one contiguous copy each); columns are picked at the end.
    rec_real = np.empty((n_steps + 1, len(real_buf)), dtype=np.float64)
    rec_int = np.empty((n_steps + 1, len(int_buf)), dtype=np.int32)
    # Inputs are set from these. Jacobi: a copy of the values at t_k, frozen before anyone
    # steps, so every component sees t_k whatever the order; otherwise the live buffers.
    real_in, int_in = (real_buf.copy(), int_buf.copy()) if jacobi else (real_buf, int_buf)
    layout = _Layout(graph, tuple(str(p.ref) for p in graph.recorded),
                     [real_slots[p] if p.type == "Real" else int_slots[p] for p in graph.recorded],
                     start, stop, h, n_steps)

    slaves: list[_Slave] = []
    rows = 0              # rows recorded so far
    t = start
    wall = 0.0
    with ExitStack() as stack:
        ctrl_c = stack.enter_context(_ctrl_c_latched())
        for inst in graph.instances:
            slave = _Slave(inst)
            slave.instantiate()
            stack.callback(slave.free)
            slaves.append(slave)
        by_name = {s.name: s for s in slaves}
        primes = _plan(slaves, graph, outputs_of, real_slots, int_slots,
                       (real_buf, int_buf), (real_in, int_in),
                       trapezoidal)
        terminated: list[_Slave] = []

        def terminate_all():
            for s in slaves:
                if s not in terminated:
                    s.terminate()
        stack.callback(terminate_all)

        def fail(slave: _Slave, function: str, status: int, when: float):
            slave.broken = status if status >= 3 else 0
            slave.failed = True
            raise SimulationError(
                f"{function} returned {STATUS.get(status, status)}"
                + (f" (FMU says: {slave.last_log()})" if slave.last_log() else ""),
                component=slave.name, time=when, status=STATUS.get(status, str(status)),
                results=layout.results(rec_real, rec_int, rows, experiment, wall, False))

        # ---- initialization: start values, then walk the links in dependency order
        current = None
        try:
            for s in slaves:
                current = s
                _setup_start_values(s)
                s.fmu.setupExperiment(startTime=start, stopTime=stop)
            for s in slaves:
                current = s
                s.fmu.enterInitializationMode()
            for link in graph.links:
                current = by_name[link.source.ref.instance]
                value = _get_one(current, link.source)
                current = by_name[link.target.ref.instance]
                _set_one(current, link.target, value)
            for s in slaves:
                current = s
                s.fmu.exitInitializationMode()
            for s in slaves:
                current = s
                for c_get, vrs, n, pointer in s.reads:
                    s.check("get", c_get(s.component, vrs, n, pointer))
        except (FMICallException, FmuCallError) as err:
            fail(current, err.function, err.status, start)
        rec_real[0] = real_buf
        rec_int[0] = int_buf
        rows = 1
        for prime in primes:
            prime()

        # ---- stepping: the hot loop; everything it touches was prepared above
        program = [(s, s.component, s.c_do_step, s.writes, s.reads) for s in slaves]
        tick = _time.perf_counter()
        next_report = tick + 1.0
        try:
            for k in range(n_steps):
                if ctrl_c[0]:
                    raise KeyboardInterrupt
                t = start + k * h
                h_k = h if k < n_steps - 1 else stop - t
                if jacobi:
                    real_in[:] = real_buf
                    int_in[:] = int_buf
                for s, comp, do_step, writes, reads in program:
                    for fill, c_set, vrs, n, pointer in writes:
                        if fill is not None:
                            fill()
                        st = c_set(comp, vrs, n, pointer)
                        if st > 1:
                            fail(s, "set", st, t)
                    st = do_step(comp, t, h_k, 1)
                    if st > 1:
                        fail(s, _step_failure(s), st, t)
                    for c_get, vrs, n, pointer in reads:
                        st = c_get(comp, vrs, n, pointer)
                        if st > 1:
                            fail(s, "get", st, t + h_k)
                rec_real[k + 1] = real_buf
                rec_int[k + 1] = int_buf
                rows = k + 2
                if progress is not None and not k & 255:
                    now = _time.perf_counter()
                    if now >= next_report:
                        progress((t - start) / (stop - start))
                        next_report = now + 0.5
            if ctrl_c[0]:                 # pressed during the last step
                raise KeyboardInterrupt
        except KeyboardInterrupt:
            wall = _time.perf_counter() - tick
            partial = layout.results(rec_real, rec_int, rows, experiment, wall, False)
            # the time of the last row kept (a step may have been recorded after `t` was set)
            raise Interrupted(float(partial.time[-1]), results=partial) from None
        wall = _time.perf_counter() - tick
        for s in slaves:
            s.terminate()
            terminated.append(s)
    return layout.results(rec_real, rec_int, rows, experiment, wall, True)


@dataclass
class _Layout:
    """Where each recorded column lives in the recorded buffers, and the time grid."""
    graph: Graph
    names: tuple[str, ...]
    slots: list[int]
    start: float
    stop: float
    h: float
    n_steps: int

    def results(self, rec_real, rec_int, rows, experiment, wall, complete) -> Results:
        """The structured array of the rows recorded so far (t0 row included)."""
        dtype = [("time", "f8")]
        for port in self.graph.recorded:
            dtype.append((str(port.ref), {"Real": "f8", "Integer": "i4"}.get(port.type, "?")))
        data = np.empty(rows, dtype=dtype)
        # t_k = start + k*h, computed, not accumulated; the last point is stop_time itself.
        times = self.start + np.arange(rows) * self.h
        if rows == self.n_steps + 1:
            times[-1] = self.stop
        data["time"] = times
        for name, port, slot in zip(self.names, self.graph.recorded, self.slots):
            source = rec_real if port.type == "Real" else rec_int
            data[name] = source[:rows, slot]
        return Results(self.names, data, experiment.master, experiment.start_time,
                       experiment.stop_time, experiment.step_size, max(rows - 1, 0), wall,
                       complete)


def _step_failure(slave: _Slave) -> str:
    """Name the failed call; say 'terminated early' only when the FMU itself says so."""
    terminated = ctypes.c_int(0)
    try:
        status = slave.fmu._functions["fmi2GetBooleanStatus"](
            slave.component, _fmi2Terminated, ctypes.byref(terminated))
    except Exception:   # an FMU may not export it at all
        return "fmi2DoStep"
    if status == 0 and terminated.value == 1:
        return "fmi2DoStep (the FMU terminated early)"
    return "fmi2DoStep"


def _get_one(slave: _Slave, port: Port):
    kind = port.type
    getter = {"Real": slave.fmu.getReal, "Integer": slave.fmu.getInteger,
              "Boolean": slave.fmu.getBoolean}[kind]
    return getter([port.vr])[0]


def _set_one(slave: _Slave, port: Port, value) -> None:
    setter = {"Real": slave.fmu.setReal, "Integer": slave.fmu.setInteger,
              "Boolean": slave.fmu.setBoolean}[port.type]
    setter([port.vr], [value])


def _plan(slaves, graph, outputs_of, real_slots, int_slots, outputs_to, inputs_from,
          trapezoidal: bool) -> list[Callable[[], None]]:
    """Preallocate, per instance and type, one batched get and one batched set.

    A get writes straight into the buffers `outputs_to` (Real, Int); a set takes its values
    from `inputs_from`: straight from the buffer when its
    sources sit in one contiguous run in the right order (the usual chain), else from a
    staging array filled by one np.take. With `trapezoidal`, a Real input that no output of
    its FMU depends on (it only drives the FMU's state over the step) takes the mean of its
    values at t_k and t_k+1: a trapezoidal hold, second order. t_k+1 is known when the source
    steps earlier in the Gauss-Seidel order; otherwise the mean is extrapolated from t_k and
    t_k-1 (1.5 u_k - 0.5 u_k-1). A Real input fed back from an FMU that steps later (e.g. a
    heading from an integrator) takes its value at t_k+1 extrapolated, 2 u_k - u_k-1, so the
    feedback stays second order. Returns the functions that seed the blends' history at t0.
    """
    position = {s.name: i for i, s in enumerate(slaves)}
    primes = []
    (real_out, int_out), (real_in, int_in) = outputs_to, inputs_from
    buffers = {"Real": (real_out, real_in, real_slots, ctypes.c_double, np.float64),
               "Integer": (int_out, int_in, int_slots, ctypes.c_int, np.int32),
               "Boolean": (int_out, int_in, int_slots, ctypes.c_int, np.int32)}
    for s in slaves:
        ports = outputs_of[s.name]
        for kind, c_get in (("Real", s.c_get_real), ("Integer", s.c_get_int),
                            ("Boolean", s.c_get_bool)):
            mine = [p for p in ports if p.type == kind]
            if mine:
                buf, _, slots, ctype, _ = buffers[kind]
                first = slots[mine[0]]
                # slots were handed out per instance and type: one contiguous run
                assert [slots[p] for p in mine] == list(range(first, first + len(mine)))
                s.reads.append((c_get, _vr_array([p.vr for p in mine]), len(mine),
                                _pointer(buf, first, ctype)))
        links = [l for l in graph.links if l.target.ref.instance == s.name]
        state_only = _state_only_inputs(s.inst) if trapezoidal else set()
        fed_back = {l.target.ref.variable for l in links
                    if position[l.source.ref.instance] > position[s.name]} if trapezoidal else set()
        blended = state_only | fed_back
        groups = (("Real", s.c_set_real, [l for l in links if l.target.type == "Real"
                                          and l.target.ref.variable not in blended]),
                  ("Blend", s.c_set_real, [l for l in links if l.target.type == "Real"
                                           and l.target.ref.variable in blended]),
                  ("Integer", s.c_set_int, [l for l in links if l.target.type == "Integer"]),
                  ("Boolean", s.c_set_bool, [l for l in links if l.target.type == "Boolean"]))
        for kind, c_set, mine in groups:
            if not mine:
                continue
            _, buf, slots, ctype, dtype = buffers["Real" if kind == "Blend" else kind]
            src = np.array([slots[l.source] for l in mine], dtype=np.intp)
            vrs = _vr_array([l.target.vr for l in mine])
            if kind == "Blend":
                staging = np.zeros(len(mine))
                weights = np.zeros((len(mine), 2 * len(mine)))
                for i, l in enumerate(mine):
                    upstream_first = position[l.source.ref.instance] < position[s.name]
                    weights[i, i], weights[i, len(mine) + i] = (
                        ((0.5, 0.5) if upstream_first else (1.5, -0.5))
                        if l.target.ref.variable in state_only else (2.0, -1.0))
                fill, prime = _blend(buf, src, weights, staging)
                primes.append(prime)
                s.writes.append((fill, c_set, vrs, len(mine), _pointer(staging, 0, ctype)))
            elif list(src) == list(range(src[0], src[0] + len(src))):
                s.writes.append((None, c_set, vrs, len(mine), _pointer(buf, int(src[0]), ctype)))
            else:
                staging = np.zeros(len(mine), dtype=dtype)
                s.writes.append((_take(buf, src, staging), c_set, vrs, len(mine),
                                 _pointer(staging, 0, ctype)))
    return primes


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
