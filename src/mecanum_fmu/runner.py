"""`run` as a library call: load, check, simulate, compare with the ground truth, write.

Results are written in the order that keeps the most on a failure: CSV and summary first,
plots last; a run that fails mid-way still writes every row recorded up to the failure.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .scenario.arguments import check_prepare, check_run
from .bag_output import check_room, remove_previous, write_run_bag
from .errors import (ArgumentError, Interrupted, MecanumError, Problem, ScenarioError,
                     SimulationError)
from .scenario.graph import Graph, compile_graph
from .models.rebuild import build_bundled
from .models.topology import Topology, topology
from .report import against_recorded
from .report.evaluation import Evaluation, evaluate, report_lines as evaluation_lines
from .report.truth import Truth
from .output import OutputFolder, summarize
from .report.plot_worker import PlotWorker
from .process import sigterm_raises, signals_deferred
from .masters import tolerance_master
from .results import Results, error_estimate_lines
from .scenario.document import (MAPPING_LABEL, Scenario, override_experiment, read_scenario,
                       scenario_from_doc)


@dataclass(repr=False)
class RunOutcome:
    scenario: Scenario
    graph: Graph
    results: Results
    evaluation: Evaluation
    summary: dict
    out_dir: Path
    files: list[Path]

    @property
    def truth(self) -> Truth | None:
        """The single pose's ground truth (None: none, or several poses)."""
        return self.evaluation.truth

    def __repr__(self) -> str:
        match = self.summary.get("match")
        return (f"RunOutcome({self.scenario.name!r}, out_dir={str(self.out_dir)!r}, "
                f"complete={self.results.complete}, steps={self.results.steps}"
                + (f", match={match}" if match is not None else "")
                + f", files={len(self.files)})")


def prepare(path: str | Path | dict, *, step_size: float | None = None,
            stop_time: float | None = None, master_name: str | None = None,
            fmu_dir: Path | None = None, build: bool = True,
            parameters: dict | None = None, tolerance: float | None = None,
            relative_tolerance: float | None = None, estimate: str | None = None) -> Graph:
    """Load and check a scenario (a file, or a mapping of a file's keys whose relative paths
    are taken from the working folder) with command-line overrides and `parameters`
    ({"w2c.R": 0.061}, or a shared {"R": 0.061}) and `tolerance` (the adaptive master; with
    `relative_tolerance`, an output y may err tolerance + relative_tolerance |y|), `estimate`
    (how the run's error is estimated: masters.ESTIMATES), and
    compile its graph. Every problem is
    raised at once (ScenarioError; errors.ArgumentError for an argument of the wrong kind),
    the file's own together with the graph's. With build (the default), the bundled FMUs it
    uses are built first when missing or stale; without (validate), such an FMU is reported
    as a problem with the command that builds it."""
    check_prepare(path, step_size, stop_time, master_name, fmu_dir, parameters, tolerance,
                  estimate)
    scenario, problems = _read(path, parameters)
    changes = {k: v for k, v in (("step_size", step_size), ("stop_time", stop_time),
                                 ("master", master_name), ("tolerance", tolerance),
                                 ("relative_tolerance", relative_tolerance),
                                 ("estimate", estimate))
               if v is not None}
    if scenario is not None and changes:
        try:
            if (picked := tolerance_master(master_name, tolerance, scenario.label)):
                changes["master"] = picked      # a tolerance chooses the adaptive master
            scenario = override_experiment(scenario, changes, scenario.label,
                                           " (from the command line or prepare's arguments)")
        except ScenarioError as err:
            problems += err.problems
    if problems:
        if scenario is not None:        # what the graph would add: every problem at once
            try:
                compile_graph(scenario, fmu_dir)
            except ScenarioError as err:
                problems += [p for p in err.problems if p not in problems]
        raise ScenarioError(problems)
    if build:
        build_bundled(scenario, fmu_dir)
    return compile_graph(scenario, fmu_dir)


