"""`sweep`: many runs of one scenario on a Dask cluster, one row per run.

The client (this process) checks the sweep file, every value, the output folder, the worker
count and the scheduler before the first run; plans the runs, sends them in batches to Dask
workers (a LocalCluster of worker processes by default, or a running `dask scheduler` by
address), computes the ground truth once per distinct commanded profile, and writes runs.csv
(sorted by run index: the same bytes whatever the scheduling), summary.json and the plots
through output.OutputFolder (locked; summary.json says `complete: false` from before the
first run until every run is written).

Signals: while the cluster starts and the runs go, Ctrl-C and SIGTERM only set a flag
(process.ctrl_c_latched) that the loop polls; the rest is cancelled, what finished is written.
During the evaluation and the plots a signal stops them; the files are written with signals
deferred. Exit 130 (Ctrl-C) or 143 (SIGTERM), `complete: false`.
"""
from __future__ import annotations

import csv
import logging
import math
import multiprocessing.forkserver
import os
import shutil
import signal
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..scenario.arguments import check_execute, check_sweep_file
from ..errors import Interrupted, MecanumError, Problem, ScenarioError
from ..scenario.graph import Graph
from ..master.recorder import time_grid
from ..models.catalog import find_roles
from ..models.topology import topology
from ..output import OutputFolder, WriteError
from ..process import SignalFlag, ctrl_c_latched, sigterm_raises
from ..report.evaluation import evaluate, solve_truth
from ..report.ground_truth import truth_inputs
from ..results import Results, format_value
from ..runner import prepare
from . import spec
from .checks import check_workers, probe_scheduler
from .spec import MAX_RUNS, Run, Sweep
from .worker import CleanUp, RunResult, run_batch, with_values

BATCHES_PER_WORKER = 4        # tasks per worker: load balance and little lost on a dead worker
MAX_BATCH = 25
ERRORS = ("error.dx", "error.dy", "error.dtheta", "error.position")
PRELOAD = "mecanum_fmu.sweep.forkserver_preload"
UNIX_PATH_ROOM = 70           # TMPDIR bytes that leave room for "/pymp-*/listener-*"
POLL_S = 0.05                 # how often the client looks for results and signals
SIGNAL_NAMES = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}
GROUP_SIGNALS = {signal.SIGINT, signal.SIGTERM}   # the fork server and the workers ignore them


@dataclass
class Execution:
    results: dict[int, RunResult]
    workers: int
    scheduler: str                 # "local" or the address
    startup_s: float               # cluster start / connection
    wall_s: float                  # first batch sent -> last result in
    complete: bool


def prepare_sweep(path: str | Path, fmu_dir: Path | None = None,
                  max_runs: int = MAX_RUNS) -> tuple[Sweep, Graph, list[Run]]:
    """Load and check the sweep file, its scenario and every value. Raises ScenarioError."""
    check_sweep_file(path)
    return spec.prepare_sweep(path, lambda scenario: prepare(scenario, fmu_dir=fmu_dir),
                              max_runs)


def execute(graph: Graph, runs: list[Run], *, workers: int | None = None,
            scheduler: str | None = None,
            progress: Callable[[int, int], None] | None = None,
            log: Callable[[str], None] = lambda line: None,
            stop: list[int] | None = None) -> Execution:
    """Run every planned run (those with a problem are failed rows without running).
    stop: a flag (process.ctrl_c_latched's) that ends the sweep when set."""
    check_execute(graph, runs, workers, scheduler, progress, log)
    stop = stop if stop is not None else [0]
    if stop[0]:                 # a signal before the start: no cluster for nothing
        return Execution(_not_runnable(runs), workers or 0, scheduler or "local", 0.0, 0.0,
                         False)
    tick = time.perf_counter()
    with cluster(workers, scheduler) as (client, n_workers, address):
        startup = time.perf_counter() - tick
        log(f"{n_workers} worker(s) ready ({address}, {startup:.1f} s)")
        tick = time.perf_counter()
        results, complete = run_on(client, n_workers, graph, runs, progress, stop)
        wall = time.perf_counter() - tick
    return Execution(results, n_workers, address, startup, wall, complete)


