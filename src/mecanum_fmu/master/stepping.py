"""Initialisation and the stepping loop over prepared instances."""
from __future__ import annotations

import ctypes
import time as _time
from typing import Callable

import numpy as np
from fmpy.fmi1 import FMICallException

from ..scenario.graph import Graph, port_type
from .breakpoints import Cut, graph_breaks, step_cuts
from .instance import FmuCallError, RunningInstance
from .plan import Holds
from .recorder import Recorder


def _guarded(r: RunningInstance, action: Callable[[], None]) -> None:
    """Run an fmpy call on r; an FMI error becomes an FmuCallError that names r."""
    try:
        action()
    except FMICallException as err:
        raise FmuCallError(r, err.function, err.status) from None


def _set_start_values(r: RunningInstance) -> None:
    variables = {v.name: v for v in r.inst.model.modelVariables}
    for name, value in r.inst.start_values.items():
        var = variables[name]
        setter = {"Real": r.fmu.setReal, "Integer": r.fmu.setInteger,
                  "Boolean": r.fmu.setBoolean, "String": r.fmu.setString}[port_type(var)]
        setter([var.valueReference], [value])


def initialise(running: list[RunningInstance], graph: Graph, start: float, stop: float) -> None:
    """Start values, initialization mode, the links walked in dependency order (so that t0 is
    consistent), then every output read once into the buffers. Raises FmuCallError."""
    by_name = {r.name: r for r in running}
    for r in running:
        _guarded(r, lambda: _set_start_values(r))
        _guarded(r, lambda: r.fmu.setupExperiment(startTime=start, stopTime=stop))
    for r in running:
        _guarded(r, r.fmu.enterInitializationMode)
    for link in graph.links:
        source, target = by_name[link.source.ref.instance], by_name[link.target.ref.instance]
        value = []
        _guarded(source, lambda: value.append(source.get_one(link.source)))
        _guarded(target, lambda: target.set_one(link.target, value[0]))
    for r in running:
        _guarded(r, r.fmu.exitInitializationMode)
    for r in running:
        for c_get, vrs, n, pointer in r.reads:
            r.call("get", c_get(r.component, vrs, n, pointer))


def settled_end(running: list[RunningInstance], graph: Graph, real: np.ndarray
                ) -> np.ndarray | None:
    """After the run's last step, each FMU whose outputs its inputs move (in step order, the
    graph's dependency order) set its sources' newest values, no doStep, and its outputs
    read again, as initialise walks the links at t0. An output with direct feedthrough then
    shows its value for inputs of the last time (FMI 2.0 lets a master read it so, as
    settle does after a sample), which under Jacobi its rows reach only steps later. The
    Real buffer after it (a copy), the run's own `real` left as it was; None where a call
    fails (an FMU whose call returned Error or Fatal is marked failed: FMI allows nothing
    more of it)."""
    by_name, saved = {r.name: r for r in running}, real.copy()
    try:
        for r in running:       # in step order: only FMUs whose outputs their inputs move
            if any(u.dependencies != [] for u in r.inst.model.outputs):
                _settle_one(r, [l for l in graph.links if l.target.ref.instance == r.name],
                            by_name)
                for c_get, vrs, n, pointer in r.reads:
                    r.call("get", c_get(r.component, vrs, n, pointer))
        return real.copy()
    except FmuCallError as err:
        if err.status >= 3:
            err.running.mark_failed(err.status)
        return None
    finally:
        real[:] = saved


def _settle_one(target: RunningInstance, links: list, by_name: dict) -> None:
    """Set target's linked inputs to their sources' values now: the Reals in one call, read
    by one call per source. Raises FmuCallError."""
    reals = [l for l in links if l.source.type == l.target.type == "Real"]
    for link in (l for l in links if l not in reals):
        source, value = by_name[link.source.ref.instance], []
        _guarded(source, lambda: value.append(source.get_one(link.source)))
        _guarded(target, lambda: target.set_one(link.target, value[0]))
    if not reals:
        return
    values = (ctypes.c_double * len(reals))()
    for name in dict.fromkeys(l.source.ref.instance for l in reals):
        mine = [i for i, l in enumerate(reals) if l.source.ref.instance == name]
        got, source = (ctypes.c_double * len(mine))(), by_name[name]
        vrs = (ctypes.c_uint * len(mine))(*(reals[i].source.vr for i in mine))
        source.call("get", source.c_get["Real"](source.component, vrs, len(mine), got))
        for i, v in zip(mine, got):
            values[i] = v
    vrs = (ctypes.c_uint * len(reals))(*(l.target.vr for l in reals))
    target.call("set", target.c_set["Real"](target.component, vrs, len(reals), values))


class NonFinite(Exception):
    """The Real buffer holds NaN or an infinity after the step that ended at `time`."""

    def __init__(self, time: float):
        self.time = time


def check_finite(real, time: float) -> None:
    """Raise NonFinite when a Real value is NaN or infinite (initialisation, tests)."""
    if not np.isfinite(real).all():
        raise NonFinite(time)