def _read(path: str | Path | dict, parameters: dict | None) -> tuple[Scenario | None, list]:
    """The scenario of a file, an SSP archive or a mapping, and the problems found."""
    if isinstance(path, dict):
        return scenario_from_doc(path, Path(MAPPING_LABEL), parameters)
    if Path(path).suffix.lower() in (".ssp", ".ssd"):   # SSP 1.0 archive or bare SSD
        from .interop.ssp_read import load_ssp
        if parameters:
            raise ArgumentError([Problem("runner.prepare()", "argument parameters", "is for "
                                 "YAML scenarios and mappings; set an SSP's parameters in its "
                                 "SSD, or export-ssp the scenario with them")])
        return load_ssp(path), []
    return read_scenario(path, parameters)


def default_out_dir(scenario: Scenario) -> Path:
    return Path("results") / scenario.name


# What runner.run keeps in memory for the ground truth and the plots: about this many evenly
# spaced rows plus the exact last one (results.csv holds every row).
KEEP_ROWS = 10_000


def run(graph: Graph, out_dir: Path | None = None, *, plots: bool = True,
        progress: Callable[[float], None] | None = None,
        log: Callable[[str], None] | None = None, quiet: bool = True, animate: bool = False,
        keep_rows: int | None = KEEP_ROWS, plotter: PlotWorker | None = None,
        bag: bool = False) -> RunOutcome:
    """Simulate, write results.csv, summary.json and the plots into out_dir.

    results.csv is written during the run; the outcome's Results hold `keep_rows` rows (None:
    every row). The folder is checked and locked first (ScenarioError). A failure after the
    stepping loop (ground truth, plots) costs only itself: the tables are written first.
    The report lines go to `log`; without one they are printed unless `quiet` (the default).
    `plotter`: a plot worker started earlier (the CLI starts it before loading, to hide
    matplotlib's import); without one, one is started here when plots are wanted.
    `bag`: also write the run as a ROS 2 MCAP bag in out_dir/bag/ (bag_output.py; a complete
    run only)."""
    check_run(graph, out_dir, progress, log, keep_rows)
    out_dir = Path(out_dir) if out_dir is not None else default_out_dir(graph.scenario)
    log = log if log is not None else (_silent if quiet else print)
    topo = topology(graph)
    plotter = (plotter or PlotWorker.start()) if plots else None    # imports matplotlib now
    try:
        with sigterm_raises(), OutputFolder(out_dir) as out:
            remove_previous(out.path)       # an earlier run's bag/ is not this run's
            if bag:
                check_room(out.path)
            try:
                outcome = _run_in(graph, topo, out, plotter=plotter, progress=progress,
                                  log=log, animate=animate, keep_rows=keep_rows, bag=bag)
            except MecanumError as err:
                out.record(err.files)      # named in summary.json: a re-run removes them
                raise
            out.record(outcome.files)
            return outcome
    finally:
        if plotter is not None:
            plotter.cancel()        # stops the worker if the plots were not drawn


def _silent(line: str) -> None:
    pass


