"""The Python API's argument checks: each public entry point (runner.prepare, master.simulate,
runner.run, the sweep API) calls one of the functions here first, so that a wrong argument is
an ArgumentError naming the argument and the fix, before anything is read, extracted or
written (nothing is left in TMPDIR), instead of a TypeError or ZeroDivisionError from deep
inside."""
from __future__ import annotations

import os
from typing import Any

from ..errors import ArgumentError, Problem, did_you_mean
from .graph import Graph
from ..models.library import fmu_guid
from .document import MASTERS, Experiment, check_experiment, estimate_problem, tolerance_problem
from ..values import is_finite, is_number, show


def _problem(call: str, name: str, message: str) -> Problem:
    return Problem(f"{call}()", f"argument {name}", message)


def _raise(problems: list[Problem]) -> None:
    if problems:
        raise ArgumentError(problems)


def _graph_problems(call: str, graph: Any) -> list[Problem]:
    if isinstance(graph, Graph):
        return []
    return [_problem(call, "graph", f"expected a Graph, got {show(graph)}; make one with "
                                    "runner.prepare('scenario.yaml')")]


def _fmu_problems(call: str, graph: Graph) -> list[Problem]:
    """Each FMU the graph was compiled from must still be there with the same GUID: deleted or
    replaced by another model since prepare(), it is reported before anything is extracted."""
    problems = []
    for inst in graph.instances:
        guid = _guid(inst.fmu_path)
        if guid == inst.model.guid:
            continue
        what = ("is gone or unreadable" if guid is None else
                f"was replaced by another model (GUID {show(guid, 60)}, not {inst.model.guid})")
        problems.append(_problem(call, "graph", f"the FMU {inst.fmu_path} of component "
                                 f"'{inst.name}' {what} since prepare() read it; call "
                                 "prepare() again"))
    return problems


_GUIDS: dict[tuple, str | None] = {}     # (path, inode, size, mtime) -> GUID: read once


def _guid(path) -> str | None:
    """fmu_guid, read again only when the file's identity or size or time changed."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    key = (str(path), st.st_ino, st.st_size, st.st_mtime_ns)
    if key not in _GUIDS:
        if len(_GUIDS) > 1000:
            _GUIDS.clear()
        _GUIDS[key] = fmu_guid(path)
    return _GUIDS[key]


def _callable_problems(call: str, **functions: Any) -> list[Problem]:
    return [_problem(call, name, f"expected a function or None, got {show(value)}")
            for name, value in functions.items() if value is not None and not callable(value)]


def keep_rows_problems(call: str, keep_rows: Any) -> list[Problem]:
    if keep_rows is None or (isinstance(keep_rows, int) and not isinstance(keep_rows, bool)
                             and keep_rows >= 1):
        return []
    return [_problem(call, "keep_rows", f"{show(keep_rows)} is not a row count; give a whole "
                                        "number >= 1, or None to keep every row")]


def _time_problems(call: str, values: dict[str, Any], none_unchanged: bool = True
                   ) -> list[Problem]:
    """Numbers of seconds (None: unchanged, when none_unchanged) given as arguments."""
    problems = []
    for name, value in values.items():
        if value is None and none_unchanged:
            continue
        if not is_number(value):
            problems.append(_problem(call, name, f"expected a number of seconds, got "
                                                 f"{show(value)}"))
        elif not is_finite(value):
            problems.append(_problem(call, name, f"{show(value)} is not a finite number of "
                                                 "seconds"))
    return problems


def master_problems(call: str, name: str, master: Any) -> list[Problem]:
    if isinstance(master, str) and master in MASTERS:
        return []
    hint = did_you_mean(master, MASTERS) if isinstance(master, str) else ""
    return [_problem(call, name, f"unknown master {show(master)}{hint} (choose one of "
                                 f"{', '.join(MASTERS)})")]


def experiment_problems(call: str, experiment: Any) -> list[Problem]:
    """An Experiment whose times are finite numbers in order and whose master is known."""
    if not isinstance(experiment, Experiment):
        return [_problem(call, "experiment", f"expected an Experiment, got {show(experiment)}; "
                                             "pass graph.scenario.experiment")]
    times = {k: getattr(experiment, k) for k in ("start_time", "stop_time", "step_size")}
    problems = _time_problems(call, {f"experiment.{k}": v for k, v in times.items()}, False)
    if not problems:
        problems = [_problem(call, place, message) for place, message in
                    check_experiment(experiment)]
    return problems + master_problems(call, "experiment.master", experiment.master)


def check_prepare(path: Any, step_size: Any, stop_time: Any, master_name: Any,
                  fmu_dir: Any, parameters: Any, tolerance: Any = None,
                  estimate: Any = None) -> None:
    """runner.prepare's arguments (the values themselves are checked with the scenario's
    rules afterwards, placed as command-line options)."""
    call = "runner.prepare"
    problems = []
    if not isinstance(path, (str, os.PathLike, dict)):
        problems.append(_problem(call, "path", f"expected a scenario file path or a scenario "
                                               f"mapping, got {show(path)}"))
    problems += _time_problems(call, {"step_size (--step-size)": step_size,
                                      "stop_time (--stop-time)": stop_time})
    if tolerance is not None and (problem := tolerance_problem(tolerance, None)):
        problems.append(_problem(call, "tolerance (--tolerance)", problem))
    if estimate is not None and (problem := estimate_problem(estimate, None)):
        problems.append(_problem(call, "estimate (--estimate)", problem))
    if master_name is not None:
        problems += master_problems(call, "master_name (--master)", master_name)
    if fmu_dir is not None and not isinstance(fmu_dir, (str, os.PathLike)):
        problems.append(_problem(call, "fmu_dir", f"expected a folder path, got {show(fmu_dir)}"))
    if parameters is not None and not isinstance(parameters, dict):
        problems.append(_problem(call, "parameters", f"expected a mapping like "
                                 f"{{'w2c.R': 0.061}}, got {show(parameters)}"))
    _raise(problems)


def check_simulate(graph: Any, experiment: Any, progress: Any, sink: Any,
                   keep_rows: Any) -> None:
    """master.simulate's arguments."""
    call = "master.simulate"
    problems = _graph_problems(call, graph)
    wrong_experiment = experiment_problems(call, experiment)   # the checks that read no file
    _raise((problems or _fmu_problems(call, graph)) + wrong_experiment
           + _callable_problems(call, progress=progress, sink=sink)
           + keep_rows_problems(call, keep_rows))