def run_on(client, n_workers: int, graph: Graph, runs: list[Run],
           progress: Callable[[int, int], None] | None = None,
           stop: list[int] | None = None) -> tuple[dict, bool]:
    """Send the runs in batches to the client's workers and gather their rows by index.
    Returns (rows, complete); a set `stop` flag or Ctrl-C cancels what is left."""
    from distributed import as_completed
    stop = stop if stop is not None else [0]
    results = _not_runnable(runs)
    if stop[0]:
        return results, False
    futures = _submit(client, n_workers, graph, runs)
    pending = as_completed(list(futures))
    try:
        while not pending.is_empty():
            if stop[0]:
                break
            done = pending.next_batch(block=False) if pending.has_ready() else []
            if not done:
                time.sleep(POLL_S)
            for future in done:
                for row in _batch_rows(future, futures[future]):
                    results[row.index] = row
                if progress is not None:
                    progress(len(results), len(runs))
    except KeyboardInterrupt:         # not latched (not the main thread, a handler of its own)
        stop[0] = stop[0] or signal.SIGINT
    if stop[0]:
        client.cancel(list(futures))
        return results, False
    return results, True


def _not_runnable(runs: list[Run]) -> dict[int, RunResult]:
    """The failed rows of the runs whose values the scenario's rules refuse (not run)."""
    return {r.index: RunResult(r.index, "failed", r.problem, {}, None, 0.0, 0.0)
            for r in runs if r.problem is not None}


