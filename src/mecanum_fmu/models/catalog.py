"""What the project knows about its bundled models, in one place.

Each bundled model has a pythonfmu slave in slaves/ (its variables, units, defaults and
dependencies live there and reach the model description), a role in the original diagram,
and value rules that are checked before a run so that a bad value is an input error (exit 2),
not an FMU failure. Facts the model description already states (defaults, units) are read from
it, not repeated here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping

from .blocks.expression import ExpressionError, compile_expression
from .blocks.bicycle import bicycle_problem
from .blocks.kinematics import GEOMETRY, geometry_problem, radius_deviation_problem
from .blocks.motor import DEFAULT_MOTOR, motor_problem
from .blocks.omni import omni_geometry_problem
from .blocks.odometry import odometry_problem
from .blocks.sensors import encoder_problem, gyro_problem
from .blocks.traction import BODY, body_problem
from ..values import is_number

AUTHOR = "mecanum_fmu"     # the author attribute of every bundled model description


@dataclass(frozen=True)
class Model:
    name: str            # modelName and FMU file name
    module: str          # slave module in mecanum_fmu.models.slaves
    role: str            # its part in the original diagram (see Roles)
    # (values, start time) -> [(parameter, message)]: the model's own rules on its values
    check: Callable[[Mapping[str, object], float], list[tuple[str, str]]]
    # a parameter that the scenario layer sets to the experiment's step_size unless the
    # scenario sets it: a property of the run the model's numerics are tied to, fixed for all
    # its steps (an adaptive master's trial and half steps step the same model)
    step_parameter: str | None = None


def _numbers_rule(names: tuple[str, ...], problem: Callable):
    """A rule over numeric parameters: problem(*values) -> (parameter, message) or None."""
    def check(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
        numbers = [values.get(k) for k in names]
        if any(v is None or isinstance(v, (bool, str)) for v in numbers):
            return []            # a missing or mistyped value is reported by the type check
        found = problem(*numbers)
        return [found] if found else []
    return check


def _mecanum_problem(alpha, L, W, R):
    found = geometry_problem(alpha, L, W, R)
    if found is not None:
        return found
    c = 1.0 / math.tan(alpha)
    k = L + W * c
    return _coefficient_problem({"alpha": alpha, "L": L, "W": W, "R": R}, (
        ("alpha", c, "cot(alpha)"), ("L" if L >= W * c else "W", k, "L + W cot(alpha)"),
        ("R", 1.0 / R, "1/R"), ("R", k / R, "(L + W cot(alpha))/R"),
        ("R", R * math.tan(alpha) / 4.0, "R tan(alpha)/4"), ("R", R / (4.0 * k), "R/(4 k)")))


def _omni_problem(L, R):
    found = omni_geometry_problem(L, R)
    if found is not None:
        return found
    return _coefficient_problem({"L": L, "R": R}, (
        ("R", 1.0 / R, "1/R"), ("L", L / R, "L/R"), ("R", R / (4.0 * L), "R/(4 L)")))


def _coefficient_problem(values: dict, coefficients) -> tuple[str, str] | None:
    """Geometry in range whose kinematic coefficients overflow (or underflow to 0), e.g.
    R = 5e-324 (1/R = inf) or L = W = 1e308 (L + W = inf): every step would give inf or nan,
    so it is bad input, refused before the run (docs/spec.md, Kinematics)."""
    for name, coefficient, what in coefficients:
        if not (math.isfinite(coefficient) and coefficient > 0.0):
            return name, (f"parameter {name} = {values[name]!r} makes {what} = {coefficient!r}, "
                          "not a finite number > 0: the kinematics overflow on the first step; "
                          "give lengths in metres and the roller angle in radians")
    return None


_check_geometry = _numbers_rule(GEOMETRY, _mecanum_problem)


def _check_expressions(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    problems = []
    for key, text in values.items():
        if key.endswith("_expr") and isinstance(text, str):
            try:
                # evaluate once at the start: a constant part like 1/0 only fails then
                compile_expression(text)(start_time)
            except ExpressionError as err:
                problems.append((key, str(err)))
    return problems


def _check_forward(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    """Wheel2Center: the geometry, and every effective wheel radius R + dRi > 0."""
    problems = _check_geometry(values, start_time)
    if not problems and "dR1" in values:
        problems += _numbers_rule(("R", "dR1", "dR2", "dR3", "dR4"),
                                  radius_deviation_problem)(values, start_time)
    return problems


def _check_inverse(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    """Center2Wheel: the geometry, and w_max >= 0 (0: no wheel speed limit)."""
    problems = _check_geometry(values, start_time)
    w_max = values.get("w_max")
    if is_number(w_max) and not (math.isfinite(w_max) and w_max >= 0):
        problems.append(("w_max", f"parameter w_max = {w_max!r} rad/s must be >= 0 "
                                  "(0: no wheel speed limit)"))
    return problems


def _check_follower(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    """PathFollower: positive gains, and reference expressions that evaluate."""
    problems = _check_expressions(values, start_time)
    for name in ("k_pos", "k_theta"):
        gain = values.get(name)
        if is_number(gain) and not (math.isfinite(gain) and gain > 0):
            problems.append((name, f"gain {name} = {gain!r} 1/s must be > 0 (the rate at "
                                   "which the error decays; try 2)"))
    return problems


def _check_odometry(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    """Odometry: the geometry it assumes, a period > 0, a known update and heading."""
    problems = _check_geometry(values, start_time)
    found = odometry_problem(values.get("period"), values.get("update"), values.get("heading"))
    return problems + ([found] if found else [])


def _check_dynamics(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    """MecanumDynamics: the geometry, and a body with positive mass, inertia and friction."""
    return _check_geometry(values, start_time) + _numbers_rule(BODY, body_problem)(
        values, start_time)


def _no_rules(values: Mapping[str, object], start_time: float) -> list[tuple[str, str]]:
    return []


MODELS: dict[str, Model] = {m.name: m for m in (
    Model("VelocitySource", "velocity_source", "source", _check_expressions),
    Model("Center2Wheel", "center2wheel", "inverse", _check_inverse),
    Model("Wheel2Center", "wheel2center", "forward", _check_forward),
    Model("PoseIntegrator", "pose_integrator", "pose", _no_rules),
    Model("PathFollower", "path_follower", "follower", _check_follower),
    # the other two chassis of the original documents (docs/chassis.md)
    Model("OmniCenter2Wheel", "omni_center2wheel", "omni-inverse",
          _numbers_rule(("L", "R"), _omni_problem)),
    Model("OmniWheel2Center", "omni_wheel2center", "omni-forward",
          _numbers_rule(("L", "R"), _omni_problem)),
    Model("FieldToBody", "field_to_body", "frame", _no_rules),
    Model("Bicycle", "bicycle", "forward", _numbers_rule(("l", "reference"), bicycle_problem)),
    Model("SteeringSource", "steering_source", "steering", _check_expressions),
    # what the robot knows: sensors and dead reckoning (docs/robot.md)
    Model("Encoder", "encoder", "encoder", _numbers_rule(("cpr", "period", "sigma"), encoder_problem)),
    Model("Gyro", "gyro", "gyro", _numbers_rule(("period", "sigma", "bias"), gyro_problem)),
    Model("Odometry", "odometry", "odometry", _check_odometry),
    # the drive train and the floor (docs/robot.md)
    Model("DCMotor", "dc_motor", "motor", _numbers_rule(tuple(DEFAULT_MOTOR), motor_problem)),
    # the forward map with physics: wheel speeds in, the twist the floor allows out
    # (its friction's regularisation eps = max(eps_min, eps_rate h_ref): docs/robot.md)
    Model("MecanumDynamics", "mecanum_dynamics", "forward", _check_dynamics, "h_ref"),
)}


# Blocks that sample at their own period (docs/robot.md, Sample times): the step must
# divide it, and a run at another step samples differently (no Richardson estimate).
SAMPLED_MODELS = ("Encoder", "Gyro", "Odometry")


def bundled_model(md) -> Model | None:
    """The bundled model a model description belongs to, or None for any other FMU."""
    model = MODELS.get(md.modelName)
    return model if model is not None and md.author == AUTHOR else None


@dataclass(frozen=True)
class Roles:
    """Which instance plays which part of the original diagram (None: not in this graph)."""
    source: str | None
    inverse: str | None
    forward: str | None
    pose: str | None
    follower: str | None = None     # a PathFollower: closed loop, the truth is its reference
    frame: str | None = None        # a FieldToBody: the source's twist is in the WORLD frame
    omni_inverse: str | None = None   # the omni X-drive's kinematics pair (docs/chassis.md)
    omni_forward: str | None = None
    steering: str | None = None     # a SteeringSource: the car-like chassis' (v, phi) input
    odometry: str | None = None     # an Odometry: the robot's belief beside the pose (docs/robot.md)
    # the scenario's `recorded:` paths, (pose instance, checked path table) pairs (docs/bags.md)
    recorded: tuple[tuple[str, str], ...] = ()


def find_roles(graph) -> Roles:
    """The single instance of each role's bundled model (None when there is none or several)."""
    found: dict[str, list[str]] = {}
    for inst in graph.instances:
        model = bundled_model(inst.model)
        if model is not None:
            found.setdefault(model.role, []).append(inst.name)
    one = {role: names[0] for role, names in found.items() if len(names) == 1}
    return Roles(one.get("source"), one.get("inverse"), one.get("forward"), one.get("pose"),
                 one.get("follower"), one.get("frame"), one.get("omni-inverse"),
                 one.get("omni-forward"), one.get("steering"), one.get("odometry"),
                 tuple(graph.scenario.recorded.items()))
