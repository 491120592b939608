"""The co-simulation master: Graph -> Results.

simulate() prepares the instances and the value buffers (plan), initialises the FMUs, runs the
stepping loop (stepping) and hands back what the Recorder holds; every instance is terminated
and freed (or kept for reuse, see runtime) in all cases.
"""
from __future__ import annotations

import signal
import time as _time
from contextlib import ExitStack
from types import MappingProxyType
from typing import Callable

import numpy as np

from ..scenario.arguments import check_simulate
from ..errors import Interrupted, ScenarioError, SimulationError
from ..scenario.graph import Graph, adaptive_samples, rollback_problems
from ..masters import (DEFAULT_RELATIVE_TOLERANCE, DEFAULT_TOLERANCE, Master,
                       entry as master_entry)
from ..process import ctrl_c_latched
from ..results import Results
from ..runtime import RUNTIME, STATUS, release_instances
from ..scenario.document import Experiment
from .adaptive import NoProgress, estimate_of, step_adaptive
from .adaptive_holds import AdaptiveHolds
from .coarse import Start, coarse_runs
from .estimate import coarse_plan, error_estimate, pair_tap, steps_coarser, wants_pair
from .instance import FmuCallError, RunningInstance
from .pair_rows import PairRows
from .plan import Buffers, Holds, plan_transfers
from .memory import (AtStart, advice, hidden_at_start, lazy_at_start, probe_at_start,
                     used_outputs)
from .probe import prober
from .recorder import Recorder, step_count
from .stepping import (EndRequested, NonFinite, StepFailure, asked_to_end, before_stop,
                       check_finite, initialise, settled_end, step_all)

__all__ = ["simulate", "estimate_error", "release_instances", "RUNTIME"]


def simulate(graph: Graph, experiment: Experiment,
             progress: Callable[[float], None] | None = None, *,
             sink: Callable[[np.ndarray], None] | None = None,
             keep_rows: int | None = None, with_estimate: bool = False) -> Results:
    """Run the graph. Raises SimulationError (with the partial Results) when an FMU fails or
    a Real value stops being finite, Interrupted on Ctrl-C or SIGTERM; every instance is
    terminated and freed in all cases.

    `sink` gets the recorded rows as they come, in chunks (structured arrays; every row has
    reached it when simulate returns or raises, except when the sink itself raises, which
    ends the run with that exception). `keep_rows`: the returned Results hold every row
    (None, the default) or about that many evenly spaced rows plus the exact last one.
    `with_estimate`: a complete run also steps the error estimate's coarser runs on its own
    instances, restored to t0 (coarse.py), for estimate_error; without, or where an FMU
    cannot save its state, estimate_error makes them afresh.
    Wrong arguments raise errors.ArgumentError before anything is extracted."""
    check_simulate(graph, experiment, progress, sink, keep_rows)
    how = master_entry(experiment.master)
    buffers = Buffers(graph, freeze=how.freezes_inputs)
    recorder = Recorder(graph, experiment, buffers, step_count(experiment), sink, keep_rows)
    with ExitStack() as stack:
        ctrl_c = stack.enter_context(ctrl_c_latched())
        running = _start_instances(graph, stack)
        holds = plan_transfers(running, graph, buffers, how.hold, _adaptive_holds(how, graph),
                               how.holds_samples)
        stack.callback(lambda: [r.terminate() for r in running])
        _initialise(running, graph, experiment, buffers, recorder)
        holds = _held_at_end(how, graph, running, buffers, recorder, holds)
        _ = graph.breaks    # cached; the stepping reads them: run set-up, not the estimate
        pair, start = (_estimate_start(graph, experiment, running, buffers, recorder, stack,
                                       _rolls_back_loops(how, running, holds))
                       if with_estimate else (None, None))
        recorder.record()
        holds.prime()
        stepper, counts = _stepper(how, running, recorder, ctrl_c, progress, holds)
        ended = _run_loop(recorder, ctrl_c, buffers, stepper)
        results = recorder.results(True)
        if holds.held_at_end:
            results.extra["held_at_end"] = dict(holds.held_at_end)
        if holds.hidden:
            results.extra["hidden_state"] = sorted(holds.hidden)
        if ended:
            results.extra["ended"] = ended
        elif with_estimate:
            _estimate_end(results, pair, start, running, recorder, holds,
                          lambda rec: _stepper(how, running, rec, ctrl_c, None, holds)[0],
                          ctrl_c)
        if counts:
            results.steps_taken, results.steps_rejected = (counts["steps_taken"],
                                                           counts["steps_rejected"])
            results.extra["error_estimate"] = estimate_of(counts["names"], results, counts)
            results.extra["passes"] = counts["passes"]
            if counts.get("flat_at") is not None:
                results.extra["flat_at"] = counts["flat_at"]
        return results


