"""Accuracy per cost: per scenario with a ground truth and per master, the end-point error
against doStep passes and wall time; the adaptive master at several tolerances against the best
fixed step that meets each (bisection over the steps that land on the output grid); a
zero-order-hold host (libcosim or Ecos) at a fixed step on our exported SSP where installed.

A "pass" is one doStep of every FMU of the graph: the fixed masters take one per step (two in a
feedback loop under quadratic), the adaptive master one per step taken or rejected (two in a
loop). Errors are |end point - ground truth| in m (report/ground_truth.py); "estimate" is the
adaptive master's own at the end (summary.json's error_estimate, |(x, y)|). Wall times are of
the stepping loop, on whatever else this machine runs: compare within one run.

Run: make bench  (or: .venv/bin/python bench/accuracy.py [--quick] [--plot PATH])
It writes results/bench/accuracy.png (never a tracked file); the docs' plot is made with
  .venv/bin/python bench/accuracy.py --plot docs/img/accuracy.png
"""
from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from mecanum_fmu import master
from mecanum_fmu.interop.other_hosts import HostFailed, HostUnavailable, run_host
from mecanum_fmu.interop.ssp_write import export_ssp
from mecanum_fmu.masters import MASTERS, entry
from mecanum_fmu.process import exit_now
from mecanum_fmu.report.ground_truth import ground_truth
from mecanum_fmu.results import BELOW_ROUND_OFF
from mecanum_fmu.runner import prepare

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("circle.yaml", "chassis/omni_field_circle.yaml", "profiles/joystick.yaml",
             "profiles/quiet_then_busy.yaml", "modes/showcase.yaml", "modes/figure_eight.yaml")
FIXED = tuple(m for m in MASTERS if not entry(m).adaptive)
DIVIDE = (1, 2, 4)                      # fixed steps: the output interval / these
TOLERANCES = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)


def with_experiment(graph, **changes):
    exp = dataclasses.replace(graph.scenario.experiment, **changes)
    return dataclasses.replace(graph, scenario=dataclasses.replace(graph.scenario,
                                                                   experiment=exp)), exp


def measure(graph, **changes) -> dict:
    graph, exp = with_experiment(graph, **changes)
    res = master.simulate(graph, exp)
    truth = ground_truth(graph, res.time)
    pose = next(n[:-2] for n in res.names if n.endswith(".x") and n[:-2] + ".theta" in res.names)
    err = float(np.hypot(res[pose + ".x"][-1] - truth.x[-1], res[pose + ".y"][-1] - truth.y[-1]))
    own = res.extra.get("error_estimate", {})        # the adaptive master's own, at the end
    ends = [own[pose + k]["end"] for k in (".x", ".y")] if pose + ".x" in own else None
    # "below round-off" (a string) for both: shown as such; for one: that one counts 0; an
    # end left unresolved (another string: its terms cancel) leaves |(x, y)| unresolved
    estimate = None if ends is None else "unresolved" if any(
        isinstance(e, str) and not _below(e) for e in ends) else BELOW_ROUND_OFF if all(
        map(_below, ends)) else float(np.hypot(*(0.0 if _below(e) else e for e in ends)))
    return {"master": exp.master, "h": exp.step_size, "tol": exp.tolerance, "err": err,
            "estimate": estimate, "passes": _passes(graph, res), "wall": res.wall_time}


def _below(value) -> bool:
    return value == BELOW_ROUND_OFF


def _passes(graph, res) -> int:
    twice = 2 if entry(res.master).rolls_back and _has_loop(graph) else 1
    if res.steps_taken is not None:
        return twice * (res.steps_taken + res.steps_rejected)
    return twice * res.steps


def _has_loop(graph) -> bool:
    position = {inst.name: i for i, inst in enumerate(graph.instances)}
    return any(position[l.source.ref.instance] > position[l.target.ref.instance]
               for l in graph.links)


def best_fixed(graph, tolerance: float, cache: dict) -> dict | None:
    """The fewest passes of a fixed quadratic step h_out / m that meets the tolerance:
    m doubled until it does, then bisected."""
    h_out = graph.scenario.experiment.step_size

    def run(m: int) -> dict:
        if m not in cache:
            cache[m] = measure(graph, master="quadratic", step_size=h_out / m)
        return cache[m]
    low, m = 0, 1
    while run(m)["err"] > tolerance:
        low, m = m, 2 * m
        if m > 256:
            return None
    while m - low > 1:
        mid = (low + m) // 2
        low, m = (low, mid) if run(mid)["err"] <= tolerance else (mid, m)
    return run(m)


