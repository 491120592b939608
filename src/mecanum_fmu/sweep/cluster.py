"""`sweep`: many runs of one scenario on a Dask cluster, one row per run.

The client (this process) checks the sweep file and every value, plans the runs, sends them in
batches to Dask workers (a LocalCluster of worker processes by default, or a running
`dask scheduler` by address), computes the ground truth once per distinct commanded profile,
and writes runs.csv (sorted by run index: the same bytes whatever the scheduling),
summary.json and the plots. Files are written under a temporary name and renamed.
"""
from __future__ import annotations

import csv
import json
import logging
import math
import os
import shutil
import signal
import tempfile
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..arguments import check_execute, check_sweep_file
from ..errors import Interrupted, Problem, ScenarioError
from ..graph import Graph
from ..master.recorder import time_grid
from ..models.catalog import find_roles
from ..models.topology import topology
from ..report.evaluation import evaluate, solve_truth
from ..report.ground_truth import truth_inputs
from ..results import Results, format_value
from ..runner import prepare
from . import spec
from .spec import Run, Sweep
from .worker import CleanUp, RunResult, run_batch, with_values

BATCHES_PER_WORKER = 4        # tasks per worker: load balance and little lost on a dead worker
MAX_BATCH = 25
ERRORS = ("error.dx", "error.dy", "error.dtheta", "error.position")


@dataclass
class Execution:
    results: dict[int, RunResult]
    workers: int
    scheduler: str                 # "local" or the address
    startup_s: float               # cluster start / connection
    wall_s: float                  # first batch sent -> last result in
    complete: bool


def prepare_sweep(path: str | Path, fmu_dir: Path | None = None) -> tuple[Sweep, Graph, list[Run]]:
    """Load and check the sweep file, its scenario and every value. Raises ScenarioError."""
    check_sweep_file(path)
    return spec.prepare_sweep(path, lambda scenario: prepare(scenario, fmu_dir=fmu_dir))


def execute(graph: Graph, runs: list[Run], *, workers: int | None = None,
            scheduler: str | None = None,
            progress: Callable[[int, int], None] | None = None,
            log: Callable[[str], None] = lambda line: None) -> Execution:
    """Run every planned run (those with a problem are failed rows without running)."""
    check_execute(graph, runs, workers, scheduler, progress, log)
    tick = time.perf_counter()
    with cluster(workers, scheduler) as (client, n_workers, address):
        startup = time.perf_counter() - tick
        log(f"{n_workers} worker(s) ready ({address}, {startup:.1f} s)")
        tick = time.perf_counter()
        results, complete = run_on(client, n_workers, graph, runs, progress)
        wall = time.perf_counter() - tick
    return Execution(results, n_workers, address, startup, wall, complete)


def run_on(client, n_workers: int, graph: Graph, runs: list[Run],
           progress: Callable[[int, int], None] | None = None) -> tuple[dict, bool]:
    """Send the runs in batches to the client's workers and gather their rows by index.
    Returns (rows, complete); Ctrl-C cancels what is left (complete False)."""
    from distributed import as_completed
    todo = [(r.index, r.values) for r in runs if r.problem is None]
    results = {r.index: RunResult(r.index, "failed", r.problem, {}, None, 0.0, 0.0)
               for r in runs if r.problem is not None}
    roles = find_roles(graph)
    path_names = (f"{roles.pose}.x", f"{roles.pose}.y") if roles.pose else None
    size = max(1, min(MAX_BATCH, math.ceil(len(todo) / (n_workers * BATCHES_PER_WORKER))))
    batches = [todo[i:i + size] for i in range(0, len(todo), size)]
    futures = {client.submit(run_batch, graph, b, path_names, pure=False): b for b in batches}
    try:
        for future in as_completed(list(futures)):
            for row in _batch_rows(future, futures[future]):
                results[row.index] = row
            if progress is not None:
                progress(len(results), len(runs))
    except KeyboardInterrupt:
        client.cancel(list(futures))
        return results, False
    return results, True


