"""What runs on a Dask worker: a batch of runs of one compiled graph.

Per run only the varied start values change: they are applied to the already compiled graph
(a new Instance with merged start values, nothing re-read or re-checked here; the client
checked every value with the scenario's rules). master.simulate unpacks each FMU once per
process and reuses instances across runs (fmi2Reset), so a worker pays the FMU set-up once.
"""
from __future__ import annotations

import dataclasses
import tempfile
import time
from dataclasses import dataclass

import numpy as np
from distributed import WorkerPlugin

from .. import master
from ..runtime import RUNTIME
from ..errors import MecanumError
from ..scenario.graph import Graph
from ..scenario.document import Scalar, VarRef

PATH_POINTS = 101        # points kept per path for the overlaid-paths plot


@dataclass
class RunResult:
    index: int
    status: str                          # ok or failed
    message: str
    ends: dict[str, float | int]         # end value of every recorded output (what was reached)
    path: np.ndarray | None              # (PATH_POINTS, 2): pose x, y, subsampled
    seconds: float                       # the whole run on the worker
    loop_seconds: float                  # its stepping loop
    estimate: dict = dataclasses.field(default_factory=dict)   # summary.json's error_estimate
    end_time: float | None = None        # the last row's time (an FMU may end the run early)


def with_values(graph: Graph, values: dict[VarRef, Scalar]) -> Graph:
    """The graph with these start values set (instances keep their order and FMUs)."""
    by_instance: dict[str, dict[str, Scalar]] = {}
    for ref, value in values.items():
        by_instance.setdefault(ref.instance, {})[ref.variable] = value
    instances = tuple(dataclasses.replace(i, start_values={**i.start_values, **by_instance[i.name]})
                      if i.name in by_instance else i for i in graph.instances)
    return dataclasses.replace(graph, instances=instances)


def run_batch(graph: Graph, batch: list[tuple[int, dict[VarRef, Scalar]]],
              path_names: tuple[str, str] | None) -> list[RunResult]:
    """Run each (index, values) of the batch in turn; a failed run is a row, not an error."""
    return [_run_one(graph, index, values, path_names) for index, values in batch]


def _run_one(graph, index, values, path_names) -> RunResult:
    tick = time.perf_counter()
    variant = with_values(graph, values)
    try:
        results = master.simulate(variant, variant.scenario.experiment, with_estimate=True)
        status, message = "ok", results.ended_by or ""
    except MecanumError as err:        # SimulationError: keep what was reached
        results = getattr(err, "results", None)
        status, message = "failed", str(err)
    ends, path, loop = {}, None, 0.0
    if results is not None and len(results.time):
        ends = {name: results[name][-1].item() for name in results.names}
        loop = results.wall_time
        if status == "ok" and path_names is not None:
            rows = np.linspace(0, len(results.time) - 1, PATH_POINTS).round().astype(int)
            path = np.column_stack([np.asarray(results[n])[rows] for n in path_names])
    if status != "ok":
        ends = {}                      # a failed run has no end point
    estimate = (master.estimate_error(variant, results).get("error_estimate") or {}
                if status == "ok" else {})
    return RunResult(index, status, message, ends, path, time.perf_counter() - tick, loop,
                     estimate, float(results.time[-1]) if ends else None)


class CleanUp(WorkerPlugin):
    """A Dask worker plugin: when the worker closes, delete its FMU extraction folders (the
    loaded libraries stay mapped) so nothing is left in the worker's temporary folder."""
    name = "mecanum_fmu-clean-up"

    def setup(self, worker):
        # a forked worker may hold the fork server's cached temporary folder: use its TMPDIR
        # (a local cluster's scratch folder, removed by the client even if the worker dies)
        tempfile.tempdir = None

    def teardown(self, worker):
        RUNTIME.remove_extractions()