def zoh_host(graph) -> str:
    exp = graph.scenario.experiment
    names = [n for n in (str(p.ref) for p in graph.recorded) if n.endswith((".x", ".y"))][:2]
    with tempfile.TemporaryDirectory(prefix="mecanum-bench-") as tmp:
        ssp = export_ssp(graph, Path(tmp) / "run.ssp")
        for host in ("libcosim", "ecos"):
            try:
                run = run_host(host, ssp, start=exp.start_time, stop=exp.stop_time,
                               step=exp.step_size, variables=names)
            except (HostUnavailable, HostFailed) as err:
                last = str(err).splitlines()[0]
                continue
            truth = ground_truth(graph, np.array([exp.start_time, exp.stop_time]))
            err = float(np.hypot(run.values[names[0]] - truth.x[-1],
                                 run.values[names[1]] - truth.y[-1]))
            return (f"{host} {run.version} (zero-order hold, h = {exp.step_size:g}): "
                    f"|e| = {err:.2e} m, {run.simulate_s:.3f} s")
    return f"no zero-order-hold host installed ({last})"


def scenario_rows(name: str, quick: bool) -> tuple[list[dict], list[tuple]]:
    graph = prepare(ROOT / "scenarios" / name)
    h_out = graph.scenario.experiment.step_size
    fixed = [measure(graph, master=m, step_size=h_out / d) for m in FIXED for d in DIVIDE]
    cache = {d: r for d, r in zip(DIVIDE, fixed[:len(DIVIDE)])}
    adaptive, table = [], []
    for tol in TOLERANCES[:3] if quick else TOLERANCES:
        row = measure(graph, master="adaptive", tolerance=tol)
        adaptive.append(row)
        table.append((tol, row, best_fixed(graph, tol, cache)))
    return fixed + adaptive, table


def print_scenario(name: str, rows: list[dict], table: list[tuple], host: str) -> None:
    print(f"\n== {name}")
    print(f"{'master':<13} {'h or TOL':>9} {'|error| m':>10} {'passes':>7} {'wall s':>8}")
    for r in rows:
        knob = r["tol"] if r["master"] == "adaptive" else r["h"]
        print(f"{r['master']:<13} {knob:>9.3g} {r['err']:>10.2e} {r['passes']:>7d} "
              f"{r['wall']:>8.3f}")
    print(f"{'TOL':>7} {'true |e|':>9} {'estimate':>9} {'<= TOL':>6} {'passes':>7} "
          f"{'best fixed':>10} {'its h':>9} {'ratio':>6}")
    for tol, row, best in table:
        fixed = f"{best['passes']:>10d} {best['h']:>9.3g} {row['passes'] / best['passes']:>6.2f}" \
            if best is not None else f"{'none':>10}"
        shown = f"{row['estimate']:.2e}" if isinstance(row["estimate"], float) else \
            str(row["estimate"])
        print(f"{tol:>7.0e} {row['err']:>9.2e} {shown:>9} "
              f"{str(row['err'] <= tol):>6} {row['passes']:>7d} {fixed}")
    print(f"host: {host}")


def plot(everything: dict, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg   # here: start-up
    from matplotlib.figure import Figure
    lines = -(-len(everything) // 3)
    fig = Figure(figsize=(11, 3.5 * lines))
    FigureCanvasAgg(fig)
    for i, (name, rows) in enumerate(everything.items()):
        ax = fig.add_subplot(lines, 3, i + 1)
        for m, marker in zip(MASTERS, "Dos^*"):
            mine = [r for r in rows if r["master"] == m and r["err"] > 0]
            if mine:
                ax.loglog([r["passes"] for r in mine], [r["err"] for r in mine], marker=marker,
                          label=m, lw=0.8, ms=4)
        ax.set_title(name, fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=7)
        if i % 3 == 0:
            ax.set_ylabel("end-point error [m]", fontsize=8)
        if i >= 3 * (lines - 1):
            ax.set_xlabel("doStep passes", fontsize=8)
    fig.axes[0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    print(f"wrote {path}")


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="three tolerances, no 1e-5/1e-6")
    parser.add_argument("--plot", type=Path, default=ROOT / "results" / "bench" / "accuracy.png")
    parser.add_argument("--scenario", action="append", choices=SCENARIOS,
                        help="only this one (repeatable; default: all)")
    args = parser.parse_args(argv)
    everything = {}
    for name in args.scenario or SCENARIOS:
        rows, table = scenario_rows(name, args.quick)
        host = zoh_host(prepare(ROOT / "scenarios" / name))
        print_scenario(name, rows, table, host)
        print(flush=True)
        everything[name] = rows
    plot(everything, args.plot)
    return everything


if __name__ == "__main__":
    main()
    exit_now(0)      # no interpreter shutdown with pythonfmu FMUs loaded