def _batch_rows(future, batch) -> list[RunResult]:
    try:
        return future.result()
    except Exception as err:     # the task itself failed (a worker lost too often, a bug)
        message = f"worker error: {type(err).__name__}: {err}"
        return [RunResult(index, "failed", message, {}, None, 0.0, 0.0) for index, _ in batch]


class cluster:
    """Context: a connected Client, its worker count and the scheduler address (or 'local').
    Local: one worker process per core (or `workers`), one thread each; the workers' statistical
    profiler is off (it samples every worker thread's stack every 10 ms, costly next to FMU
    calls that re-enter Python).
    A LocalCluster gets a scratch folder of its own, removed afterwards."""

    def __init__(self, workers: int | None, scheduler: str | None):
        self.workers, self.scheduler = workers, scheduler
        self.client = self.cluster = self.scratch = self.config = None

    def __enter__(self):
        try:
            return self._start()
        except BaseException:            # Ctrl-C or no scheduler: leave nothing behind
            self.__exit__(None, None, None)
            raise

    def _start(self):
        from distributed import Client, LocalCluster
        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout="20s")
                self.client.wait_for_workers(1, timeout=60)
            except (OSError, TimeoutError, ValueError) as err:
                raise ScenarioError([Problem("command line", "--scheduler", f"cannot use the "
                                     f"Dask scheduler at {self.scheduler}: {err}; give tcp://HOST:PORT "
                                     "of one started with `dask scheduler` (and `dask worker "
                                     "ADDRESS`s)")]) from None
            n = len(self.client.scheduler_info(n_workers=-1)["workers"])
        else:
            n = self.workers or os.cpu_count() or 1
            self.scratch = tempfile.mkdtemp(prefix="mecanum_sweep_")
            import dask
            self.config = dask.config.set({"temporary-directory": self.scratch,
                                           "distributed.worker.profile.enabled": False})
            with _workers_ignore_ctrl_c():
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                            dashboard_address=None, local_directory=self.scratch,
                                            silence_logs=logging.CRITICAL, host="127.0.0.1",
                                            # its HTTP server (health checks) on any free port,
                                            # not 8787: several sweeps may run at once
                                            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            self.client = self.cluster.get_client()
        self.client.register_plugin(CleanUp(), name=CleanUp.name)
        return self.client, n, self.scheduler or "local"

    def __exit__(self, *exc):
        try:
            if self.client is not None:
                self.client.close()
            if self.cluster is not None:
                self.cluster.close()
        finally:
            if self.config is not None:
                self.config.__exit__(None, None, None)
            if self.scratch:
                shutil.rmtree(self.scratch, ignore_errors=True)
        return False


@contextmanager
def _workers_ignore_ctrl_c():
    """Worker processes started in here ignore SIGINT (an ignored signal stays ignored in a
    child, and Python keeps it so): Ctrl-C at a terminal reaches the whole process group, and
    the client, not each worker, is the one to stop the sweep and cancel what is left."""
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        yield
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)


# ---------------------------------------------------------------------------------------------
def end_errors(graph: Graph, runs: list[Run], results: dict[int, RunResult],
               log: Callable[[str], None] = lambda line: None) -> dict[int, dict]:
    """dx, dy, dtheta and |e| of each ok run's end pose against its ground truth: the run's
    Evaluation (report.evaluation), with one truth solved per distinct set of the values it
    reads (report.ground_truth.truth_inputs). A truth that fails costs only its runs' errors
    (logged)."""
    if len(topology(graph).drives) != 1:
        return {}
    times = time_grid(graph.scenario.experiment)
    truths: dict[tuple, tuple] = {}
    errors, failures = {}, {}
    for run in runs:
        row = results.get(run.index)
        if row is None or row.status != "ok":
            continue
        variant = with_values(graph, run.values)
        topo = topology(variant)            # the run's own values (a swept w_max, say)
        drive = topo.drives[0]
        key = tuple(tuple(sorted(variant.instance(n).start_values.items()))
                    for n in truth_inputs(variant, drive))
        if key not in truths:
            truths[key] = solve_truth(variant, drive, times)
        truth, failure = truths[key]
        pose = evaluate(variant, _end_row(row, drive.pose, times), topo=topo,
                        truths={drive.pose: truth}).single
        if failure is not None:
            failures[failure] = failures.get(failure, 0) + 1
        elif pose.error is not None:
            errors[run.index] = {f"error.{k}": v for k, v in pose.error.items()}
    for failure, count in failures.items():
        log(f"no ground truth for {count} run(s): {failure}")
    return errors