def _submit(client, n_workers: int, graph: Graph, runs: list[Run]) -> dict:
    todo = [(r.index, r.values) for r in runs if r.problem is None]
    roles = find_roles(graph)
    path_names = (f"{roles.pose}.x", f"{roles.pose}.y") if roles.pose else None
    size = max(1, min(MAX_BATCH, math.ceil(len(todo) / (n_workers * BATCHES_PER_WORKER))))
    batches = [todo[i:i + size] for i in range(0, len(todo), size)]
    return {client.submit(run_batch, graph, b, path_names, pure=False): b for b in batches}


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
    A LocalCluster gets a scratch folder of its own, which is also its workers' TMPDIR (their
    FMU extraction folders live there), removed afterwards: a worker killed by a signal
    leaves nothing behind either."""

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
        if self.scheduler:
            n = self._connect()
        else:
            n = self._start_local()
        self.client.register_plugin(CleanUp(), name=CleanUp.name)
        return self.client, n, self.scheduler or "local"

    def _connect(self) -> int:
        from distributed import Client
        try:
            self.client = Client(self.scheduler, timeout="20s")
            self.client.wait_for_workers(1, timeout=60)
        except (OSError, TimeoutError, ValueError) as err:
            raise ScenarioError([Problem("command line", "--scheduler", f"cannot use the "
                                 f"Dask scheduler at {self.scheduler}: {err}; give tcp://HOST:PORT "
                                 "of one started with `dask scheduler` (and `dask worker "
                                 "ADDRESS`s)")]) from None
        return len(self.client.scheduler_info(n_workers=-1)["workers"])

    def _start_local(self) -> int:
        from distributed import LocalCluster
        import dask
        n = self.workers or os.cpu_count() or 1
        self.scratch = tempfile.mkdtemp(prefix="mecanum_sweep_")
        self.config = dask.config.set({"temporary-directory": self.scratch,
                                       "distributed.worker.profile.enabled": False,
                                       "distributed.worker.multiprocessing-method":
                                           "forkserver"})
        _forkserver_ignoring_ctrl_c()
        self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                    dashboard_address=None, local_directory=self.scratch,
                                    silence_logs=logging.CRITICAL, host="127.0.0.1",
                                    env={"TMPDIR": self.scratch},
                                    # its HTTP server (health checks) on any free port,
                                    # not 8787: several sweeps may run at once
                                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
        self.client = self.cluster.get_client()
        return n

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


def _forkserver_ignoring_ctrl_c() -> None:
    """Local workers are forked by multiprocessing's fork server, started here (once per
    process) with sweep.forkserver_preload first in its preload list: the server ignores
    SIGINT and SIGTERM, and so does every worker it forks. The Ctrl-C that a terminal sends to
    the whole process group, or a SIGTERM to the group, reaches only the client, which stops
    the sweep, cancels what is left and closes the workers (none dies of it, so no nanny
    restarts one while the cluster closes). This thread blocks both while the server is
    spawned (the mask is inherited: a signal before the preload runs waits, then is dropped);
    the client's own dispositions never change, so a signal meanwhile is taken by another
    thread of the client (OpenBLAS's) and handled as usual: none is lost. The resource
    tracker, which the server's start launches first in a process's first sweep, is started
    before the mask is set: it unblocks both after its own spawn, and the server then started
    unblocked (a group signal during its `site` import was a traceback on the sweep's stderr)."""
    from multiprocessing import resource_tracker
    from distributed.utils import get_mp_context
    get_mp_context()                      # sets Dask's preload list for the server
    server = multiprocessing.forkserver._forkserver
    if PRELOAD not in server._preload_modules:
        server.set_forkserver_preload([PRELOAD, *server._preload_modules])
    _socket_folder()
    resource_tracker.ensure_running()     # it blocks and unblocks both around its own spawn
    signal.pthread_sigmask(signal.SIG_BLOCK, GROUP_SIGNALS)
    try:
        server.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, GROUP_SIGNALS)


def _socket_folder() -> None:
    """The fork server listens on a Unix socket in multiprocessing's pymp-* folder, made in
    TMPDIR; a socket path has at most 107 bytes, so under a TMPDIR too long for it the folder
    is made in /tmp instead (removed at exit, process.exit_now too)."""
    from multiprocessing import current_process, util
    if "tempdir" in current_process()._config or len(tempfile.gettempdir()) <= UNIX_PATH_ROOM:
        return
    saved, tempfile.tempdir = tempfile.tempdir, "/tmp"
    try:
        util.get_temp_dir()
    finally:
        tempfile.tempdir = saved


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
        end = times[-1] if row.end_time is None else row.end_time     # an FMU ended it
        key = tuple(tuple(sorted(variant.instance(n).start_values.items()))
                    for n in truth_inputs(variant, drive)) + (end,)
        if key not in truths:
            truths[key] = solve_truth(variant, drive, times[times <= end])
        truth, failure = truths[key]
        pose = evaluate(variant, _end_row(row, drive.pose, times, end), topo=topo,
                        truths={drive.pose: truth}).single
        if failure is not None:
            failures[failure] = failures.get(failure, 0) + 1
        elif pose.error is not None:
            errors[run.index] = {f"error.{k}": v for k, v in pose.error.items()}
    for failure, count in failures.items():
        log(f"no ground truth for {count} run(s): {failure}")
    return errors


def _end_row(row: RunResult, pose: str, times: np.ndarray, end: float) -> Results:
    """The run's end pose as a one-row Results at the run's end time `end` (its last row's:
    an FMU may have ended the run before the stop time)."""
    names = tuple(f"{pose}.{k}" for k in ("x", "y", "theta"))
    data = np.array([(end,) + tuple(row.ends[n] for n in names)],
                    dtype=[("time", "f8")] + [(n, "f8") for n in names])
    return Results(names, data, "", float(times[0]), float(times[-1]), 0.0, 0, 0.0)


def write_runs_csv(out: OutputFolder, sweep: Sweep, graph: Graph, runs: list[Run],
                   results: dict[int, RunResult], errors: dict[int, dict]) -> Path:
    outputs = [str(p.ref) for p in graph.recorded]
    varied = [str(ref) for ref in sweep.varied]
    roles = find_roles(graph)
    has_truth = bool(errors) or (roles.source is not None and roles.pose is not None)
    estimates = estimate_columns(results)
    header = (["run"] + varied + ["status", "message"] + outputs
              + (list(ERRORS) if has_truth else []) + list(estimates))
    try:
        with out.atomic("runs.csv") as temp, open(temp, "w", newline="") as fh:
            _write_rows(csv.writer(fh, lineterminator="\n"), header, sweep, outputs, runs,
                        results, errors, has_truth, estimates)
    except OSError as err:                        # a full disk: exit 1, as `run`
        raise WriteError(out.path, err) from None
    return out.path / "runs.csv"


def _write_rows(writer, header, sweep, outputs, runs, results, errors, has_truth,
                estimates) -> None:
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


def summarize(sweep: Sweep, graph: Graph, runs: list[Run], ex: Execution,
              errors: dict[int, dict], signum: int = 0) -> dict:
    """The summary; `complete` only when every run ran, nothing stopped and no signal came."""
    summary = _counts(sweep, graph, runs, ex, signum)
    ok = [r for r in ex.results.values() if r.status == "ok"]
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


def _counts(sweep: Sweep, graph: Graph, runs: list[Run], ex: Execution, signum: int) -> dict:
    rows = ex.results.values()
    ok = sum(r.status == "ok" for r in rows)
    worked = [r for r in rows if r.seconds > 0]
    exp = graph.scenario.experiment
    summary = {
        "sweep": sweep.name, "file": str(sweep.path), "scenario": str(sweep.scenario_path),
        "master": exp.master, "step_size": exp.step_size, "stop_time": exp.stop_time,
        "varied": [str(r) for r in sweep.varied], "seed": sweep.seed,
        "runs": len(runs), "ok": ok, "failed": len(rows) - ok,
        "not_run": len(runs) - len(rows),
        "complete": ex.complete and len(rows) == len(runs) and not signum,
        "workers": ex.workers, "scheduler": ex.scheduler,
        "startup_s": round(ex.startup_s, 3), "wall_time_s": round(ex.wall_s, 3),
        "runs_per_s": round(len(rows) / ex.wall_s, 3) if ex.wall_s > 0 else None,
        "per_run_s": _mean([r.seconds for r in worked]),
        "per_run_stepping_loop_s": _mean([r.loop_seconds for r in worked]),
    }
    if signum:
        summary["interrupted"] = SIGNAL_NAMES.get(signum, str(signum))
    return summary


def _mean(values: list[float]) -> float | None:
    return round(float(np.mean(values)), 6) if values else None


def check_sweep(path: str | Path, *, workers: int | None = None, scheduler: str | None = None,
                fmu_dir: Path | None = None,
                max_runs: int = MAX_RUNS) -> tuple[Sweep, Graph, list[Run], int | None]:
    """Everything checked before the first run but the output folder: the sweep file, its
    scenario and values, the run count, the worker count or the scheduler. ScenarioError."""
    if workers is not None and scheduler:
        raise ScenarioError([Problem("command line", "--workers", "the workers of --scheduler "
                                     "are started with `dask worker`; give one of the two")])
    if isinstance(max_runs, bool) or not isinstance(max_runs, int) or max_runs < 1:
        raise ScenarioError([Problem("command line", "--max-runs", f"{max_runs!r} is not a "
                                     "run count; give 1 or more")])
    workers = None if scheduler else check_workers(workers)
    if scheduler:
        probe_scheduler(scheduler)
    sweep, graph, runs = prepare_sweep(path, fmu_dir, max_runs)
    return sweep, graph, runs, workers


def run_sweep(path: str | Path, out_dir: Path | None = None, *, workers: int | None = None,
              scheduler: str | None = None, plots: bool = True, fmu_dir: Path | None = None,
              progress: Callable[[int, int], None] | None = None,
              log: Callable[[str], None] = print, max_runs: int = MAX_RUNS) -> dict:
    """The whole command. Returns the summary; raises ScenarioError before the first run,
    Interrupted (exit code 130 / 143) after writing what finished on Ctrl-C or SIGTERM."""
    check_execute(None, None, None, scheduler, progress, log)   # workers: check_sweep
    sweep, graph, runs, workers = check_sweep(path, workers=workers, scheduler=scheduler,
                                              fmu_dir=fmu_dir, max_runs=max_runs)
    out_dir = Path(out_dir) if out_dir is not None else Path("results") / sweep.name
    with sigterm_raises(), ctrl_c_latched() as flag, \
            OutputFolder(out_dir, tables=("runs.csv", "summary.json")) as out:
        log(f"{sweep.name}: {len(runs)} runs of {graph.scenario.name} into {out_dir}/, "
            + (f"scheduler {scheduler}" if scheduler else
               f"{workers} local worker process(es)"))
        summary = _sweep_into(out, flag, sweep, graph, runs, workers=workers,
                              scheduler=scheduler, plots=plots, progress=progress, log=log)
    for line in report_lines(summary):
        log(line)
    log(f"wrote {len(summary['files'])} files to {out_dir}/")
    if "interrupted" in summary:
        err = Interrupted(float("nan"), terminated=summary["interrupted"] == "SIGTERM")
        err.args = (f"{'terminated (SIGTERM)' if err.terminated else 'interrupted'}: "
                    f"{len(runs) - summary['not_run']} of {len(runs)} runs written to "
                    f"{out_dir}/",)
        raise err
    return summary


def _sweep_into(out: OutputFolder, flag: SignalFlag, sweep: Sweep, graph: Graph,
                runs: list[Run], *, workers, scheduler, plots: bool, progress, log) -> dict:
    """Run and write into out, with signals latched in flag: summary.json with complete:
    false first, then the runs, runs.csv, the plots and the final summary.json. The
    evaluation and the plots stop on a signal; nothing else does. Returns the final summary
    (with "files")."""
    started = Execution({}, workers or 0, scheduler or "local", 0.0, 0.0, False)
    out.write_json(summarize(sweep, graph, runs, started, {}))      # complete: false
    ex = execute(graph, runs, workers=workers, scheduler=scheduler, progress=progress,
                 log=log, stop=flag)
    try:
        errors, failures = _interruptible(flag, lambda: end_errors(graph, runs, ex.results, log),
                                          {}), {}
    except Exception as err:       # a failing ground truth costs only itself, as in `run`
        errors, failures = {}, {"ground_truth_error": f"{type(err).__name__}: {err}"}
    write_runs_csv(out, sweep, graph, runs, ex.results, errors)
    plots_error = _plots(out, flag, sweep, graph, runs, ex, errors) if plots else None
    if plots_error:
        failures["plots_error"] = plots_error
    summary = {**summarize(sweep, graph, runs, ex, errors, flag[0]), **failures}
    out.write_json(summary)
    if flag[0] and "interrupted" not in summary:      # came while it was written
        summary = {**summarize(sweep, graph, runs, ex, errors, flag[0]), **failures}
        out.write_json(summary)
    if plots_error:
        raise MecanumError(f"writing the plots into {out.path} failed: {plots_error}",
                           files=[out.path / name for name in sorted(out.written)])
    return {**summary, "files": sorted(out.written)}


def _plots(out: OutputFolder, flag: SignalFlag, sweep, graph, runs, ex, errors) -> str | None:
    """Draw the plots (stopped by a signal); what went wrong, if anything (a full disk)."""
    if not ex.results:
        return None
    from .plots import write_sweep_plots   # here: matplotlib's import is slow
    try:
        out.record(_interruptible(flag, lambda: write_sweep_plots(
            out.path, sweep, graph, runs, ex.results, errors), []))
    except Exception as err:       # the runs are written: report the figure, keep the rest
        return f"{type(err).__name__}: {err}"
    return None


def _interruptible(flag: SignalFlag, action: Callable, nothing):
    """action(), unless a signal came already or comes during it: then `nothing`."""
    if flag[0]:
        return nothing
    try:
        with flag.raising():
            return action()
    except KeyboardInterrupt:          # process.Terminated too (SIGTERM); flag[0] says which
        return nothing


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
