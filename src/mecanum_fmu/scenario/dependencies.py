"""A component's `dependencies:`: the inputs each output depends on, for the outputs whose model
description declares none.

FMI 2.0 and 3.0 take an output whose dependencies are not declared to depend on every input
(and maybe on a state). pythonfmu and pythonfmu3 declare none, so two of their FMUs in a
feedback loop make an algebraic loop that the step order cannot break. The scenario may say
what the FMU leaves unsaid, per instance:

    plant: {fmu: plant.fmu, dependencies: {x: []}}      # x depends on no input: a state
    ctrl: {fmu: ctrl.fmu, dependencies: {u: [r, y]}}    # u reads r and y directly

A dependency the model description declares is the FMU's own word and is not overridden.
"""
from __future__ import annotations

import copy
from typing import Callable

from fmpy.model_description import ModelDescription

from ..errors import did_you_mean
from ..values import show


def with_dependencies(model: ModelDescription, pairs: tuple, place: str,
                      bad: Callable[[str, str], None]) -> ModelDescription:
    """The model description with `pairs` ((output, (input, ...)), the component's
    `dependencies:`) as its outputs' dependencies: a copy (one per instance; the FMU's own is
    shared), or the model itself where there are none or one is refused (bad(place, ...):
    not an output, not an input, or an output that declares its own)."""
    if not pairs:
        return model
    outputs = {u.variable.name: u for u in model.outputs}
    inputs = {v.name: v for v in model.modelVariables if v.causality == "input"}
    given = {}
    for output, names in pairs:
        problem = _problem(outputs, inputs, output, names)
        if problem:
            bad(f"{place}.{output}", problem)
        else:
            given[output] = [inputs[n] for n in names]
    if len(given) < len(pairs):
        return model
    mine = copy.copy(model)
    mine.outputs = [_declared(u, given[u.variable.name]) if u.variable.name in given else u
                    for u in model.outputs]
    return mine


def _problem(outputs: dict, inputs: dict, output: str, names: tuple) -> str | None:
    if output not in outputs:
        return (f"{show(output)} is not an output of this FMU{did_you_mean(output, outputs)} "
                f"(its outputs: {', '.join(outputs) or 'none'})")
    declared = outputs[output].dependencies
    if declared is not None:
        return (f"{output}'s model description declares its dependencies "
                f"({', '.join(v.name for v in declared) or 'none'}): `dependencies:` only "
                "says what an FMU leaves undeclared; remove this entry")
    unknown = [n for n in names if n not in inputs]
    if unknown:
        return (f"{show(unknown[0])} is not an input of this FMU"
                f"{did_you_mean(unknown[0], inputs)} (its inputs: {', '.join(inputs) or 'none'})")
    return None


def _declared(unknown, variables: list):
    """A copy of the model structure's Unknown with these dependencies."""
    mine = copy.copy(unknown)
    mine.dependencies = list(variables)
    mine.dependenciesKind = ["dependent"] * len(variables)
    return mine


def loop_hint(cycle: list[str], instances: list) -> str:
    """What to add to an algebraic loop's message where outputs on it declare no
    dependencies (`cycle`: the loop's "instance.variable" nodes), else ""."""
    by_name = {inst.name: inst for inst in instances}
    undeclared = []
    for node in cycle:
        name, _, variable = node.partition(".")
        inst = by_name.get(name)
        if inst is not None and any(u.variable.name == variable and u.dependencies is None
                                    for u in inst.model.outputs):
            undeclared.append((name, variable))
    if not undeclared:
        return ""
    pairs = list(dict.fromkeys(undeclared))
    return (f"; {', '.join(f'{n}.{v}' for n, v in pairs)} declare"
            f"{'s' if len(pairs) == 1 else ''} no dependencies (pythonfmu and pythonfmu3 "
            "write none), so FMI takes each to depend on every input of its FMU. Where one is "
            "made from a state (it does not depend on its FMU's inputs at a communication "
            "point), say so in the scenario: "
            + " or ".join(f"`{n}: {{fmu: ..., dependencies: {{{v}: []}}}}`" for n, v in pairs))
