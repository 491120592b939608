"""A velocity table against the same profile written as expressions.

scenarios/profiles/joystick.csv is a recorded-style log (20 Hz, 4 decimals, extra columns a
recorder writes: buttons, battery) of the twist that scenarios/profiles/joystick_expressions.yaml
writes as formulas. Both scenarios run under the default master; this prints both end points
and their distance (linear interpolation between 20 Hz samples: error ~ dt^2/8 |v''|, plus the
4-decimal rounding).

    PYTHONPATH=src python bench/table_vs_expressions.py           # measure
    PYTHONPATH=src python bench/table_vs_expressions.py --write   # regenerate the CSV
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROFILES = ROOT / "scenarios" / "profiles"
RATE_HZ, STOP = 20, 12.0
FORMULAS = {"vx": "0.25*sin(0.6*t)", "vy": "0.35*(1 - cos(0.4*t))", "w": "0.3*sin(0.25*t)"}


def twist(t: float) -> tuple[float, float, float]:
    return (0.25 * math.sin(0.6 * t), 0.35 * (1 - math.cos(0.4 * t)), 0.3 * math.sin(0.25 * t))


def csv_text() -> str:
    lines = ["# recorded joystick commands, 20 Hz (body frame: vx right, vy forward, w ccw)",
             "time,vx,vy,w,buttons,battery_v"]
    for k in range(int(STOP * RATE_HZ) + 1):
        t = k / RATE_HZ
        vx, vy, w = twist(t)
        lines.append(f"{t:.2f},{vx:.4f},{vy:.4f},{w:.4f},{0 if t < 6 else 1},"
                     f"{12.6 - 0.01 * t:.2f}")
    return "\n".join(lines) + "\n"


def end_point(path: Path):
    from mecanum_fmu import master
    from mecanum_fmu.runner import prepare
    graph = prepare(path)
    res = master.simulate(graph, graph.scenario.experiment)
    return tuple(res.final(f"pose.{k}") for k in ("x", "y", "theta"))


def main() -> None:
    if "--write" in sys.argv:
        (PROFILES / "joystick.csv").write_text(csv_text())
    assert (PROFILES / "joystick.csv").read_text() == csv_text(), "run with --write"
    table = end_point(PROFILES / "joystick.yaml")
    formulas = end_point(PROFILES / "joystick_expressions.yaml")
    print(f"table (20 Hz, linear):  x = {table[0]:.6f}  y = {table[1]:.6f}  theta = {table[2]:.6f}")
    print(f"expressions:            x = {formulas[0]:.6f}  y = {formulas[1]:.6f}  "
          f"theta = {formulas[2]:.6f}")
    print(f"distance {math.dist(table[:2], formulas[:2]):.3e} m, "
          f"heading difference {table[2] - formulas[2]:.3e} rad")


if __name__ == "__main__":
    main()
