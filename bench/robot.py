"""What a doStep of the drive train costs against the algebraic chain (docs/robot.md).

Runs the seed circle twice at h = 1e-3 for 2 s: scenarios/circle.yaml (VelocitySource,
Center2Wheel, Wheel2Center, PoseIntegrator: algebraic but for the pose) and
scenarios/robot/circle.yaml (the same with four DCMotor and one MecanumDynamics in place of
Wheel2Center), each under the quadratic master, and prints the stepping loop per step, per
doStep call, and their ratio; then the block maths alone (one MecanumDynamics step, one DCMotor
step, one Wheel2Center evaluation) in microseconds. Medians of 3; wall times on whatever else
the machine runs.

Run: .venv/bin/python bench/robot.py
"""
from __future__ import annotations

import statistics
import timeit
from pathlib import Path

from mecanum_fmu import master
from mecanum_fmu.models.blocks.kinematics import DEFAULT_GEOMETRY, wheel_to_center
from mecanum_fmu.models.blocks.motor import DEFAULT_MOTOR, Motor
from mecanum_fmu.models.blocks.traction import DEFAULT_BODY, Chassis
from mecanum_fmu.runner import prepare

ROOT = Path(__file__).resolve().parents[1]
STEP, STOP, REPEATS = 1e-3, 2.0, 3


def loop_per_step(path: Path) -> tuple[float, int]:
    """(median stepping-loop seconds per communication step, doStep calls per step)."""
    graph = prepare(path, step_size=STEP, stop_time=STOP)
    walls = []
    for _ in range(REPEATS):
        results = master.simulate(graph, graph.scenario.experiment, keep_rows=2)
        walls.append(results.wall_time / results.steps)
    return statistics.median(walls), len(graph.instances)


def block_micros() -> dict[str, float]:
    g = DEFAULT_GEOMETRY
    chassis = Chassis(g["alpha"], g["L"], g["W"], g["R"], **DEFAULT_BODY)
    motor = Motor(*DEFAULT_MOTOR.values())
    wheels = [16.7, 16.7, 16.7, 16.7]
    calls = {"MecanumDynamics step": lambda: chassis.step([0.0, 1.0, 0.0, 0.0, 0.0], wheels, STEP),
             "DCMotor step": lambda: motor.step([16.7, 8.0, 0.0, 0, 0, 0, 0, 0], 17.0, 0.05, STEP),
             "Wheel2Center evaluation": lambda: wheel_to_center(*wheels, g["alpha"], g["L"],
                                                                g["W"], g["R"])}
    return {name: 1e6 * min(timeit.repeat(f, number=2000, repeat=3)) / 2000
            for name, f in calls.items()}


def main() -> None:
    chain, n_chain = loop_per_step(ROOT / "scenarios" / "circle.yaml")
    robot, n_robot = loop_per_step(ROOT / "scenarios" / "robot" / "circle.yaml")
    print(f"algebraic chain ({n_chain} FMUs): {1e6 * chain:.0f} us per step, "
          f"{1e6 * chain / n_chain:.0f} us per doStep")
    print(f"drive train ({n_robot} FMUs):    {1e6 * robot:.0f} us per step, "
          f"{1e6 * robot / n_robot:.0f} us per doStep")
    print(f"ratio per step: {robot / chain:.2f}, per doStep: "
          f"{(robot / n_robot) / (chain / n_chain):.2f}")
    for name, micros in block_micros().items():
        print(f"{name}: {micros:.1f} us (the maths alone, no FMI)")


if __name__ == "__main__":
    main()
