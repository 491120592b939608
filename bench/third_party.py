"""The error estimate on third-party FMUs with a state (nothing the masters know of): the
embedded pair with their response measured by probes (master/probe.py) against the true
error, and its cost against Richardson's, per master and step, in one process.

Seventeen graphs of test FMUs built here with pythonfmu (tests/fmu_sources/with_state): a source
u = cos t into a lag x' = -2 x + u; u = cos 2t into a speed under quadratic drag v' = u - 3 v
|v| (nonlinear; the truth: the same graph at 1/64 of the step); a chain of two lags (x1' = -2
x1 + cos t, x2' = -x2 + x1: the error forwarded from one into the next); the lag with a
second output y = x + u, which the input reaches directly; a loop, cos t into a
P controller u = 3 (r - x) (no state) around the lag (x' = -2 x + u: the error carried
through the controller's measured Jacobian); and "bare", the first lag with its model
description's dependencies taken out, as pythonfmu and pythonfmu3 write it (an FMU whose
outputs declare none may hold a state: plan.has_state); and "bare_loop", the loop with the
controller's dependencies taken out (a probe at t0 finds it without a state:
master/memory.py); and "lazy", the lag with y = x + u worked out in its doStep alone (it
does not follow u set after the step: probe.lazy); and "spring", cos t into a mass on a
spring with a damper, x'' + 0.4 x' + 4 x = u, its x and v (a response of second order: two
poles, master/probe_fit.py), and "spring_loop", the spring under the P controller (its error
carried around the loop by the modes' shares); and "vdp", the spring as a Van der Pol
oscillator (mu 1, c 0, k 1: its two poles change along the run, and the pair hands over to
Richardson), and "ball", a bouncing ball's height into the lag (a kink at each bounce,
inside a step; the truth: the graph at 1/64 of the step); and three with a response faster
than the step: "stiff", the lag at k = 100 (gone within a step from 0.05 s up: its pole
measured over substeps, probe.Target._faster), "overdamped", the spring at c = 101, k = 100
(poles -1 and -100: the fast one's part of the speed), and "triple", three lags in a row
(x1' = -x1 + cos t, x2' = x1 - 2 x2, x3' = x2 - 300 x3: at 0.01 s two poles fit x3's
response only to 1e-3, and the pair hands over to Richardson); and two whose response bends
inside the FMU: "saturated", cos 2t into the lag, its input saturating at 0.5 inside its
doStep, and "saturated_loop", the loop with that lag. The truths of the linear ones and of
the saturating ones: their ODEs by scipy's DOP853 at rtol 1e-12 (1.6e-12 from the closed
form of "saturated"). Per run and recorded output: the estimate
over the true error for the largest value and the end (within 3x: [0.33, 3]), and the
estimate's cost against the run's stepping time (error_estimate_cost: the pair's NumPy work
and the probes' time, medians of 5 runs; "ms", the same in milliseconds, the pair's own), and
the probes' doStep calls against the run's. The same with `--estimate richardson` for
comparison. Last, the pair's milliseconds split into a fixed part and a part per step (a line
through each graph's and master's steps), and the run length from which it costs at most
0.2x of the stepping.

With --adaptive: the adaptive master at tolerances 1e-2 to 1e-6 on the same graphs, its
steps against the fixed quadratic master's that meet the tolerance, each output's true
error in tolerances and the estimate over it.

Run: .venv/bin/python bench/third_party.py [--adaptive]
"""
from __future__ import annotations

import math
import re
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from helpers import rewrite_description, state_fmus, with_experiment  # noqa: E402
from cost_fit import fit, summary as fit_summary  # noqa: E402
from mecanum_fmu import master  # noqa: E402
from mecanum_fmu.runner import prepare  # noqa: E402

MASTERS = ("quadratic", "trapezoidal", "gauss-seidel", "jacobi")
STEPS = (0.2, 0.1, 0.05, 0.025, 0.01)
REPS = 5
REFINE = 64


