"""Up-front value checks for the other chassis' FMUs (docs/chassis.md), so that a bad wheelbase,
reference point or expression is an input error (exit 2) naming its place, like the mecanum
geometry and VelocitySource's expressions in graph.py."""
from __future__ import annotations

from typing import Callable

from .blocks.bicycle import check_bicycle
from .blocks.expression import ExpressionError, compile_expression
from .blocks.omni import check_omni_geometry
from .scenario import is_number

# model -> (parameters, check function taking them as keywords)
NUMBER_CHECKS = {"OmniCenter2Wheel": (("L", "R"), check_omni_geometry),
                 "OmniWheel2Center": (("L", "R"), check_omni_geometry),
                 "Bicycle": (("l", "reference"), check_bicycle)}
EXPRESSIONS = {"SteeringSource": ("v_expr", "phi_expr")}


def check_chassis_values(comp, model_name: str, value: Callable[[str], object], own,
                         bad: Callable[[str], None], scenario_start: float) -> None:
    """Report (through `bad(place, message)`) the first out-of-range parameter of one of our
    chassis FMUs, and every expression that does not compile or fails at the start time."""
    def place(name: str) -> str:
        return (f"{comp.place}.parameters.{name}" if name in comp.parameters
                else f"parameters.{name}")
    if model_name in NUMBER_CHECKS:
        names, check = NUMBER_CHECKS[model_name]
        values = {k: value(k) for k in names if k in own}
        if len(values) == len(names) and all(is_number(v) for v in values.values()):
            try:
                check(**values)
            except ValueError as err:
                bad(place(str(err).split()[1]), str(err))
    for key in EXPRESSIONS.get(model_name, ()):
        text = value(key) if key in own else None
        if isinstance(text, str):
            try:
                compile_expression(text)(scenario_start)
            except ExpressionError as err:
                bad(place(key), str(err))