class StepFailure(Exception):
    """A call in the stepping loop returned Discard or worse."""

    def __init__(self, running: RunningInstance, function: str, status: int, time: float,
                 end: float):
        self.running, self.function, self.status, self.time = running, function, status, time
        self.end = end      # the end of the step under way


def step_all(running: list[RunningInstance], recorder: Recorder, ctrl_c: list[bool],
             freeze: Callable[[], None] | None, progress: Callable[[float], None] | None,
             holds: Holds, rollback: bool) -> None:
    """The hot loop: everything it touches was prepared. With `rollback`, every step is taken
    twice: predicted, rolled back to t_k (fmi2SetFMUstate), corrected (plan.HOLDS). A step
    that ends on a jump is taken in pieces (jump_cuts). Raises StepFailure, NonFinite,
    KeyboardInterrupt."""
    exp = recorder.experiment
    start, stop, h, n_steps = exp.start_time, exp.stop_time, exp.step_size, recorder.n_steps
    program = programs(running)
    record, commit = recorder.record, (holds.commit if holds.blends else None)
    buffers = recorder.buffers
    held = bool(buffers.held_slots)      # a sample an FMU holds (plan.Buffers.hold)
    settling = [p for p in program if p[0].settles]
    cuts = jump_cuts(recorder.graph, exp, n_steps) if freeze is None else {}
    # One dot product per step finds any NaN or infinity in the Real values (0 * inf is NaN,
    # 0 * finite is 0, and a sum of zeros cannot overflow).
    real_dot, zeros = recorder.buffers.real.dot, np.zeros_like(recorder.buffers.real)
    next_report = _time.perf_counter() + 1.0
    probe = recorder.probe
    probe_at = probe.at if probe is not None else ()
    ending = None
    for k in range(n_steps):
        if ctrl_c[0]:
            raise KeyboardInterrupt
        t = start + k * h
        h_k = h if k < n_steps - 1 else stop - t
        if k in probe_at:
            probe(k, t, h)
        if freeze is not None:
            freeze()
        if held:
            buffers.hold()
        if k in cuts:
            _pieces(running, program, holds, rollback, t, t + h_k, cuts[k], real_dot, zeros)
        else:
            if rollback:
                _predict(running, program, holds, t, h_k)
            try:
                one_pass(program, t, h_k)
            except StepFailure as err:
                ending = finish_pass(err, program, t, h_k)
            if commit is not None:
                commit()
            if real_dot(zeros) != 0.0:
                raise NonFinite(t + h_k)
        if held and buffers.changed():
            settle(settling, buffers, holds, t + h_k)
            if real_dot(zeros) != 0.0:
                raise NonFinite(t + h_k)
        record()
        if ending is not None:
            raise EndRequested(ending, t + h_k)
        if progress is not None and not k & 255:
            now = _time.perf_counter()
            if now >= next_report:
                progress((t - start) / (stop - start))
                next_report = now + 0.5
    if ctrl_c[0]:                 # pressed during the last step
        raise KeyboardInterrupt


class EndRequested(Exception):
    """An FMU asked to end the simulation (RunningInstance.ends_run) in the step that ends at
    `time`, and the step was completed: the run's last row is at `time`."""

    def __init__(self, running: RunningInstance, time: float):
        super().__init__(running.name, time)
        self.running, self.time = running, time


def before_stop(time: float, exp) -> bool:
    """Whether a run that an FMU ended at `time` ended before exp's stop time (else it is a
    plain end: the FMU asked on the last step)."""
    return time < exp.stop_time - 1e-9 * exp.step_size


def asked_to_end(err: "StepFailure") -> bool:
    """Whether the doStep that failed asked to end the simulation and got to its step's
    end: fmi2Discard with fmi2Terminated true and fmi2LastSuccessfulTime there (the
    Reference FMUs' Stair), or fmi3DoStep's terminateSimulation with no early return. One
    that stopped short is a failed step: pythonfmu's do_step that returns False says
    fmi2Terminated too, at the step's start."""
    r = err.running
    return err.status == 2 and r.ends_run() and r.reached(err.end, err.end - err.time)


def finish_pass(err: "StepFailure", program: list, t: float, h_k: float) -> RunningInstance:
    """The pass in which an FMU's doStep asked to end the simulation (asked_to_end): that
    FMU's outputs read, the FMUs after it set their inputs and stepped as in any pass. The
    FMU that asked, or err raised again where its doStep failed otherwise."""
    r = err.running
    if err.time != t or not asked_to_end(err):
        raise err
    i = next(i for i, entry in enumerate(program) if entry[0] is r)
    for c_get, vrs, n, pointer in r.reads:
        if c_get(r.component, vrs, n, pointer) > 1:
            raise err
    one_pass(program[i + 1:], t, h_k)
    return r