def _end_row(row: RunResult, pose: str, times: np.ndarray) -> Results:
    """The run's end pose as a one-row Results at the run's end time."""
    names = tuple(f"{pose}.{k}" for k in ("x", "y", "theta"))
    data = np.array([(times[-1],) + tuple(row.ends[n] for n in names)],
                    dtype=[("time", "f8")] + [(n, "f8") for n in names])
    return Results(names, data, "", float(times[0]), float(times[-1]), 0.0, 0, 0.0)


def write_runs_csv(path: Path, sweep: Sweep, graph: Graph, runs: list[Run],
                   results: dict[int, RunResult], errors: dict[int, dict]) -> None:
    outputs = [str(p.ref) for p in graph.recorded]
    varied = [str(ref) for ref in sweep.varied]
    has_truth = bool(errors) or (find_roles(graph).source is not None
                                 and find_roles(graph).pose is not None)
    estimates = estimate_columns(results)
    header = (["run"] + varied + ["status", "message"] + outputs
              + (list(ERRORS) if has_truth else []) + list(estimates))
    with _atomic(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(header)
        for run in runs:
            row = results.get(run.index)
            if row is None:
                continue           # not run (interrupted): summary.json counts it
            err = errors.get(run.index, {})
            writer.writerow([run.index] + [format_value(run.values[ref]) for ref in sweep.varied]
                            + [row.status, row.message]
                            + [format_value(row.ends[o]) if o in row.ends else "" for o in outputs]
                            + ([format_value(err[e]) if e in err else "" for e in ERRORS]
                               if has_truth else [])
                            + [column.get(run.index, "") for column in estimates.values()])


def estimate_columns(results: dict[int, RunResult]) -> dict[str, dict[int, str]]:
    """runs.csv's error-estimate columns (master/estimate.py): `estimate.<output>.max` and
    `.end` per pose output, one value per run that has one ("below round-off" as it is)."""
    columns: dict[str, dict[int, str]] = {}
    for index, row in sorted(results.items()):
        for name, e in row.estimate.items():
            for k in ("max", "end"):
                columns.setdefault(f"estimate.{name}.{k}", {})[index] = format_value(e[k])
    return columns


class _atomic:
    """open() on a temporary name next to `path`; renamed to `path` only when closed cleanly."""

    def __init__(self, path: Path, mode: str, **kwargs):
        self.path = Path(path)
        self.tmp = self.path.with_name(f".{self.path.name}.partial")
        self.fh = open(self.tmp, mode, **kwargs)

    def __enter__(self):
        return self.fh

    def __exit__(self, kind, *rest):
        self.fh.close()
        if kind is None:
            os.replace(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)
        return False


def summarize(sweep: Sweep, graph: Graph, runs: list[Run], ex: Execution,
              errors: dict[int, dict]) -> dict:
    rows = ex.results.values()
    ok = [r for r in rows if r.status == "ok"]
    worked = [r for r in rows if r.seconds > 0]
    exp = graph.scenario.experiment
    summary = {
        "sweep": sweep.name, "file": str(sweep.path), "scenario": str(sweep.scenario_path),
        "master": exp.master, "step_size": exp.step_size, "stop_time": exp.stop_time,
        "varied": [str(r) for r in sweep.varied], "seed": sweep.seed,
        "runs": len(runs), "ok": len(ok), "failed": len(rows) - len(ok),
        "not_run": len(runs) - len(rows), "complete": ex.complete and len(rows) == len(runs),
        "workers": ex.workers, "scheduler": ex.scheduler,
        "startup_s": round(ex.startup_s, 3), "wall_time_s": round(ex.wall_s, 3),
        "runs_per_s": round(len(rows) / ex.wall_s, 3) if ex.wall_s > 0 else None,
        "per_run_s": _mean([r.seconds for r in worked]),
        "per_run_stepping_loop_s": _mean([r.loop_seconds for r in worked]),
    }
    roles = find_roles(graph)
    if roles.pose and ok:
        xy = np.array([[r.ends[f"{roles.pose}.x"], r.ends[f"{roles.pose}.y"]] for r in ok])
        mean = xy.mean(axis=0)
        spread = np.hypot(*(xy - mean).T)
        summary["end_point"] = {"mean": mean.tolist(), "sd": xy.std(axis=0, ddof=1).tolist()
                                if len(xy) > 1 else [0.0, 0.0],
                                "max_from_mean": float(spread.max())}
    if errors:
        e = np.array([v["error.position"] for v in errors.values()])
        summary["error_position"] = {"mean": float(e.mean()), "sd": float(e.std(ddof=1))
                                     if len(e) > 1 else 0.0, "max": float(e.max())}
    return summary


def _mean(values: list[float]) -> float | None:
    return round(float(np.mean(values)), 6) if values else None


def write_summary(path: Path, summary: dict) -> None:
    with _atomic(path, "w") as fh:
        fh.write(json.dumps(summary, indent=2) + "\n")


def run_sweep(path: str | Path, out_dir: Path | None = None, *, workers: int | None = None,
              scheduler: str | None = None, plots: bool = True, fmu_dir: Path | None = None,
              progress: Callable[[int, int], None] | None = None,
              log: Callable[[str], None] = print) -> dict:
    """The whole command. Returns the summary; raises Interrupted after writing on Ctrl-C."""
    check_execute(None, None, workers, scheduler, progress, log)
    sweep, graph, runs = prepare_sweep(path, fmu_dir)
    out_dir = Path(out_dir) if out_dir is not None else Path("results") / sweep.name
    log(f"{sweep.name}: {len(runs)} runs of {graph.scenario.name}, "
        + (f"scheduler {scheduler}" if scheduler else
           f"{workers or os.cpu_count()} local worker process(es)"))
    ex = execute(graph, runs, workers=workers, scheduler=scheduler, progress=progress, log=log)
    errors = end_errors(graph, runs, ex.results, log)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_runs_csv(out_dir / "runs.csv", sweep, graph, runs, ex.results, errors)
    summary = summarize(sweep, graph, runs, ex, errors)
    write_summary(out_dir / "summary.json", summary)
    if plots and ex.results:
        from .plots import write_sweep_plots
        write_sweep_plots(out_dir, sweep, graph, runs, ex.results, errors)
    for line in report_lines(summary):
        log(line)
    if not summary["complete"]:
        err = Interrupted(float("nan"))
        err.args = (f"interrupted: {len(ex.results)} of {len(runs)} runs written to {out_dir}/",)
        raise err
    return summary


def report_lines(s: dict) -> list[str]:
    lines = [f"{s['ok']} ok, {s['failed']} failed, {s['not_run']} not run; {s['workers']} "
             f"workers ({s['scheduler']}), {s['wall_time_s']:.2f} s, {s['runs_per_s']} runs/s"]
    if "end_point" in s:
        ep = s["end_point"]
        lines.append(f"end point: mean ({ep['mean'][0]:.4f}, {ep['mean'][1]:.4f}), sd "
                     f"({ep['sd'][0]:.2e}, {ep['sd'][1]:.2e}), max from mean "
                     f"{ep['max_from_mean']:.2e} m")
    if "error_position" in s:
        e = s["error_position"]
        lines.append(f"end-point error vs ground truth: mean {e['mean']:.2e}, sd {e['sd']:.2e}, "
                     f"max {e['max']:.2e} m")
    return lines
