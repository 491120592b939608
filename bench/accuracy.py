"""Accuracy per cost on the seed circle: master x step size -> end-point error, steps, wall time.

Prints the table and writes docs/img/accuracy.png (error vs wall time, log-log).
Run: make bench   (or: .venv/bin/python bench/accuracy.py)
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from mecanum_fmu import master
from mecanum_fmu.process import exit_now
from mecanum_fmu.runner import prepare

ROOT = Path(__file__).resolve().parents[1]
EXACT = (1 - np.cos(10.0), np.sin(10.0))      # docs/spec.md, The seed scenario
MASTERS = ("quadratic", "trapezoidal", "gauss-seidel", "jacobi")
STEPS = (0.2, 0.1, 0.05, 0.01, 0.001)


def measure(graph, master_name: str, h: float, repeat: int = 3) -> dict:
    exp = dataclasses.replace(graph.scenario.experiment, master=master_name, step_size=h)
    best = None
    for _ in range(repeat):
        res = master.simulate(graph, exp)
        best = res if best is None or res.wall_time < best.wall_time else best
    ex = best.final("pose.x") - EXACT[0]
    ey = best.final("pose.y") - EXACT[1]
    return {"master": master_name, "h": h, "steps": best.steps, "ex": ex, "ey": ey,
            "err": float(np.hypot(ex, ey)), "wall": best.wall_time}


def main() -> list[dict]:
    graph = prepare(ROOT / "scenarios" / "circle.yaml")
    rows = [measure(graph, m, h) for m in MASTERS for h in STEPS]
    print(f"{'master':<13} {'h [s]':>7} {'steps':>7} {'error x':>11} {'error y':>11} "
          f"{'|error|':>10} {'wall [s]':>9}")
    for r in rows:
        print(f"{r['master']:<13} {r['h']:>7g} {r['steps']:>7d} {r['ex']:>11.3e} {r['ey']:>11.3e} "
              f"{r['err']:>10.3e} {r['wall']:>9.4f}")
    # Cost of reaching 5e-4 with zero-order hold vs the trapezoidal master at h = 0.05.
    trap = next(r for r in rows if r["master"] == "trapezoidal" and r["h"] == 0.05)
    gs = {r["h"]: r for r in rows if r["master"] == "gauss-seidel"}
    # zero-order hold error is ~c*h: the step that reaches the trapezoidal error at h = 0.05
    c = gs[0.001]["err"] / 0.001
    h_needed = trap["err"] / c
    zoh = measure(graph, "gauss-seidel", h_needed, repeat=1)
    print(f"\nsame error as trapezoidal at h = 0.05 ({trap['err']:.2e} m): gauss-seidel needs "
          f"h = {h_needed:.2e} s ({zoh['steps']} steps, error {zoh['err']:.2e} m, "
          f"{zoh['wall']:.3f} s) -> trapezoidal is {zoh['wall'] / trap['wall']:.0f}x less wall time")
    _plot(rows, ROOT / "docs" / "img" / "accuracy.png")
    return rows


def _plot(rows, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.5, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for name, marker in zip(MASTERS, "Dos^"):
        mine = [r for r in rows if r["master"] == name]
        ax.loglog([r["wall"] for r in mine], [r["err"] for r in mine], marker=marker, label=name)
        for r in mine:
            ax.annotate(f"h={r['h']:g}", (r["wall"], r["err"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
    ax.axhline(5e-4, color="grey", lw=0.8, ls="--", label="5e-4 m")
    ax.set_xlabel("wall time of the stepping loop [s]")
    ax.set_ylabel("end-point error [m]")
    ax.set_title("Seed circle: accuracy per cost")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
    exit_now(0)      # no interpreter shutdown with pythonfmu FMUs loaded