def jump_cuts(graph: Graph, exp, n_steps: int) -> dict[int, Cut]:
    """The steps that end on (or start just before) a jump or a breakpoint that may be one
    (an expression's comparison with t, a path's row): breakpoints.step_cuts. A kink needs no
    cut (the limited holds integrate a piecewise-linear input exactly)."""
    breaks = graph_breaks(graph)
    return step_cuts(breaks.taken_as_jumps(), exp.start_time,
                     exp.step_size, n_steps, exp.stop_time)


def settle(settling: list, buffers, holds: Holds, t: float) -> None:
    """A held discrete output (a sample) changed in the step that ended at t: each instance
    whose outputs it moves at once (Graph.settled; `settling`: their entries of programs(),
    in step order) is set its newest inputs, the new sample among them, and its outputs are
    read again, with no doStep (an output with direct feedthrough follows its inputs at
    once). The outputs made from the sample jump at t: the step's blends took their left
    values, the next step starts from the right ones, the holds' history moved by the jump
    (Holds.shift)."""
    for r, comp, _, _, _, reads in settling:
        buffers.hold()          # the newest values, those settled before it among them
        _set(r, comp, r.settles, t, 0.0)
        for c_get, vrs, n, pointer in reads:
            st = c_get(comp, vrs, n, pointer)
            if st > 1:
                raise StepFailure(r, "get", st, t, t)
    holds.shift()


def _pieces(running: list[RunningInstance], program: list, holds: Holds, rollback: bool,
            t: float, end: float, cut: Cut, real_dot, zeros) -> None:
    """One step taken in pieces, t -> cut.inside... -> end, each predicted and corrected as
    a whole step would be and committed; the holds restart after a piece flagged so (its
    values become their whole history: none from before the jump enters a blend after it)."""
    for until, restart in zip((*cut.inside, end), cut.restart):
        if rollback:
            _predict(running, program, holds, t, until - t)
        one_pass(program, t, until - t)
        if holds.blends:
            holds.prime() if restart else holds.commit()
        if real_dot(zeros) != 0.0:
            raise NonFinite(until)
        t = until


def programs(running: list[RunningInstance]) -> list:
    """What one_pass walks: per instance in step order, its component, doStep and transfers."""
    return [(r, r.component, r.c_do_step, r.writes, r.resets, r.reads) for r in running]


def one_pass(program: list, t: float, h_k: float) -> None:
    """Every instance in step order: set its inputs, step it, set the inputs it holds at
    their mean during the step to their end values (resets: the adaptive master's, plan.py),
    read its outputs."""
    for r, comp, do_step, writes, resets, reads in program:
        _set(r, comp, writes, t, h_k)
        st = do_step(comp, t, h_k, 1)
        if st > 1:
            raise StepFailure(r, r.step_failure(), st, t, t + h_k)
        if resets:
            _set(r, comp, resets, t, h_k)
        for c_get, vrs, n, pointer in reads:
            st = c_get(comp, vrs, n, pointer)
            if st > 1:
                raise StepFailure(r, "get", st, t + h_k, t + h_k)


def _set(r: RunningInstance, comp, writes: list, t: float, h_k: float) -> None:
    for fill, c_set, vrs, n, pointer in writes:
        if fill is not None:
            fill()
        st = c_set(comp, vrs, n, pointer)
        if st > 1:
            raise StepFailure(r, "set", st, t, t + h_k)


def save_states(running: list[RunningInstance], t: float, states: list | None = None) -> None:
    """fmi2GetFMUstate of every instance, into its one saved state (RunningInstance.state)
    or into `states` (a ctypes.c_void_p per instance)."""
    refs = [r.state_ref for r in running] if states is None else map(ctypes.byref, states)
    for r, ref in zip(running, refs):
        _state_call(r, "fmi2GetFMUstate", r.c_get_state(r.component, ref), t)


def restore_states(running: list[RunningInstance], t: float, states: list | None = None
                   ) -> None:
    """fmi2SetFMUstate of every instance: back to the state save_states saved at t."""
    for r, s in zip(running, [r.state for r in running] if states is None else states):
        _state_call(r, "fmi2SetFMUstate", r.c_set_state(r.component, s), t)


def free_states(running: list[RunningInstance], t: float, states: list | None = None) -> None:
    """fmi2FreeFMUstate of every instance's saved state."""
    refs = [r.state_ref for r in running] if states is None else map(ctypes.byref, states)
    for r, ref in zip(running, refs):
        _state_call(r, "fmi2FreeFMUstate", r.c_free_state(r.component, ref), t)


def _predict(running: list[RunningInstance], program: list, holds: Holds, t: float,
             h_k: float) -> None:
    """Save every instance's state, take the step with the predictor's inputs (the buffers
    then hold the predicted values at t_k+1), roll every instance back to t_k."""
    save_states(running, t)
    holds.mode = holds.PREDICT
    one_pass(program, t, h_k)
    restore_states(running, t)
    free_states(running, t)
    holds.mode = holds.CORRECT


def _state_call(r: RunningInstance, function: str, status: int, t: float) -> None:
    if status > 1:
        raise StepFailure(r, function, status, t, t)
