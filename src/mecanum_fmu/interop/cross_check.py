"""Cross-check a scenario in other FMI hosts: export it as SSP, run it in libcosim and Ecos,
and compare their end values with our Jacobi master at the same communication step.

libcosim's fixed-step algorithm and Ecos step every FMU from the values all FMUs had at the
start of the step - the Jacobi scheme - so with the same step the three must agree to rounding.
They differ only in how the clock is kept (ours: start + k*h; libcosim: integer nanoseconds;
Ecos: adds h each step, 7e-15 s off after 200 steps), which moves the end point by ~1e-14.
TOLERANCE is 1e-9 (relative, floor 1): five orders above that, and five below the smallest
coupling difference we could mistake for it (Gauss-Seidel vs Jacobi differ by 0.19 m on the
circle at h = 0.05, by 1e-3 m at h = 1e-4). Ecos' command-line program writes 6 decimals.

Compared: the Real outputs that depend on no input (ModelStructure dependencies empty): the
pose, the source's signals. An output with direct feedthrough (wheel speeds, body twist) reads
differently after the last step depending on whether the host moves values along the
connections once more before it is read: Ecos does, libcosim and our master do not.
"""
from __future__ import annotations

import dataclasses
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from .. import __version__, master
from ..errors import Problem, ScenarioError
from ..scenario.graph import Graph, port_type
from ..masters import ZOH_HOST
from .other_hosts import HOSTS, HostFailed, HostRun, HostUnavailable, run_host
from .ssp_write import export_ssp

TOLERANCE = 1e-9
CSV_TOLERANCE = 1e-6        # ecos-cli: its CSV rounds to 6 decimals (one unit of the last)
HOST_TOLERANCE = {"ecos-cli": CSV_TOLERANCE}
# libcosimpy 0.0.6 cannot create an execution from an SSP with an FMI 3.0 FMU (measured)
FMI2_ONLY = ("libcosim",)


def compared_outputs(graph: Graph) -> list[str]:
    """Real outputs with an empty dependency list (functions of time and state only)."""
    names = []
    for inst in graph.instances:
        declared = {u.variable.name: u.dependencies for u in inst.model.outputs}
        for var in inst.model.modelVariables:
            if var.causality == "output" and port_type(var) == "Real" \
                    and declared.get(var.name) == []:
                names.append(f"{inst.name}.{var.name}")
    return names


@dataclass(frozen=True)
class Row:
    host: str
    run: HostRun | None
    difference: float | None        # max relative difference from ours over `compared`
    tolerance: float
    problem: str | None = None      # why there is no run
    missing: bool = False           # ... because the host is not installed

    @property
    def agrees(self) -> bool:
        return self.difference is not None and self.difference <= self.tolerance


@dataclass(frozen=True)
class CrossCheck:
    title: str                      # scenario, coupling, step and span
    ours: HostRun
    compared: list[str]
    rows: list[Row]
    ssp: Path | None


def _divides(step: float, span: float) -> bool:
    steps = round(span / step)
    return steps >= 1 and abs(steps * step - span) <= 1e-9 * step


def fixed_step_problem(graph: Graph) -> Problem | None:
    """The other hosts take fixed steps only (our master shortens the last one), so the step
    must divide the run or the runs end at different times."""
    exp = graph.scenario.experiment
    span = exp.stop_time - exp.start_time
    if _divides(exp.step_size, span):
        return None
    nice = [m * 10.0 ** e for e in range(-6, 3) for m in (1, 2, 2.5, 4, 5)]
    fits = [c for c in nice if c <= exp.step_size and _divides(c, span)]
    hint = f", e.g. --step-size {max(fits):g}" if fits else ""
    return Problem(graph.scenario.label, "experiment.step_size", (
        f"{exp.step_size:g} s does not divide the run ({span:g} s): the other hosts take fixed "
        f"steps only, so their runs would end at another time than ours. Choose a step that "
        f"divides it{hint}"))


def difference(a: dict[str, float], b: dict[str, float], names: list[str]) -> float:
    return max(abs(a[n] - b[n]) / max(1.0, abs(b[n])) for n in names)


def ours_jacobi(graph: Graph, names: list[str]) -> HostRun:
    experiment = dataclasses.replace(graph.scenario.experiment, master=ZOH_HOST, tolerance=None)
    t0 = time.perf_counter()
    results = master.simulate(graph, experiment)
    total = time.perf_counter() - t0
    values = {n: results.final(n) for n in names}
    return HostRun(host="mecanum_fmu jacobi", version=__version__,
                   end_time=float(results.time[-1]), values=values,
                   setup_s=total - results.wall_time, simulate_s=results.wall_time)