def _estimate_end(results: Results, pair, start: Start | None,
                  running: list[RunningInstance], recorder: Recorder, holds: Holds,
                  stepper, ctrl_c) -> None:
    """The estimate's part after a complete run: the pair's finish (results.extra["pair"])
    and, where it does not hold and the t0 was kept, Richardson's coarser runs stepped on
    the run's own instances (results.extra["coarse"])."""
    graph = recorder.graph
    found = _finish(pair, running, graph, recorder.buffers)
    if isinstance(pair, PairRows):
        found["advice"] = advice(pair.plan, used_outputs(graph))
    if recorder.probe is not None:      # its probes ran inside the stepping loop
        found["seconds"] += recorder.probe.seconds
        found["probe_seconds"] = recorder.probe.seconds
        found["probe_calls"] += recorder.probe.calls
    results.extra["pair"] = {"graph": graph, "found": found}
    if start is not None and not (isinstance(found, dict) and found["failed"] is None):
        # after a rough hand-over the runs at h/2 and h/3 (coarse_plan)
        start.factors = coarse_plan(graph, recorder.experiment,
                                    rough=isinstance(found, dict) and found.get("rough"))
        results.extra["coarse"] = coarse_runs(graph, results, start, holds, stepper, ctrl_c)


def _finish(pair, running: list[RunningInstance], graph: Graph, buffers: Buffers):
    """The pair's finish() (or why there is none); under Jacobi on a chain, with the late
    outputs' values at the last node read after the run first (stepping.settled_end,
    PairRows.settle_end; in the estimate's time): the end is then not extrapolated past the
    rows, and the pass is a plain one."""
    if not isinstance(pair, PairRows):
        return pair
    if pair.wants_end:
        tick = _time.perf_counter()
        settled = settled_end(running, graph, buffers.real)
        if settled is not None:
            pair.settle_end(settled[pair.plan.slots])
        pair.seconds += _time.perf_counter() - tick
    return pair.finish()


def _initialise(running: list[RunningInstance], graph: Graph, exp: Experiment,
                buffers: Buffers, recorder: Recorder) -> None:
    """stepping.initialise, and every value at t0 finite; else the run fails (SimulationError,
    the rows so far kept)."""
    try:
        initialise(running, graph, exp.start_time, exp.stop_time)
        check_finite(buffers.real, exp.start_time)
    except FmuCallError as err:
        raise _failure(err.running, err.function, err.status, exp.start_time,
                       recorder) from None
    except NonFinite as err:
        raise _not_finite(buffers, err.time, recorder) from None


def _held_at_end(how: Master, graph: Graph, running: list[RunningInstance], buffers: Buffers,
                 recorder: Recorder, holds: Holds) -> Holds:
    """The adaptive master's holds, planned again where the probes at t0 find third-party
    outputs, recorded or read by another FMU, worked out in doStep alone
    (memory.lazy_at_start): such an output reads the step mean a "through" hold sets, its
    value hanging on each step's length; those FMUs' inputs are held at their end values
    instead (first order: AdaptiveHolds.richardson; results.extra["held_at_end"]). Or
    FMUs whose outputs declare inputs only holding a state (memory.hidden_at_start): their
    inputs are held as a state's (results.extra["hidden_state"])."""
    if not (how.adaptive and graph.measured):
        return holds
    exp = recorder.experiment
    at = (running, buffers.real_slots, buffers.real, exp.start_time, exp.step_size)
    room = int((exp.stop_time - exp.start_time) / exp.step_size + 1e-9) - 1
    try:
        found, hidden = lazy_at_start(graph, *at, room), hidden_at_start(graph, *at)
    except StepFailure as err:      # a probe's call: Error or worse
        raise _failed_at_t0(err, exp, recorder) from None
    if not (found or hidden):
        return holds
    for r in running:
        r.reads, r.writes, r.resets, r.settles = [], [], [], []
    holds = _adaptive_holds(how, graph)
    holds.held_at_end, holds.hidden = MappingProxyType(found), hidden
    return plan_transfers(running, graph, buffers, how.hold, holds, how.holds_samples)


def _failed_at_t0(err: StepFailure, exp: Experiment, recorder: Recorder) -> SimulationError:
    """The run's failure where a probe's or a state save's call before the first step
    returned Error or worse: the t0 row kept (every FMU was initialised), no estimate."""
    recorder.tap = recorder.probe = None
    recorder.record()
    return _failure(err.running, err.function, err.status, exp.start_time, recorder)


def _adaptive_holds(how: Master, graph: Graph) -> AdaptiveHolds | None:
    """The adaptive master's holds, which check the held inputs for smooth curves where the
    graph holds FMUs the scenario layer knows nothing of (Graph.measured)."""
    return AdaptiveHolds(how.hold, graph.error_models, bool(graph.measured)) \
        if how.adaptive else None


