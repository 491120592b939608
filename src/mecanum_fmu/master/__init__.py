"""The co-simulation master: Graph -> Results.

simulate() prepares the instances and the value buffers (plan), initialises the FMUs, runs the
stepping loop (stepping) and hands back what the Recorder holds; every instance is terminated
and freed (or kept for reuse, see runtime) in all cases.
"""
from __future__ import annotations

import time as _time
from contextlib import ExitStack
from typing import Callable

from ..errors import Interrupted, SimulationError
from ..graph import Graph
from ..results import Results
from ..runtime import RUNTIME, STATUS, release_instances
from ..scenario import Experiment
from .instance import FmuCallError, RunningInstance
from .plan import Buffers, plan_transfers
from .recorder import Recorder, step_count
from .stepping import StepFailure, ctrl_c_latched, initialise, step_all

__all__ = ["simulate", "release_instances", "RUNTIME"]


def simulate(graph: Graph, experiment: Experiment,
             progress: Callable[[float], None] | None = None) -> Results:
    """Run the graph. Raises SimulationError (with the partial Results) when an FMU fails,
    Interrupted on Ctrl-C; every instance is terminated and freed in all cases."""
    buffers = Buffers(graph, jacobi=experiment.master == "jacobi")
    recorder = Recorder(graph, experiment, buffers, step_count(experiment))
    with ExitStack() as stack:
        ctrl_c = stack.enter_context(ctrl_c_latched())
        running = _start_instances(graph, stack)
        primes = plan_transfers(running, graph, buffers, experiment.master == "trapezoidal")
        stack.callback(lambda: [r.terminate() for r in running])
        try:
            initialise(running, graph, experiment.start_time, experiment.stop_time)
        except FmuCallError as err:
            raise _failure(err.running, err.function, err.status, experiment.start_time,
                           recorder) from None
        recorder.record()
        for prime in primes:
            prime()
        _run_loop(running, recorder, ctrl_c, buffers, progress)
    return recorder.results(True)


def _start_instances(graph: Graph, stack: ExitStack) -> list[RunningInstance]:
    running = []
    for inst in graph.instances:
        r = RunningInstance(inst)
        r.instantiate()
        stack.callback(r.free)
        running.append(r)
    return running


def _run_loop(running, recorder: Recorder, ctrl_c, buffers: Buffers, progress) -> None:
    freeze = buffers.freeze if recorder.experiment.master == "jacobi" else None
    tick = _time.perf_counter()
    try:
        step_all(running, recorder, ctrl_c, freeze, progress)
    except StepFailure as err:
        recorder.wall = _time.perf_counter() - tick
        raise _failure(err.running, err.function, err.status, err.time, recorder) from None
    except KeyboardInterrupt:
        recorder.wall = _time.perf_counter() - tick
        partial = recorder.results(False)
        # the time of the last row kept (a step may have been recorded after `t` was set)
        raise Interrupted(float(partial.time[-1]), results=partial) from None
    recorder.wall = _time.perf_counter() - tick


def _failure(r: RunningInstance, function: str, status: int, when: float,
             recorder: Recorder) -> SimulationError:
    r.mark_failed(status)
    said = r.log.last()
    return SimulationError(
        f"{function} returned {STATUS.get(status, status)}"
        + (f" (FMU says: {said})" if said else ""),
        component=r.name, time=when, status=STATUS.get(status, str(status)),
        results=recorder.results(False))