def cross_check(graph: Graph, hosts: tuple[str, ...] | list[str] = HOSTS,
                workdir: Path | None = None) -> CrossCheck:
    """Run `graph` (with its step size and start/stop) under our Jacobi master and in `hosts`.
    A host that cannot be loaded gets a row with `problem` set (what to install). The SSP is
    kept in `workdir` if given (CrossCheck.ssp), else written to a temporary folder."""
    recorded = {str(p.ref) for p in graph.recorded}
    names = [n for n in compared_outputs(graph) if n in recorded]
    if not names:
        raise ScenarioError([Problem(graph.scenario.label, "outputs", "none of the outputs "
                             "that depend on no input is recorded, so there is nothing to "
                             "compare; drop the `outputs:` list or add the pose to it")])
    exp = graph.scenario.experiment
    problem = fixed_step_problem(graph)
    if problem is not None:
        raise ScenarioError([problem])
    title = (f"{graph.scenario.label}: jacobi coupling, step {exp.step_size:g} s over "
             f"[{exp.start_time:g}, {exp.stop_time:g}] s")
    with tempfile.TemporaryDirectory(prefix="mecanum-cross-") as tmp:
        ssp = export_ssp(graph, Path(workdir or tmp) / f"{graph.scenario.name}.ssp")
        ours = ours_jacobi(graph, names)
        rows = []
        fmi3 = [i.name for i in graph.instances if i.model.fmiVersion.startswith("3.")]
        for host in hosts:
            tolerance = HOST_TOLERANCE.get(host, TOLERANCE)
            if host in FMI2_ONLY and fmi3:
                verb = "is" if len(fmi3) == 1 else "are"
                rows.append(Row(host, None, None, tolerance, f"{host} cannot load FMI 3.0 "
                                f"FMUs and {', '.join(map(repr, fmi3))} {verb} FMI 3.0 (use "
                                "the FMI 2.0 twins, `fmu: <Model>`, for this host)"))
                continue
            try:
                run = run_host(host, ssp, start=exp.start_time, stop=exp.stop_time,
                               step=exp.step_size, variables=names)
            except (HostUnavailable, HostFailed) as err:
                rows.append(Row(host, None, None, tolerance, str(err),
                                missing=isinstance(err, HostUnavailable)))
                continue
            rows.append(Row(host, run, difference(run.values, ours.values, names), tolerance))
    return CrossCheck(title, ours, names, rows, ssp if workdir else None)


def report_lines(check: CrossCheck, exact: tuple[float, float] | None = None) -> list[str]:
    ours = check.ours
    xy = [n for n in check.compared if n.endswith((".x", ".y"))][:2]
    lines = [check.title, f"compared at the end time: {', '.join(check.compared)}"]
    head = f"{'host':<26} {'end time':>9} " + " ".join(f"{n:>12}" for n in xy)
    lines.append(head + f" {'max rel diff':>12} {'setup s':>8} {'steps s':>8}")

    def line(run: HostRun, diff: str) -> str:
        setup = "-" if run.setup_s is None else f"{run.setup_s:.3f}"
        return (f"{run.host + ' ' + run.version:<26} {run.end_time:>9.6g} "
                + " ".join(f"{run.values[n]:>12.7f}" for n in xy)
                + f" {diff:>12} {setup:>8} {run.simulate_s:>8.3f}")
    lines.append(line(ours, "-"))
    for row in check.rows:
        if row.run is None:
            lines.append(f"{row.host:<26} not run: {row.problem}")
        else:
            verdict = "agrees" if row.agrees else f"DIFFERS (tolerance {row.tolerance:g})"
            lines.append(line(row.run, f"{row.difference:.1e}") + f"  {verdict}")
            if (not row.agrees and row.host.startswith("ecos")
                    and abs(row.run.end_time - ours.end_time) < 1e-6):
                lines.append("  (Ecos applies parameter values after its initial value "
                             "propagation, so a chain whose start outputs depend on them "
                             "starts late: docs/other-tools.md)")
    if any(r.run is not None and r.run.setup_s is None for r in check.rows):
        lines.append("(ecos-cli: one number for the whole program - start, load, steps, CSV)")
    if exact is not None and xy:
        err = math.hypot(ours.values[xy[0]] - exact[0], ours.values[xy[1]] - exact[1])
        lines.append(f"ground truth of the commanded twist (an ODE solve, rtol 1e-10): "
                     f"({exact[0]:.7f}, {exact[1]:.7f}); the Jacobi run is {err:.3e} m from it "
                     "(the coupling error is first order in h)")
    return lines