GRAPHS = {
    "lag": ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_lag}, parameters: {{k: 2.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.x]""", lambda t, y: [-2 * y[0] + np.cos(t)]),
    "drag": ("""\
  wave: {{fmu: {xtest_wave}, parameters: {{omega: 2.0}}}}
  it: {{fmu: {xtest_drag}, parameters: {{c: 3.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.v]""", None),
    "chain": ("""\
  wave: {{fmu: {xtest_wave}}}
  one: {{fmu: {xtest_lag}, parameters: {{k: 2.0}}}}
  two: {{fmu: {xtest_lag}, parameters: {{k: 1.0}}}}
connections: [[wave.u, one.u], [one.x, two.u]]
outputs: [one.x, two.x]""", lambda t, y: [-2 * y[0] + np.cos(t), y[0] - y[1]]),
    "through": ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_through}, parameters: {{k: 2.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.x, it.y]""", lambda t, y: [-2 * y[0] + np.cos(t), 0.0]),
    "bare": ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_lag_bare}, parameters: {{k: 2.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.x]""", lambda t, y: [-2 * y[0] + np.cos(t)]),
    "loop": ("""\
  wave: {{fmu: {xtest_wave}}}
  ctrl: {{fmu: {xtest_gain}, parameters: {{kp: 3.0}}}}
  plant: {{fmu: {xtest_lag}, parameters: {{k: 2.0}}}}
connections: [[wave.u, ctrl.r], [plant.x, ctrl.y], [ctrl.u, plant.u]]
outputs: [plant.x]""", lambda t, y: [-2 * y[0] + 3 * (np.cos(t) - y[0])]),
}
GRAPHS["spring"] = ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_spring}}}
connections: [[wave.u, it.u]]
outputs: [it.x, it.v]""", lambda t, y: [y[1], np.cos(t) - 4.0 * y[0] - 0.4 * y[1]])
GRAPHS["spring_loop"] = ("""\
  wave: {{fmu: {xtest_wave}}}
  ctrl: {{fmu: {xtest_gain}, parameters: {{kp: 3.0}}}}
  it: {{fmu: {xtest_spring}}}
connections: [[wave.u, ctrl.r], [it.x, ctrl.y], [ctrl.u, it.u]]
outputs: [it.x, it.v]""", lambda t, y: [y[1], 3 * (np.cos(t) - y[0]) - 4.0 * y[0] - 0.4 * y[1]])
GRAPHS["bare_loop"] = (GRAPHS["loop"][0].replace("{xtest_gain}", "{xtest_gain_bare}"),
                       GRAPHS["loop"][1])
GRAPHS["lazy"] = (GRAPHS["through"][0].replace("k: 2.0}", "k: 2.0, lazy: 1}"),
                  GRAPHS["through"][1])
GRAPHS["vdp"] = ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_spring}, parameters: {{mu: 1.0, c: 0.0, k: 1.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.x, it.v]""", lambda t, y: [y[1], (1 - y[0] ** 2) * y[1] - y[0] + np.cos(t)])
GRAPHS["ball"] = ("""\
  ball: {{fmu: {xtest_ball}}}
  it: {{fmu: {xtest_lag}, parameters: {{k: 2.0}}}}
connections: [[ball.h, it.u]]
outputs: [it.x]""", None)
GRAPHS["stiff"] = (GRAPHS["lag"][0].replace("k: 2.0", "k: 100.0"),
                   lambda t, y: [-100.0 * y[0] + np.cos(t)])
GRAPHS["overdamped"] = ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_spring}, parameters: {{c: 101.0, k: 100.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.x, it.v]""", lambda t, y: [y[1], np.cos(t) - 100.0 * y[0] - 101.0 * y[1]])
GRAPHS["triple"] = ("""\
  wave: {{fmu: {xtest_wave}}}
  it: {{fmu: {xtest_triple}, parameters: {{a: 1.0, b: 2.0, c: 300.0}}}}
connections: [[wave.u, it.u]]
outputs: [it.x1, it.x2, it.x3]""", lambda t, y: [np.cos(t) - y[0], y[0] - 2.0 * y[1],
                                                 y[1] - 300.0 * y[2]])

GRAPHS["saturated"] = ("""\
  wave: {{fmu: {xtest_wave}, parameters: {{omega: 2.0}}}}
  it: {{fmu: {xtest_lag}, parameters: {{k: 2.0, lim: 0.5}}}}
connections: [[wave.u, it.u]]
outputs: [it.x]""", lambda t, y: [-2 * y[0] + np.clip(np.cos(2 * t), -0.5, 0.5)])
GRAPHS["saturated_loop"] = (GRAPHS["loop"][0].replace("k: 2.0}", "k: 2.0, lim: 0.5}"),
                            lambda t, y: [-2 * y[0] + np.clip(3 * (np.cos(t) - y[0]), -0.5,
                                                              0.5)])


def scenario(folder: Path, fmus: dict, name: str) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(f"""\
name: {name}
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.1}}
components:
{GRAPHS[name][0].format(**fmus)}
""")
    return path


def true_errors(name: str, graph, results, outputs: list[str]) -> dict:
    """Per recorded output |run - truth|: the ODEs' solution, or (the drag, the ball) the
    same graph at 1/REFINE of the step."""
    rates = GRAPHS[name][1]
    if rates is None:       # (the adaptive master's reference: the quadratic one's)
        exp = graph.scenario.experiment
        fine, fexp = with_experiment(graph, step_size=exp.step_size / REFINE, estimate="none",
                                     master="quadratic" if exp.tolerance else exp.master,
                                     tolerance=None)
        reference = master.simulate(fine, fexp)
        return {o: np.abs(results[o] - reference[o][::REFINE]) for o in outputs}
    truth = solve_ivp(rates, (0.0, 6.0), [0.0] * len(outputs), t_eval=results.time,
                      rtol=1e-12, atol=1e-14, method="DOP853").y
    if name in ("through", "lazy"):     # y = x + u: the lag's x and the input
        truth = np.array([truth[0], truth[0] + np.cos(results.time)])
    return {o: np.abs(results[o] - row) for o, row in zip(outputs, truth)}


def measure(name: str, path: Path, master_name: str, h: float, estimate: str) -> list[dict]:
    graph = prepare(path, estimate=estimate)
    graph, exp = with_experiment(graph, step_size=h, master=master_name)
    costs, spent = [], []
    for _ in range(REPS):
        results = master.simulate(graph, exp, with_estimate=True)
        found = master.estimate_error(graph, results)
        costs.append(found.get("error_estimate_cost", float("nan")))
        pair = results.extra.get("pair", {}).get("found")
        spent.append(pair["seconds"] if isinstance(pair, dict) and "seconds" in pair
                     else float("nan"))
    outputs = [str(p.ref) for p in graph.recorded]
    pair = results.extra["pair"]["found"]
    calls = pair.get("probe_calls", 0) if isinstance(pair, dict) else 0
    method = "pair+probes" if "measured" in found["error_estimate_method"] and \
        found["error_estimate_method"].startswith("the embedded") else \
        found["error_estimate_method"].split(":")[0]
    rows = []
    for output, error in true_errors(name, graph, results, outputs).items():
        est = found["error_estimate"][output]
        rows.append({"output": output, "max": _ratio(est["max"], error.max()),
                     "end": _ratio(est["end"], error[-1]), "cost": statistics.median(costs),
                     "ms": 1e3 * statistics.median(spent),
                     "calls": calls / (len(graph.instances) * results.steps),
                     "method": method})
    return rows


def _ratio(estimate, true: float) -> float:
    return float(estimate) / true if isinstance(estimate, float) else float("nan")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        fmus = state_fmus(Path(tmp))
        for stem in ("xtest_lag", "xtest_gain"):
            fmus[f"{stem}_bare"] = rewrite_description(
                fmus[stem], lambda xml: re.sub(r' dependencies="[^"]*"', "", xml),
                Path(tmp) / f"{stem}_bare.fmu")
        if sys.argv[1:] == ["--adaptive"]:
            adaptive(Path(tmp), fmus)
            return
        print(f"{'graph':<9} {'output':<8} {'master':<12} {'h':>6} {'estimate':<12} {'max':>6} "
              f"{'end':>6} {'cost':>6} {'ms':>6} {'probe calls':>11}")
        rows = []
        for name in GRAPHS:
            path = scenario(Path(tmp), fmus, name)
            for master_name in MASTERS:
                for h in STEPS:
                    for estimate in ("auto", "richardson"):
                        for m in measure(name, path, master_name, h, estimate):
                            m.update(graph=name, master=master_name, steps=round(6.0 / h))
                            rows.append((estimate, m))
                            print(f"{name:<9} {m['output']:<8} {master_name:<12} {h:>6g} "
                                  f"{m['method'][:12]:<12} {m['max']:>6.2f} {m['end']:>6.2f} "
                                  f"{m['cost']:>6.2f} {m['ms']:>6.2f} {m['calls']:>11.3f}", flush=True)
        summary(rows)


def adaptive(folder: Path, fmus: dict) -> None:
    """Per graph and tolerance, the adaptive master's steps and each recorded output's true
    error (in tolerances) and estimate over it; and the steps the fixed quadratic master
    needs to meet the tolerance, from its error at 0.05 s and 0.025 s (its observed order)."""
    for name in GRAPHS:
        path = scenario(folder, fmus, name)
        worst = []
        for h in (0.05, 0.025):
            fixed, exp = with_experiment(prepare(path), step_size=h, master="quadratic",
                                         estimate="none")
            outputs = [str(p.ref) for p in fixed.recorded]
            worst.append(max(e.max() for e in true_errors(
                name, fixed, master.simulate(fixed, exp), outputs).values()))
        order = np.log2(worst[0] / worst[1])
        # (the lazy graph is first order: 1e-6 would take about 1.5e6 steps)
        for tol in (1e-2, 1e-3, 1e-4) + (() if name == "lazy" else (1e-6,)):
            graph = prepare(path, tolerance=tol)
            results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
            found = master.estimate_error(graph, results)["error_estimate"]
            said = "; ".join(
                f"{o} {e.max() / tol:.2f} tol, estimate {_ratio(found[o]['max'], e.max()):.2f}"
                for o, e in true_errors(name, graph, results, outputs).items())
            print(f"{name:<9} {tol:<6g} {results.steps_taken:>5} steps (fixed, order "
                  f"{order:.2f}: {120 * (worst[0] / tol) ** (1 / order):>6.0f}): {said}",
                  flush=True)


def summary(rows: list) -> None:
    for estimate in ("auto", "richardson"):
        mine = [m for e, m in rows if e == estimate]
        ratios = [m[w] for m in mine for w in ("max", "end")]
        ratios = [r for r in ratios if r == r]          # nan: "unresolved", not a number
        out = sum(not (1 / 3 <= r <= 3) for r in ratios)
        costs = [m["cost"] for m in mine]
        over = [m["ms"] for m in mine if m["cost"] > 0.2 and m["ms"] == m["ms"]]
        print(f"{estimate:<10}: {2 * len(mine)} values, {2 * len(mine) - len(ratios)} "
              f"unresolved, {out} outside 3x (ratios "
              f"{min(ratios):.2f} to {max(ratios):.2f}); cost max {max(costs):.2f}, median "
              f"{statistics.median(costs):.2f}, {sum(c > 0.2 for c in costs)} of {len(costs)} "
              f"runs over 0.2x" + (f" (the pair's own time in those: at most {max(over):.2f} "
                                   "ms)" if over else "")
              + f"; methods: {sorted({m['method'] for m in mine})}")
    fixed_cost([m for e, m in rows if e == "auto" and m["method"] == "pair+probes"])


def fixed_cost(mine: list) -> None:
    """The pair's time (probes included) as a fixed part and a part per step over each
    graph's and master's steps where the pair estimates at three or more of them (30 to 600
    steps: cost_fit.py; the run's stepping: ms / cost), the run length from which it costs
    at most 0.2x of the stepping, and the graphs on which it never does."""
    runs: dict[tuple, dict] = {}
    for m in mine:      # one row per output: one per run is enough
        runs.setdefault((m["graph"], m["master"]), {})[m["steps"]] = (m["ms"], m["ms"] / m["cost"])
    found, never = [], set()
    for (graph, _), by_steps in runs.items():
        if len(by_steps) >= 3:      # (ms -> s)
            n = sorted(by_steps)
            found.append(fit(n, [by_steps[k][0] / 1e3 for k in n],
                             [by_steps[k][1] / 1e3 for k in n]))
            if math.isinf(found[-1][3]):
                never.add(graph)
    if found:
        print(fit_summary(found, "the pair with probes, its time = fixed + per step x n, per "
                             "graph and master") + f" ({', '.join(sorted(never))})")


if __name__ == "__main__":
    main()
