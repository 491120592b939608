"""Command line: `python -m mecanum_fmu run|validate|fmus|info|export-ssp|cross-check|sweep|doctor`
(`COMMANDS` below). The one place that turns the package's exceptions into messages and exit
codes (0 ok, 1 simulation failed, 2 bad input, 130 interrupted, 143 terminated by SIGTERM)."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from . import __version__
from .scenario import plausibility
from .errors import Interrupted, MecanumError, Problem, ScenarioError, SimulationError
from .masters import DEFAULT as DEFAULT_MASTER, DEFAULT_ESTIMATE, ESTIMATES, MASTERS, \
    entry as master_entry


def _number(text: str) -> float:
    # ranges (step > 0, stop > start) are checked with the scenario's own experiment check
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _positive(text: str) -> float:
    value = _number(text)
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number > 0")
    return value


def _non_negative(text: str) -> float:
    value = _number(text)
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number >= 0")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mecanum-fmu",
        description="Co-simulate a four-wheel mecanum car from FMI 2.0 FMUs wired in a YAML scenario.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for add in COMMANDS:
        add(sub)
    return parser


def _add_run(sub) -> None:
    run = sub.add_parser("run", help="simulate a scenario and write results, summary and plots",
                         description="Simulate a scenario; write results.csv, summary.json and "
                                     "plots to results/<name>/ (or --out).")
    run.add_argument("scenario", nargs="+", help="scenario file (.yaml); several run one after "
                     "another, each into --out/<file name> (default results/<scenario name>)")
    run.add_argument("--out", type=Path, help="output folder (default: results/<scenario name>)")
    run.add_argument("--step-size", type=_number, help="communication step (s)")
    run.add_argument("--stop-time", type=_number, help="end of the run (s)")
    run.add_argument("--master", help=f"{', '.join(MASTERS)} (default {DEFAULT_MASTER}; "
                     "docs/masters.md)")
    run.add_argument("--tolerance", type=_positive, metavar="TOL",
                     help="choose the step to keep every recorded output's estimated error "
                     "under TOL (in its unit): the adaptive master; rows stay every "
                     "--step-size s")
    run.add_argument("--relative-tolerance", type=_non_negative, metavar="RTOL",
                     help="with --tolerance: an output y may err TOL + RTOL |y| (default 0; "
                     "docs/masters.md)")
    run.add_argument("--estimate", choices=tuple(ESTIMATES),
                     help="how the run's error is estimated: " + "; ".join(
                         f"{k}: {v}" for k, v in ESTIMATES.items())
                     + f" (default {DEFAULT_ESTIMATE}; docs/masters.md)")
    run.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    run.add_argument("--animate", action="store_true", help="also write animation.gif")
    run.add_argument("--bag", action="store_true",
                     help="also write the run as a ROS 2 MCAP bag in OUT/bag/ (docs/bags.md)")
    run.add_argument("--quiet", "-q", action="store_true", help="print only errors")
    run.add_argument("--fmu-dir", type=Path, help=argparse.SUPPRESS)
    run.set_defaults(func=cmd_run)


def _add_validate(sub) -> None:
    val = sub.add_parser("validate", help="check a scenario and its FMUs without running",
                         description="Check a scenario and its FMUs; report every problem.")
    val.add_argument("scenario")
    val.add_argument("--strict", action="store_true",
                     help="treat plausibility warnings (units, table span, unstable gains) as "
                          "errors (exit 2)")
    val.add_argument("--fmu-dir", type=Path, help=argparse.SUPPRESS)
    val.set_defaults(func=cmd_validate)


def _add_fmus(sub) -> None:
    fmus = sub.add_parser("fmus", help="build the bundled FMUs",
                          description="Build every bundled model (the four blocks of the "
                                      "mecanum study and the other chassis) into fmus/ (only "
                                      "what changed).")
    fmus.add_argument("--dest", type=Path, help="output folder (default: fmus/)")
    fmus.add_argument("--force", action="store_true", help="rebuild even if up to date")
    fmus.set_defaults(func=cmd_fmus)


def _add_info(sub) -> None:
    info = sub.add_parser("info", help="describe an FMU: variables, structure, capabilities",
                          description="Print an FMU's interface: variables, units, "
                                      "dependencies, capabilities.")
    info.add_argument("fmu", help="an .fmu file or a bundled model name")
    info.set_defaults(func=cmd_info)


def _add_export_ssp(sub) -> None:
    exp = sub.add_parser("export-ssp", help="write a scenario as an SSP 1.0 archive",
                         description="Check a scenario and write it, with its FMUs, as an "
                                     "SSP 1.0 archive (.ssp) for other co-simulation tools.")
    exp.add_argument("scenario", help="scenario file (.yaml, .ssp or .ssd)")
    exp.add_argument("-o", "--output", type=Path, required=True, help="the .ssp file to write")
    exp.add_argument("--fmu-dir", type=Path, help=argparse.SUPPRESS)
    exp.set_defaults(func=cmd_export_ssp)


def _add_cross_check(sub) -> None:
    cross = sub.add_parser("cross-check", help="run a scenario in libcosim and Ecos too and "
                           "compare with our Jacobi master",
                           description="Export the scenario as SSP, run it in other FMI hosts "
                                       "(libcosim, Ecos, Ecos' command-line program) with the "
                                       "same step, and compare their end values with our "
                                       "Jacobi master (all three use the Jacobi scheme). Exit 1 "
                                       "if a host disagrees or fails.")
    cross.add_argument("scenario", help="scenario file (.yaml, .ssp or .ssd)")
    cross.add_argument("--step-size", type=_number, help="communication step (s)")
    cross.add_argument("--stop-time", type=_number, help="end of the run (s)")
    cross.add_argument("--hosts", default="libcosim,ecos,ecos-cli",
                       help="comma-separated, from: libcosim, ecos, ecos-cli (default: all)")
    cross.add_argument("--require", action="store_true",
                       help="exit 1 when a host is not installed (default: say so and go on)")
    cross.add_argument("--fmu-dir", type=Path, help=argparse.SUPPRESS)
    cross.set_defaults(func=cmd_cross_check)



def _add_sweep(sub) -> None:
    sweep = sub.add_parser("sweep", help="many runs of a scenario (grid and/or random draws) "
                           "on a Dask cluster",
                           description="Run the grid and random draws of a sweep file on a Dask "
                                       "cluster; write runs.csv, summary.json and plots to "
                                       "results/<name>/ (or --out). See docs/sweeps.md.")
    sweep.add_argument("sweep", help="sweep file (.yaml)")
    sweep.add_argument("--out", type=Path, help="output folder (default: results/<sweep name>)")
    sweep.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    sweep.add_argument("--scheduler", help="address of a running `dask scheduler` "
                       "(tcp://HOST:PORT) instead of local workers")
    sweep.add_argument("--max-runs", type=int, default=None, metavar="N",
                       help="allow up to N runs (default: 100000; each run is a row held in "
                            "memory)")
    sweep.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    sweep.add_argument("--fmu-dir", type=Path, help=argparse.SUPPRESS)
    sweep.set_defaults(func=cmd_sweep)


def _add_doctor(sub) -> None:
    doctor = sub.add_parser("doctor", help="what each FMU needs on a target machine (Python, glibc, win64)",
                            description="Print, per FMU, whether it is self-contained (carries "
                                        "its Python), the glibc version and system libraries "
                                        "its Linux binaries need, and what a Windows host needs.")
    doctor.add_argument("--fmu-dir", type=Path, help=argparse.SUPPRESS)
    doctor.set_defaults(func=cmd_doctor)


COMMANDS = (_add_run, _add_validate, _add_fmus, _add_info, _add_export_ssp, _add_cross_check, _add_sweep,
            _add_doctor)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from .process import Terminated, sigterm_raises
    try:
        with sigterm_raises():
            return args.func(args) or 0
    except ScenarioError as err:
        print(f"error: {len(err.problems)} problem(s) in the input:" if len(err.problems) > 1
              else "error:", file=sys.stderr)
        for problem in err.problems:
            print(f"  {problem}", file=sys.stderr)
        return err.exit_code
    except (SimulationError, Interrupted) as err:
        print(f"error: simulation failed: {err}" if isinstance(err, SimulationError)
              else f"{err}", file=sys.stderr)
        for path in err.files:
            print(f"  kept: {path}", file=sys.stderr)
        return err.exit_code
    except MecanumError as err:
        print(f"error: {err}", file=sys.stderr)
        for path in err.files:      # e.g. the plots failed after the run
            print(f"  kept: {path}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt as err:    # outside the stepping loop: loading, plotting
        if isinstance(err, Terminated):     # SIGTERM
            print("terminated (SIGTERM)", file=sys.stderr)
            return 143
        print("interrupted", file=sys.stderr)
        return Interrupted.exit_code


def exit_with(argv: list[str] | None = None) -> None:
    """The console entry point: run main() and leave without interpreter shutdown (see
    process.exit_now; with pythonfmu FMUs loaded CPython's finalization aborts now and then)."""
    from .process import exit_now
    try:
        code = main(argv)      # SystemExit (--help, bad options) and bugs propagate as usual
    except BrokenPipeError:    # `... | head`: the reader left; stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = 141
    except BaseException:
        if "mecanum_fmu.runtime" in sys.modules:    # a bug: still no extraction left behind
            from .runtime import RUNTIME
            RUNTIME.remove_extractions()
        raise
    exit_now(code)


def _progress(enabled: bool):
    if not enabled or not sys.stderr.isatty():
        return None

    def show(fraction: float) -> None:
        print(f"\r  {100 * fraction:5.1f} %", end="", file=sys.stderr, flush=True)
    return show


def _run_several(args) -> int:
    """`run a.yaml b.yaml ...`: each in turn; the first failure stops with its exit code."""
    for path in args.scenario:
        out = args.out / Path(path).stem if args.out is not None else None
        one = argparse.Namespace(**{**vars(args), "scenario": [path], "out": out})
        if (code := cmd_run(one)) != 0:
            return code
    return 0


def cmd_run(args) -> int:
    if len(args.scenario) > 1:
        return _run_several(args)
    args.scenario = args.scenario[0]
    from .report.plot_worker import PlotWorker
    plotter = None if args.no_plots else PlotWorker.start()   # imports matplotlib meanwhile
    from .runner import prepare, run
    try:
        graph = prepare(args.scenario, step_size=args.step_size, stop_time=args.stop_time,
                        master_name=args.master, fmu_dir=args.fmu_dir, tolerance=args.tolerance,
                        relative_tolerance=args.relative_tolerance, estimate=args.estimate)
    except BaseException:
        if plotter is not None:
            plotter.cancel()
        raise
    if not args.quiet:
        for warning in graph.warnings:
            print(f"warning: {warning}", file=sys.stderr)
    progress = _progress(not args.quiet)
    log = (lambda line: None) if args.quiet else print
    try:
        outcome = run(graph, args.out, plots=not args.no_plots, progress=progress, log=log,
                      animate=args.animate, plotter=plotter, bag=args.bag)
    finally:
        if progress is not None:
            print("\r" + " " * 12 + "\r", end="", file=sys.stderr)
    if not args.quiet:
        print(f"wrote {len(outcome.files)} files to {outcome.out_dir}/"
              + (f" and the ROS 2 bag {outcome.out_dir}/bag/" if "bag" in outcome.summary else ""))
    return 0


def cmd_validate(args) -> int:
    from .runner import prepare
    graph = prepare(args.scenario, fmu_dir=args.fmu_dir, build=False)
    strict = plausibility.problems(graph.scenario, graph.instances) if args.strict else []
    for warning in graph.warnings:
        if warning not in {str(p) for p in strict}:
            print(f"warning: {warning}", file=sys.stderr)
    if strict:
        raise ScenarioError(strict)
    exp = graph.scenario.experiment
    print(f"{graph.scenario.label}: ok - {len(graph.instances)} components, "
          f"{len(graph.links)} connections, {exp.master}, "
          f"step {exp.step_size:g} s over [{exp.start_time:g}, {exp.stop_time:g}] s")
    print("step order: " + " -> ".join(i.name for i in graph.instances))
    if graph.held and master_entry(exp.master).holds_samples:
        pairs = dict.fromkeys(f"{l.source.ref.instance} -> {l.target.ref.instance}"
                              for l in graph.held)
        again = [i.name for i in graph.instances if i.name in graph.settled]
        print(f"samples held from the step's start: {', '.join(pairs)}; read again after "
              f"each sample: {', '.join(again) or 'none'} (docs/masters.md, \"Samples\")")
    return 0


def cmd_fmus(args) -> int:
    from .models.build import build_all
    from .models.build3 import build_all3
    from .models.library import default_fmu_dir

    def report(path, state):
        print(f"{path}  ({path.stat().st_size // 1024} KiB, {state})")
    build_all(args.dest or default_fmu_dir(), only_stale=not args.force, report=report)
    build_all3(args.dest or default_fmu_dir(), only_stale=not args.force, report=report)  # fmi3/
    from .models.embed import summary
    print(summary() + " (details: python -m mecanum_fmu doctor, docs/other-tools.md)")
    return 0


def cmd_info(args) -> int:
    from .models.library import default_fmu_dir, read_description, resolve_fmu
    try:
        path = resolve_fmu(args.fmu, Path.cwd(), default_fmu_dir())
        md = read_description(path)
    except ValueError as err:
        raise ScenarioError([Problem(args.fmu, "", str(err))]) from None
    print(f"{md.modelName} (FMI {md.fmiVersion} co-simulation) - {path}")
    if md.description:
        print(f"  {md.description}")
    cs = md.coSimulation
    print(f"  can get/set state: {bool(cs.canGetAndSetFMUstate)}, variable step: "
          f"{bool(cs.canHandleVariableCommunicationStepSize)}, needs execution tool: "
          f"{bool(cs.needsExecutionTool)}")
    deps = {o.variable.name: o.dependencies for o in md.outputs}
    for var in md.modelVariables:
        unit = f" [{var.unit}]" if getattr(var, "unit", None) else ""
        start = f" = {var.start}" if var.start is not None else ""
        extra = ""
        if var.name in deps:
            d = deps[var.name]
            extra = "  depends on: " + ("(not declared: all inputs)" if d is None
                                         else ", ".join(x.name for x in d) or "nothing (no feedthrough)")
        print(f"  {var.causality:>9} {var.type:<7} {var.name}{unit}{start}{extra}")
    if any(d is None for d in deps.values()):
        print("  (a scenario may declare what the FMU does not: `dependencies: {OUTPUT: "
              "[INPUTS]}` in its component; docs/masters.md)")
    return 0


def cmd_export_ssp(args) -> int:
    from .runner import prepare
    from .interop.ssp_write import export_ssp
    graph = prepare(args.scenario, fmu_dir=args.fmu_dir)
    path = export_ssp(graph, args.output)
    print(f"wrote {path} ({len(graph.instances)} components, {len(graph.links)} connections)")
    said = [c.name for c in graph.scenario.components if c.dependencies]
    if said:
        print(f"note: the dependencies: of {', '.join(said)} are the scenario's, not the FMUs': "
              "the SSP has no place for them, and a host that reads them from the FMUs may "
              "see an algebraic loop", file=sys.stderr)
    return 0


def cmd_cross_check(args) -> int:
    from .interop.cross_check import cross_check, report_lines
    from .report.ground_truth import ground_truth
    from .interop.other_hosts import HOSTS
    from .runner import prepare
    hosts = [h.strip() for h in args.hosts.split(",") if h.strip()]
    unknown = [h for h in hosts if h not in HOSTS]
    if unknown or not hosts:
        raise ScenarioError([Problem("command line", "--hosts", f"unknown host(s) "
                             f"{', '.join(unknown) or '(none given)'}; choose from "
                             f"{', '.join(HOSTS)}")])
    graph = prepare(args.scenario, step_size=args.step_size, stop_time=args.stop_time,
                    fmu_dir=args.fmu_dir)
    check = cross_check(graph, hosts)
    exp = graph.scenario.experiment
    try:
        truth = ground_truth(graph, [exp.start_time, exp.stop_time])
    except Exception as err:    # costs only itself, as in run
        print(f"warning: no ground truth: {type(err).__name__}: {err}", file=sys.stderr)
        truth = None
    for line in report_lines(check, truth.end[:2] if truth is not None else None):
        print(line)
    bad = [r for r in check.rows if not r.agrees and (args.require or not r.missing)]
    return 1 if bad else 0


def cmd_doctor(args) -> int:
    from .interop.doctor import doctor_lines
    for line in doctor_lines(args.fmu_dir):
        print(line)
    return 0


def _sweep_progress():
    def show(done: int, total: int) -> None:
        bar = "#" * (30 * done // total)
        print(f"\r  [{bar:<30}] {done}/{total} runs", end="", file=sys.stderr, flush=True)
        if done == total:
            print("\r" + " " * 60 + "\r", end="", file=sys.stderr, flush=True)
    return show


def cmd_sweep(args) -> int:
    from .sweep.cluster import run_sweep
    from .sweep.spec import MAX_RUNS
    show = _sweep_progress() if sys.stderr.isatty() else None
    try:
        summary = run_sweep(args.sweep, args.out, workers=args.workers, scheduler=args.scheduler,
                            plots=not args.no_plots, fmu_dir=args.fmu_dir, progress=show,
                            max_runs=MAX_RUNS if args.max_runs is None else args.max_runs)
    finally:
        if show is not None:
            print("\r" + " " * 60 + "\r", end="", file=sys.stderr)
    return 0 if summary["failed"] == 0 else 1
