"""The error estimate on third-party FMUs with a state (nothing the masters know of): the
embedded pair with their response measured by probes (master/probe.py) against the true
error, and its cost against Richardson's, per master and step, in one process.

Two graphs of test FMUs built here with pythonfmu (tests/fmu_sources/with_state): a source u =
cos t into a lag x' = -2 x + u (the truth: its closed form), and u = cos 2t into a speed under
quadratic drag v' = u - 3 v |v| (nonlinear; the truth: the same graph at 1/64 of the step).
Per run: the estimate over the true error for the largest value and the end (within 3x:
[0.33, 3]), and the estimate's cost against the run's stepping time (error_estimate_cost:
the pair's NumPy work and the probes' time, medians of 5 runs), and the probes' doStep calls
against the run's. The same with `--estimate richardson` for comparison.

Run: .venv/bin/python bench/third_party.py
"""
from __future__ import annotations

import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from helpers import state_fmus, with_experiment  # noqa: E402
from mecanum_fmu import master  # noqa: E402
from mecanum_fmu.runner import prepare  # noqa: E402

MASTERS = ("quadratic", "trapezoidal", "gauss-seidel", "jacobi")
STEPS = (0.2, 0.1, 0.05, 0.025, 0.01)
REPS = 5
REFINE = 64


def scenario(folder: Path, fmus: dict, name: str) -> Path:
    source, (fmu, output, parameters) = {
        "lag": ("{}", ("xtest_lag", "x", "{k: 2.0}")),
        "drag": ("{omega: 2.0}", ("xtest_drag", "v", "{c: 3.0}"))}[name]
    path = folder / f"{name}.yaml"
    path.write_text(f"""\
name: {name}
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.1}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}, parameters: {source}}}
  it: {{fmu: {fmus[fmu]}, parameters: {parameters}}}
connections:
  - [wave.u, it.u]
outputs:
  - it.{output}
""")
    return path


def true_error(name: str, graph, results) -> np.ndarray:
    if name == "lag":       # x' = -2 x + cos t, x(0) = 0
        t = results.time
        truth = (2 * np.cos(t) + np.sin(t) - 2 * np.exp(-2 * t)) / 5
        return np.abs(results["it.x"] - truth)
    exp = graph.scenario.experiment
    fine, fexp = with_experiment(graph, step_size=exp.step_size / REFINE, estimate="none")
    return np.abs(results["it.v"] - master.simulate(fine, fexp)["it.v"][::REFINE])


def measure(name: str, path: Path, master_name: str, h: float, estimate: str) -> dict:
    graph = prepare(path, estimate=estimate)
    graph, exp = with_experiment(graph, step_size=h, master=master_name)
    costs = []
    for _ in range(REPS):
        results = master.simulate(graph, exp, with_estimate=True)
        found = master.estimate_error(graph, results)
        costs.append(found.get("error_estimate_cost", float("nan")))
    error = true_error(name, graph, results)
    output = next(iter(found["error_estimate"]))
    est = found["error_estimate"][output]
    calls = results.extra["pair"]["found"].get("probe_calls", 0) \
        if isinstance(results.extra["pair"]["found"], dict) else 0
    return {"max": _ratio(est["max"], error.max()), "end": _ratio(est["end"], error[-1]),
            "cost": statistics.median(costs), "calls": calls / (2 * results.steps),
            "method": "pair+probes" if "its response measured" in found[
                "error_estimate_method"] else found["error_estimate_method"].split(":")[0]}


def _ratio(estimate, true: float) -> float:
    return float(estimate) / true if isinstance(estimate, float) else float("nan")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        fmus = state_fmus(Path(tmp))
        print(f"{'graph':<5} {'master':<12} {'h':>6} {'estimate':<12} {'max':>6} {'end':>6} "
              f"{'cost':>6} {'probe calls':>11}")
        rows = []
        for name in ("lag", "drag"):
            path = scenario(Path(tmp), fmus, name)
            for master_name in MASTERS:
                for h in STEPS:
                    for estimate in ("auto", "richardson"):
                        m = measure(name, path, master_name, h, estimate)
                        rows.append((estimate, m))
                        print(f"{name:<5} {master_name:<12} {h:>6g} {m['method'][:12]:<12} "
                              f"{m['max']:>6.2f} {m['end']:>6.2f} {m['cost']:>6.2f} "
                              f"{m['calls']:>11.3f}", flush=True)
        summary(rows)


def summary(rows: list) -> None:
    for estimate in ("auto", "richardson"):
        mine = [m for e, m in rows if e == estimate]
        ratios = [m[w] for m in mine for w in ("max", "end")]
        out = sum(not (1 / 3 <= r <= 3) for r in ratios)
        costs = [m["cost"] for m in mine]
        print(f"{estimate:<10}: {len(ratios)} values, {out} outside 3x (ratios "
              f"{min(ratios):.2f} to {max(ratios):.2f}); cost max {max(costs):.2f}, median "
              f"{statistics.median(costs):.2f}, {sum(c > 0.2 for c in costs)} of {len(costs)} "
              f"runs over 0.2x; methods: {sorted({m['method'] for m in mine})}")


if __name__ == "__main__":
    main()