def _run_in(graph: Graph, topo: Topology, out: OutputFolder, *, plotter: PlotWorker | None,
            progress, log, animate: bool, keep_rows: int | None, bag: bool) -> RunOutcome:
    results, summary, files = _simulate_into(graph, topo, out, plotter, progress, keep_rows)
    if bag:
        summary["bag"] = _bag(out, topo, files)
    if plotter is not None:     # it draws what needs no truth while the truth is integrated
        plotter.draft(results, topo.roles, graph.scenario.name)
    evaluation = evaluate(graph, results, topo=topo)    # after the tables: it costs only itself
    from .master import estimate_error  # here: `validate` needs no FMI runtime
    if graph.scenario.recorded:
        summary["against_recorded"] = against_recorded.compare(results, graph.scenario.recorded)
    if added := evaluation.summary() | estimate_error(graph, results):
        summary.update(added)
        _rewrite_summary(out, summary, files)
    for line in report_lines(summary):
        log(line)
    if graph.scenario.recorded and plotter is not None:
        with out.atomic("recorded.png") as temp:
            against_recorded.write_figure(results, graph.scenario.recorded, temp)
        files.append(out.path / "recorded.png")
    stage = "plots"         # the plots and the animation; a failure is reported, files kept
    try:
        if plotter is not None:
            files += plotter.finish(results, evaluation, out.path, title=graph.scenario.name)
        stage = "animation"
        if animate:
            from .report.animation import write_animation   # startup: matplotlib
            with out.atomic("animation.gif") as temp:       # no half-written GIF
                write_animation(results, evaluation, temp)
            files.append(out.path / "animation.gif")
    except Exception as err:    # the results are written: report the figure, keep the rest
        failed = MecanumError(f"writing the {stage} into {out.path} failed: "
                              f"{type(err).__name__}: {err}", files=files)
        summary[f"{stage}_error"] = str(failed)
        _rewrite_summary(out, summary, [])
        raise failed from err
    if evaluation.failure:
        raise MecanumError(f"the ground truth could not be computed ({evaluation.failure}); "
                           f"the run itself is complete", files=files)
    return RunOutcome(graph.scenario, graph, results, evaluation, summary, out.path, files)


def _bag(out: OutputFolder, topo: Topology, files: list[Path]) -> dict:
    """The run as a ROS 2 bag (bag_output.py), after the tables: a failure costs only it."""
    try:
        with signals_deferred():
            return write_run_bag(out.path / "results.csv", topo.drives, out.path)
    except OSError as err:
        raise MecanumError(f"writing the bag into {out.path} failed: {err}",
                           files=files) from err


def _rewrite_summary(out: OutputFolder, summary: dict, files: list[Path]) -> None:
    """The summary again, now with the evaluation (or why a stage failed)."""
    try:
        with signals_deferred():
            out.write_json(summary)
    except MecanumError as err:     # output.WriteError: the tables written before are kept
        err.files.extend(files)
        raise


def _simulate_into(graph: Graph, topo: Topology, out: OutputFolder, plotter: PlotWorker | None,
                   progress, keep_rows: int | None) -> tuple[Results, dict, list[Path]]:
    """Run with results.csv streamed into `out` (the plot worker, told first what the run
    records, prepares its frame meanwhile); write the summary (without the evaluation).
    A failed or interrupted run still keeps its tables (with its end poses) and raises; a
    write error (output.WriteError) leaves no results.csv."""
    from . import master  # here: `validate` needs neither the FMI runtime nor matplotlib
    if plotter is not None:
        plotter.expect(graph, topo.roles)
    stream = None
    try:
        stream = out.csv_stream(tuple(str(p.ref) for p in graph.recorded))
        try:
            results = master.simulate(graph, graph.scenario.experiment, progress=progress,
                                      sink=stream, keep_rows=keep_rows, with_estimate=True)
        except (SimulationError, Interrupted) as err:
            if err.results is not None:
                with signals_deferred():
                    ends = evaluate(graph, err.results, topo=topo, with_truth=False).summary()
                    summary = summarize(graph, err.results) | ends
                    summary["error_message"] = str(err)
                    err.files.extend(out.write_tables(stream, summary))
            raise
        with signals_deferred():
            summary = summarize(graph, results)
            return results, summary, out.write_tables(stream, summary)
    finally:                    # a write failed (output.WriteError) or a bug: no half file
        if stream is not None and stream.temp.exists():
            stream.abort()


def report_lines(summary: dict) -> list[str]:
    return [f"{summary['scenario']}: {summary['master']}, step {summary['step_size']:g} s, "
            f"{summary['steps']} steps, stepping loop {summary['wall_time_s']:.3f} s",
            *([f"ended early: {summary['ended_by']}"] if "ended_by" in summary else []),
            *evaluation_lines(summary), *error_estimate_lines(summary),
            *against_recorded.report_lines(summary.get("against_recorded", {}))]