def _stepper(how: Master, running: list[RunningInstance], recorder: Recorder, ctrl_c,
             progress, holds: Holds) -> tuple[Callable[[], None], dict]:
    """The stepping loop of this master, and the adaptive master's step counts."""
    if not how.adaptive:
        freeze = recorder.buffers.freeze if recorder.buffers.frozen else None
        return (lambda: step_all(running, recorder, ctrl_c, freeze, progress, holds,
                                 _rolls_back_loops(how, running, holds))), {}
    graph = recorder.graph
    exp = recorder.experiment
    refused = rollback_problems(graph.scenario.label, how.name, exp.tolerance,
                                [r.name for r in running if not r.can_roll_back],
                                "no fmi2Get/SetFMUstate or canGetAndSetFMUstate false") or \
        adaptive_samples(graph, how.name, exp.tolerance)
    if refused:
        raise ScenarioError(refused)
    counts = {"steps_taken": 0, "steps_rejected": 0, "passes": 0}
    tol = (exp.tolerance or DEFAULT_TOLERANCE,
           DEFAULT_RELATIVE_TOLERANCE if exp.relative_tolerance is None
           else exp.relative_tolerance)
    return (lambda: step_adaptive(running, recorder, ctrl_c, progress, holds, tol, counts)
            ), counts


def _rolls_back_loops(how: Master, running: list[RunningInstance], holds: Holds) -> bool:
    """Whether a fixed-step run predicts, rolls back and corrects each step: its master does
    so in a loop, some input's next value is unknown when its FMU steps, and every FMU can
    get and set its state."""
    return holds.ahead and how.rolls_back and all(r.can_roll_back for r in running)


def _estimate_start(graph: Graph, exp: Experiment, running: list[RunningInstance],
                    buffers: Buffers, recorder: Recorder, stack: ExitStack,
                    rolled_back: bool) -> tuple:
    """The estimate, set up before the run steps: the embedded pair's tap on the recorder
    (PairRows, or why there is none: estimate.pair_tap), and the t0 Richardson's coarser
    runs start from, where they may be needed (the pair does not apply, or may find after
    the run that it does not). `rolled_back`: _rolls_back_loops, how the pair rebuilds the
    hold of a loop's inputs. The pair's seconds count this set-up too."""
    tick = _time.perf_counter()
    try:
        found = probe_at_start(graph, running, buffers.real_slots, buffers.real,
                               exp.start_time, exp.step_size) \
            if wants_pair(graph, exp) else AtStart()
        pair = found.refuted or pair_tap(graph, exp, buffers.real_slots, recorder.n_steps,
                                         rolled_back, found.memoryless)
        if isinstance(pair, PairRows):
            pair.probe_calls = found.calls
            recorder.tap = pair
            recorder.probe = prober(pair.plan, running, buffers.real, recorder.n_steps)
        needs_t0 = not isinstance(pair, PairRows) or pair.may_fail
        start = _start(graph, exp, running, buffers, stack) if needs_t0 else None
    except StepFailure as err:      # a probe's or a state save's call: Error or worse
        raise _failed_at_t0(err, exp, recorder) from None
    if isinstance(pair, PairRows):
        pair.seconds += _time.perf_counter() - tick
    return pair, start


def _start(graph: Graph, exp: Experiment, running: list[RunningInstance], buffers: Buffers,
           stack: ExitStack) -> Start | None:
    """The t0 the estimate's coarser runs start from (coarse.Start, freed with the run), or
    None where it makes none or an FMU cannot save its state."""
    if not steps_coarser(graph, exp) or not all(r.can_roll_back for r in running):
        return None
    try:
        start = Start(running, buffers, exp.start_time)
    except StepFailure as err:  # an FMU that says it can and cannot: the estimate runs
        if err.status > 2:      # afresh; after Error or worse FMI allows it nothing more
            raise
        return None
    stack.callback(start.free)
    return start


def _start_instances(graph: Graph, stack: ExitStack) -> list[RunningInstance]:
    running = []
    for inst in graph.instances:
        r = RunningInstance(inst)
        r.instantiate()
        stack.callback(r.free)
        running.append(r)
    return running


