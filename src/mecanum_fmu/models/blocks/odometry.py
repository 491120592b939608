"""Dead reckoning from measured wheel speeds (docs/robot.md).

Standard library only (inlined into the Odometry FMU). The twist comes from the seed's forward
kinematics (blocks/kinematics.py): ros2_controllers' mecanum_drive_controller uses the same
formulas at 45 deg rollers, with its k = half wheelbase + half track = L + W = L + W cot(45 deg).
"""
import math

UPDATES = ("euler", "exact")
HEADINGS = ("wheels", "gyro")


def euler_step(x: float, y: float, theta: float,
               vx: float, vy: float, w: float, dt: float) -> tuple[float, float, float]:
    """ros2_controllers' update: the heading first, then the position moved with the NEW
    heading, over dt with a body twist (vx right, vy forward, w counter-clockwise)."""
    theta = theta + w * dt
    c, s = math.cos(theta), math.sin(theta)
    return x + (vx * c - vy * s) * dt, y + (vx * s + vy * c) * dt, theta


def odometry_problem(period: float, update: str, heading: str):
    """(parameter, message) for a period, update or heading outside its range, else None."""
    if isinstance(period, bool) or not isinstance(period, (int, float)) \
            or not math.isfinite(period) or period <= 0.0:
        return "period", (f"parameter period = {period!r} s must be a finite number > 0 "
                          "(the odometry's update period; try 0.01)")
    if update not in UPDATES:
        return "update", (f"parameter update = {update!r} must be one of "
                          f"{', '.join(UPDATES)} (euler: ros2_controllers' update)")
    if heading not in HEADINGS:
        return "heading", (f"parameter heading = {heading!r} must be one of "
                           f"{', '.join(HEADINGS)} (gyro: the heading from the w_gyro input)")
    return None


def check_odometry(period: float, update: str, heading: str) -> None:
    problem = odometry_problem(period, update, heading)
    if problem is not None:
        raise ValueError(problem[1])
