"""The estimate's coarser runs, stepped on the run's own instances right after the run.

Every FMU's state at t0 (fmi2GetFMUstate after initialisation) is restored, the values at t0
are put back into the buffers and the holds primed again, then the same master steps at r h
(richardson.py chooses r and keeps the rows it compares). No reset, no instantiation, no
initialisation: the set-up is one fmi2SetFMUstate per FMU, where a fresh run re-creates every
slave. Each coarser run steps from the same t0 state, so its values are those of a run made
afresh (tests/test_estimate.py compares the two).
"""
from __future__ import annotations

import ctypes
import signal
import time as _time
from fractions import Fraction
from typing import Callable

import numpy as np

from ..errors import Interrupted
from ..results import Results
from ..runtime import STATUS
from ..scenario.graph import Graph
from .estimate import recorded_outputs
from .richardson import coarse_experiment, coarse_rows, coarse_sink
from .instance import RunningInstance
from .plan import Buffers, Holds
from .recorder import Recorder, step_count
from .stepping import (EndRequested, NonFinite, StepFailure, before_stop, free_states,
                       restore_states, save_states)


class Start:
    """The run's t0: every FMU's state and the buffers' values after initialisation, in
    states of their own (the quadratic master's rollback uses each instance's one saved
    state every step), and the coarser steps to take from it (estimate.coarse_plan, set
    where they are stepped: master._estimate_end)."""

    def __init__(self, running: list[RunningInstance], buffers: Buffers, t0: float):
        self.factors: tuple[Fraction, ...] = ()
        self.states = [ctypes.c_void_p() for _ in running]
        save_states(running, t0, self.states)
        self.running, self.buffers, self.t0 = running, buffers, t0
        self.real, self.ints = buffers.real.copy(), buffers.int.copy()

    def restore(self) -> None:
        restore_states(self.running, self.t0, self.states)
        self.buffers.real[:], self.buffers.int[:] = self.real, self.ints

    def free(self) -> None:
        """fmi2FreeFMUstate of the t0 states of the instances still usable."""
        usable = [(r, s) for r, s in zip(self.running, self.states) if not r.failed]
        try:
            free_states([r for r, _ in usable], self.t0, [s for _, s in usable])
        except StepFailure:     # the run's own outcome is what counts: it is reported
            pass


def coarse_runs(graph: Graph, results: Results, start: Start, holds: Holds,
                stepper: Callable[[Recorder], Callable[[], None]], ctrl_c: list) -> dict:
    """results.extra["coarse"]: per factor, the coarser run's (stepping seconds, times,
    {name: values}) or why it failed (a failure ends the coarser runs: the FMU that failed
    is not stepped again). `stepper(recorder)`: the master's stepping loop for a recorder.
    Ctrl-C or SIGTERM raises Interrupted with the run's complete results."""
    exp, names = graph.scenario.experiment, recorded_outputs(graph, results)
    runs: dict = {}
    for factor in start.factors:
        cexp = coarse_experiment(exp, factor)
        keep, parts = coarse_sink(cexp, names, results.time)
        recorder = Recorder(graph, cexp, start.buffers, step_count(cexp), keep, keep_rows=2)
        start.restore()
        recorder.record()
        holds.prime()
        tick = _time.perf_counter()
        try:
            with np.errstate(all="ignore"):
                stepper(recorder)()
        except StepFailure as err:
            err.running.mark_failed(err.status)
            runs[factor] = (f"{err.running.name}'s {err.running.function_name(err.function)} "
                            f"returned {STATUS.get(err.status, err.status)} at t = {err.time:g} s")
            break
        except NonFinite as err:
            runs[factor] = f"a value is not finite after the step that ended at {err.time:g} s"
            break
        except EndRequested as err:     # an FMU asked to end the run: where it should end?
            err.running.mark_failed(2)
            if before_stop(err.time, cexp):
                runs[factor] = f"{err.running.name} asked to end it at t = {err.time:g} s"
                break
        except KeyboardInterrupt:
            raise Interrupted(float(results.time[-1]), results=results,
                              terminated=ctrl_c[0] == signal.SIGTERM) from None
        wall = _time.perf_counter() - tick
        recorder.results(True)
        runs[factor] = coarse_rows(wall - recorder.sink_seconds, parts, names)
    return {"graph": graph, "runs": runs}