def _run_loop(recorder: Recorder, ctrl_c, buffers: Buffers, stepper: Callable[[], None]
              ) -> dict | None:
    """Step the run; where an FMU asked to end it before its stop time, how it ended
    (_ended), else None."""
    tick = _time.perf_counter()
    try:
        with np.errstate(all="ignore"):     # an overflow is reported as a non-finite value
            stepper()
    except EndRequested as err:
        recorder.wall = _time.perf_counter() - tick - recorder.sink_seconds
        return _ended(err.running, err.time, recorder)
    except StepFailure as err:
        recorder.wall = _time.perf_counter() - tick - recorder.sink_seconds
        if not np.isfinite(buffers.real).all():   # the cause: a value that went non-finite
            err.running.mark_failed(err.status)
            raise _not_finite(buffers, err.end, recorder, then=(
                f"; then {err.running.name}'s {err.running.function_name(err.function)} returned "
                f"{STATUS.get(err.status, err.status)}")) from None
        if asked_to_end(err):   # in a step the run does not keep: it ends at its last row
            return _ended(err.running, recorder.last_time, recorder, err.time)
        raise _failure(err.running, err.function, err.status, err.time, recorder) from None
    except NonFinite as err:
        recorder.wall = _time.perf_counter() - tick - recorder.sink_seconds
        raise _not_finite(buffers, err.time, recorder) from None
    except NoProgress as err:
        recorder.wall = _time.perf_counter() - tick - recorder.sink_seconds
        raise SimulationError(
            f"the tolerance needs a step of {err.wanted:.3g} s here, below the smallest step "
            f"the adaptive master takes ({err.smallest:.3g} s: 1e-9 of the output interval, "
            f"or 64 round-offs of t); loosen the tolerance (--tolerance, "
            f"experiment.tolerance, relative_tolerance)", time=err.time, status="no progress",
            results=recorder.results(False)) from None
    except KeyboardInterrupt:
        recorder.wall = _time.perf_counter() - tick - recorder.sink_seconds
        partial = recorder.results(False)
        # the time of the last row kept (a step may have been recorded after `t` was set)
        raise Interrupted(float(partial.time[-1]), results=partial,
                          terminated=ctrl_c[0] == signal.SIGTERM) from None
    recorder.wall = _time.perf_counter() - tick - recorder.sink_seconds
    return None


def _ended(r: RunningInstance, time: float, recorder: Recorder,
           short: float | None = None) -> dict | None:
    """An FMU asked to end the simulation (fmi2Discard with fmi2Terminated, fmi3DoStep's
    terminateSimulation; stepping.asked_to_end), as FMPy and the FMI standard take it: the run
    ends at `time`, its last row, and is complete there (`short`: the start of the step in
    which it asked, where the run does not keep that step: a predictor's, the adaptive
    master's try). That FMU is freed, never kept for reuse. At the stop
    time it is a plain end (None); before it, results.extra["ended"]: who asked and when.
    The pair's tap is let go (it was laid out for the whole run): the estimate is made on
    the run to `time` (estimate.error_estimate)."""
    r.mark_failed(2)
    if not before_stop(time, recorder.experiment):
        return None
    recorder.tap = None
    how = ("its fmi3DoStep set terminateSimulation" if r.fmi3 else
           "its fmi2DoStep returned Discard, and fmi2Terminated is true")
    return {"by": r.name, "time": time, "how": how if short is None else
            f"{how} in the step from t = {short:g} s, which the run does not keep"}


def _not_finite(buffers: Buffers, when: float, recorder: Recorder,
                then: str = "") -> SimulationError:
    """Name the first value that is not finite, in the stepping order (the slots of each
    instance are contiguous, in order): the one that produced it, the others got it."""
    slot = int(np.flatnonzero(~np.isfinite(buffers.real))[0])
    port = next(p for p, s in buffers.real_slots.items() if s == slot)
    return SimulationError(
        f"output {port.ref.variable} = {float(buffers.real[slot])!r} is not a finite number (an "
        f"overflow or an invalid operation; check the parameters and inputs of this "
        f"component); the run stops at the step that produced it{then}",
        component=port.ref.instance, time=when, status="not finite",
        results=recorder.results(False))


_STATE_HINT = ("; the FMU declares canGetAndSetFMUstate, and the error estimate (its probes, "
               "its coarser runs) and the quadratic master's rollback save states: --estimate "
               "none with the gauss-seidel master saves none")


def _failure(r: RunningInstance, function: str, status: int, when: float,
             recorder: Recorder) -> SimulationError:
    r.mark_failed(status)
    said = r.log.last()
    return SimulationError(
        f"{r.function_name(function)} returned {STATUS.get(status, status)}"
        + (f" (FMU says: {said})" if said else "") + (_STATE_HINT if "FMUstate" in function
                                                      else ""),
        component=r.name, time=when, status=STATUS.get(status, str(status)),
        results=recorder.results(False))


def estimate_error(graph: Graph, results: Results) -> dict:
    """The run's coupling error, for summary.json (master/estimate.py): the embedded pair
    from the run's own rows (pair.py), or where it does not apply the graph stepped again at
    two coarser steps (richardson.py), or the adaptive master's own. A run made without
    with_estimate=True is made again for it."""
    return error_estimate(graph, results, simulate)
