"""Convergence of the closed loop pose -> PathFollower -> Center2Wheel -> Wheel2Center -> pose
(scenarios/closed_loop/track_circle.yaml) under each master: the largest position error over
the run against a tight scipy solve of the same closed-loop ODE, at h, h/2, h/4, h/8, and the
ratio e(h) / e(h/2) (4 for second order, 2 for first). docs/closed-loop.md quotes a run.

    PYTHONPATH=src python bench/closed_loop_order.py
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from mecanum_fmu import master
from mecanum_fmu.process import exit_now
from mecanum_fmu.runner import prepare

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "closed_loop" / "track_circle.yaml"
K = 2.0                          # the PathFollower's default k_pos = k_theta
STEPS = (0.1, 0.05, 0.025, 0.0125)


def reference(times: np.ndarray) -> np.ndarray:
    """The closed loop as one ODE (the follower law and the pose equations written out)."""
    def rhs(t, p):
        x, y, th = p
        vxw = math.sin(t) + K * (1 - math.cos(t) - x)
        vyw = math.cos(t) + K * (math.sin(t) - y)
        return (vxw, vyw, K * math.atan2(math.sin(-th), math.cos(-th)))   # world frame
    return solve_ivp(rhs, (times[0], times[-1]), (0.3, -0.2, 0.5), t_eval=times,
                     method="DOP853", rtol=1e-12, atol=1e-13).y


def errors(master_name: str) -> list[tuple[float, float, float, float]]:
    out = []
    for h in STEPS:
        graph = prepare(SCENARIO, step_size=h, master_name=master_name)
        res = master.simulate(graph, graph.scenario.experiment)
        ref = reference(res.time)
        dist = np.hypot(res["pose.x"] - ref[0], res["pose.y"] - ref[1])
        out.append((h, float(dist.max()), float(dist[-1]), res.wall_time / res.steps))
    return out


def main() -> None:
    per_step = {}
    for name in ("quadratic", "trapezoidal", "gauss-seidel", "jacobi"):
        rows = errors(name)
        print(f"{name}: h, max position error over [0, 10] s, error at t = 10 s, ratios")
        for i, (h, worst, end, _) in enumerate(rows):
            ratio = f"{rows[i - 1][1] / worst:.3f}  {rows[i - 1][2] / end:.3f}" if i else "-"
            print(f"  {h:<8g} {worst:.3e}  {end:.3e}  {ratio}")
        per_step[name] = min(row[3] for row in rows)
    print(f"stepping loop per step (best of the runs): quadratic {per_step['quadratic'] * 1e6:.0f} us"
          f" (predict, roll back, correct), trapezoidal {per_step['trapezoidal'] * 1e6:.0f} us: "
          f"{per_step['quadratic'] / per_step['trapezoidal']:.2f}x")


if __name__ == "__main__":
    main()
    exit_now(0)
