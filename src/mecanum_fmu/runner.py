"""`run` as a library call: load, check, simulate, compare with the ground truth, write.

Results are written in the order that keeps the most on a failure: CSV and summary first,
plots last; a run that fails mid-way still writes every row recorded up to the failure.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import Interrupted, MecanumError, Problem, ScenarioError, SimulationError
from .graph import Graph, compile_graph
from .models.catalog import MODELS, find_roles
from .report.ground_truth import Truth, ground_truth
from .output import OutputFolder
from .report.plot_worker import PlotWorker
from .process import sigterm_raises, signals_deferred
from .results import Results
from .scenario import MASTERS, Scenario, load_scenario, override_experiment


@dataclass
class RunOutcome:
    scenario: Scenario
    graph: Graph
    results: Results
    truth: Truth | None
    summary: dict
    out_dir: Path
    files: list[Path]


def prepare(path: str | Path, *, step_size: float | None = None, stop_time: float | None = None,
            master_name: str | None = None, fmu_dir: Path | None = None,
            build: bool = True) -> Graph:
    """Load and check a scenario (with command-line overrides) and compile its graph. With
    build (the default), the bundled FMUs it uses are built first when missing or stale;
    without (validate), such an FMU is reported as a problem with the command that builds it."""
    if Path(path).suffix.lower() in (".ssp", ".ssd"):   # SSP 1.0 archive or bare SSD
        from .interop.ssp_read import load_ssp
        scenario = load_ssp(path)
    else:
        scenario = load_scenario(path)
    changes = {k: v for k, v in (("step_size", step_size), ("stop_time", stop_time),
                                 ("master", master_name)) if v is not None}
    if changes:
        if "master" in changes and changes["master"] not in MASTERS:
            raise ScenarioError([Problem(scenario.label, "--master", f"unknown master "
                                 f"{changes['master']!r} (choose one of {', '.join(MASTERS)})")])
        scenario = override_experiment(scenario, changes, scenario.label,
                                       " (with the command-line options)")
    if build:
        build_bundled(scenario, fmu_dir)
    return compile_graph(scenario, fmu_dir)


def build_bundled(scenario: Scenario, fmu_dir: Path | None = None) -> None:
    """Build the bundled FMUs the scenario names that are missing or stale."""
    from .models.build import build_fmu
    from .models.library import bundled_fmu_path, default_fmu_dir, is_current
    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    for comp in scenario.components:
        if comp.fmu in MODELS and not is_current(comp.fmu, bundled_fmu_path(comp.fmu, fmu_dir)):
            try:
                build_fmu(comp.fmu, fmu_dir)
            except Exception as err:  # the build is ours; report it with the place
                raise ScenarioError([Problem(scenario.label, f"{comp.place}.fmu",
                                             f"building the bundled FMU {comp.fmu} into "
                                             f"{fmu_dir} failed: {err}")]) from err


def default_out_dir(scenario: Scenario) -> Path:
    return Path("results") / scenario.name


# What runner.run keeps in memory for the ground truth and the plots: about this many evenly
# spaced rows plus the exact last one (results.csv holds every row).
KEEP_ROWS = 10_000


def run(graph: Graph, out_dir: Path | None = None, *, plots: bool = True,
        progress: Callable[[float], None] | None = None,
        log: Callable[[str], None] = print, animate: bool = False,
        keep_rows: int | None = KEEP_ROWS, plotter: PlotWorker | None = None) -> RunOutcome:
    """Simulate, write results.csv, summary.json and the plots into out_dir.

    results.csv is written during the run; the outcome's Results hold `keep_rows` rows (None:
    every row). The folder is checked and locked first (ScenarioError). A failure after the
    stepping loop (ground truth, plots) costs only itself: the tables are written first.
    `plotter`: a plot worker started earlier (the CLI starts it before loading, to hide
    matplotlib's import); without one, one is started here when plots are wanted."""
    out_dir = Path(out_dir) if out_dir is not None else default_out_dir(graph.scenario)
    plotter = (plotter or PlotWorker.start()) if plots else None    # imports matplotlib now
    try:
        with sigterm_raises(), OutputFolder(out_dir) as out:
            if plotter is not None:
                plotter.expect(graph)
            try:
                outcome = _run_in(graph, out, plotter=plotter, progress=progress, log=log,
                                  animate=animate, keep_rows=keep_rows)
            except MecanumError as err:
                out.record(err.files)      # named in summary.json: a re-run removes them
                raise
            out.record(outcome.files)
            return outcome
    finally:
        if plotter is not None:
            plotter.cancel()        # stops the worker if the plots were not drawn


def _run_in(graph: Graph, out: OutputFolder, *, plotter: PlotWorker | None, progress, log,
            animate: bool, keep_rows: int | None) -> RunOutcome:
    scenario, out_dir = graph.scenario, out.path
    results, files = _simulate_into(graph, out, progress, keep_rows)
    truth, truth_error = _ground_truth(graph, results)
    summary = summarize(graph, results, truth)
    if truth is not None or truth_error:
        if truth_error:
            summary["ground_truth_error"] = truth_error
        _rewrite_summary(out, summary, files)
    for line in report_lines(summary):
        log(line)
    stage = "plots"
    try:
        if plotter is not None:
            files += plotter.finish(results, find_roles(graph), truth, out_dir,
                                    title=scenario.name)
        stage = "animation"
        if animate:
            from .report.animation import write_animation
            from .models.modes import graph_geometry
            files.append(write_animation(results, find_roles(graph), truth,
                                         graph_geometry(graph), out_dir / "animation.gif"))
    except Exception as err:    # the results are written: report the figure, keep the rest
        failed = MecanumError(f"writing the {stage} into {out_dir} failed: "
                              f"{type(err).__name__}: {err}", files=files)
        summary[f"{stage}_error"] = str(failed)
        _rewrite_summary(out, summary, [])
        raise failed from err
    if truth_error:
        raise MecanumError(f"the ground truth could not be computed ({truth_error}); the "
                           f"run itself is complete", files=files)
    return RunOutcome(scenario, graph, results, truth, summary, out_dir, files)


def _rewrite_summary(out: OutputFolder, summary: dict, files: list[Path]) -> None:
    """The summary again, now with the ground truth (or why it failed)."""
    try:
        with signals_deferred():
            out.write_json(summary)
    except MecanumError as err:     # output.WriteError: the tables written before are kept
        err.files.extend(files)
        raise


def _simulate_into(graph: Graph, out: OutputFolder, progress,
                   keep_rows: int | None) -> tuple[Results, list[Path]]:
    """Run with results.csv streamed into `out`; write the summary (without the ground truth).
    A failed or interrupted run still keeps its tables and raises; a write error
    (output.WriteError) leaves no results.csv."""
    from . import master  # here: `validate` needs neither the FMI runtime nor matplotlib
    stream = None
    try:
        stream = out.csv_stream(tuple(str(p.ref) for p in graph.recorded))
        try:
            results = master.simulate(graph, graph.scenario.experiment, progress=progress,
                                      sink=stream, keep_rows=keep_rows)
        except (SimulationError, Interrupted) as err:
            if err.results is not None:
                with signals_deferred():
                    summary = summarize(graph, err.results, None)
                    summary["error_message"] = str(err)
                    err.files.extend(out.write_tables(stream, summary))
            raise
        with signals_deferred():
            return results, out.write_tables(stream, summarize(graph, results, None))
    finally:                    # a write failed (output.WriteError) or a bug: no half file
        if stream is not None and stream.temp.exists():
            stream.abort()


def _ground_truth(graph: Graph, results: Results) -> tuple[Truth | None, str | None]:
    """The ground truth on the (bounded) times kept, or why it failed."""
    if not results.steps:
        return None, None
    try:
        truth = ground_truth(graph, results.time)
    except Exception as err:    # e.g. an expression that fails between the recorded times
        return None, f"{type(err).__name__}: {err}"
    if truth is not None and not np.all(np.isfinite(truth.end)):
        return None, f"its end pose {truth.end} is not finite"
    return truth, None


def summarize(graph: Graph, results: Results, truth: Truth | None) -> dict:
    scenario = graph.scenario
    roles = find_roles(graph)
    summary = {
        "scenario": scenario.name,
        "file": str(scenario.path),
        "description": scenario.description,
        "master": results.master,
        "start_time": results.start_time,
        "stop_time": results.stop_time,
        "step_size": results.step_size,
        "steps": results.steps,
        "wall_time_s": round(results.wall_time, 6),
        "complete": results.complete,
        "end_time": float(results.time[-1]) if len(results.time) else None,
        "recorded": list(results.names),
        "fmus": {i.name: {"model": i.model_name, "path": str(i.fmu_path), "guid": i.model.guid}
                 for i in graph.instances},
    }
    pose = roles.pose
    if pose and all(f"{pose}.{k}" in results.names for k in ("x", "y", "theta")) and len(results.time):
        end = {k: results.final(f"{pose}.{k}") for k in ("x", "y", "theta")}
        summary["end_pose"] = end
        if truth is not None:
            ref = dict(zip(("x", "y", "theta"), truth.end))
            summary["reference_end_pose"] = ref
            err = {f"d{k}": end[k] - ref[k] for k in ("x", "y", "theta")}
            err["position"] = math.hypot(err["dx"], err["dy"])
            summary["error"] = err
            summary["match"] = (round(end["x"], 3) == round(ref["x"], 3)
                                and round(end["y"], 3) == round(ref["y"], 3))
    from .report.chassis_compare import pose_summaries
    if pose is None and (poses := pose_summaries(graph, results)):
        summary["poses"] = poses          # several chassis in one run, each with its truth
    from .models.modes import constant_twist_signs
    if (signs := constant_twist_signs(graph, results)) is not None:
        summary["wheel_signs"] = signs    # only for a constant commanded twist
    return summary


def report_lines(summary: dict) -> list[str]:
    lines = [f"{summary['scenario']}: {summary['master']}, step {summary['step_size']:g} s, "
             f"{summary['steps']} steps, stepping loop {summary['wall_time_s']:.3f} s"]
    if "end_pose" in summary:
        end = summary["end_pose"]
        lines.append(f"end point (co-simulation): x = {end['x']:.3f}, y = {end['y']:.3f}")
        if "reference_end_pose" in summary:
            ref, err = summary["reference_end_pose"], summary["error"]
            lines.append(f"end point (ground truth):  x = {ref['x']:.3f}, y = {ref['y']:.3f}")
            lines.append(f"error: dx = {err['dx']:.3e}, dy = {err['dy']:.3e}, "
                         f"|e| = {err['position']:.3e} m")
            lines.append("match!" if summary["match"] else
                         "no match (the end points differ at 3 decimals; try a smaller step)")
    if "poses" in summary:
        from .report.chassis_compare import pose_report_lines
        lines += pose_report_lines(summary["poses"])
    if "wheel_signs" in summary:
        lines.append(f"wheel signs (constant twist): {summary['wheel_signs']}")
    return lines