def check_run(graph: Any, out_dir: Any, progress: Any, log: Any, keep_rows: Any) -> None:
    """runner.run's arguments (the folder itself is checked by output.OutputFolder)."""
    call = "runner.run"
    problems = _graph_problems(call, graph)
    if not problems:
        problems = experiment_problems(call, graph.scenario.experiment)
    if out_dir is not None and not isinstance(out_dir, (str, os.PathLike)):
        problems.append(_problem(call, "out_dir", f"expected a folder path, got {show(out_dir)}"))
    _raise(problems + _callable_problems(call, progress=progress, log=log)
           + keep_rows_problems(call, keep_rows))


def check_sweep_file(path: Any) -> None:
    """The sweep API's file argument."""
    if not isinstance(path, (str, os.PathLike)):
        _raise([_problem("sweep", "path", f"expected a sweep file path, got {show(path)}")])


def check_execute(graph: Any, runs: Any, workers: Any, scheduler: Any, progress: Any,
                  log: Any) -> None:
    """sweep.cluster.execute's and run_sweep's arguments."""
    call = "sweep.execute"
    problems = [] if graph is None and runs is None else _graph_problems(call, graph)
    if runs is not None and not isinstance(runs, list):
        problems.append(_problem(call, "runs", f"expected the list of runs from "
                                               f"prepare_sweep(), got {show(runs)}"))
    if workers is not None and not (isinstance(workers, int) and not isinstance(workers, bool)
                                    and workers >= 1):
        problems.append(_problem(call, "workers", f"{show(workers)} is not a worker count; "
                                                  "give 1 or more, or None (one per core)"))
    if scheduler is not None and not (isinstance(scheduler, str) and scheduler):
        problems.append(_problem(call, "scheduler", f"expected an address like "
                                                    f"'tcp://HOST:8786', got {show(scheduler)}"))
    if workers is not None and scheduler is not None and not problems:
        problems.append(_problem(call, "workers", "the workers of a scheduler are started "
                                                  "with `dask worker`; give one of the two"))
    _raise(problems + _callable_problems(call, progress=progress, log=log))
