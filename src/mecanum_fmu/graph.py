"""Compile a Scenario against its FMUs' model descriptions into a checked, ordered Graph.

Everything that can be known before running is checked here, and every problem is reported
at once: unknown instances and variables, connection directions and types, inputs with two
drivers, parameters, and algebraic loops found from the FMUs' ModelStructure dependencies.
"""
from __future__ import annotations

import graphlib
from dataclasses import dataclass
from pathlib import Path

from fmpy.model_description import ModelDescription, ScalarVariable

from . import fmu_library
from .blocks.expression import ExpressionError, compile_expression
from .blocks.kinematics import check_geometry, check_radius_deviations
from .errors import Problem, ScenarioError
from .scenario import Scalar, Scenario, VarRef, did_you_mean, is_number, show

VALUE_TYPES = ("Real", "Integer", "Boolean")    # what moves between FMUs and is recorded


@dataclass(frozen=True)
class Port:
    """A resolved variable of one instance."""
    ref: VarRef
    type: str           # Real, Integer, Boolean, String (Enumeration is carried as Integer)
    vr: int
    causality: str


@dataclass(frozen=True)
class Instance:
    name: str
    fmu_path: Path
    model: ModelDescription
    start_values: dict[str, Scalar]
    declared_at: str

    @property
    def model_name(self) -> str:
        return self.model.modelName

    @property
    def can_get_set_state(self) -> bool:
        return bool(self.model.coSimulation.canGetAndSetFMUstate)


@dataclass(frozen=True)
class Link:
    source: Port
    target: Port
    place: str


@dataclass(frozen=True)
class Graph:
    scenario: Scenario
    instances: tuple[Instance, ...]   # step (dependency) order
    links: tuple[Link, ...]           # dependency order: walking it makes t0 consistent
    recorded: tuple[Port, ...]
    warnings: tuple[str, ...]

    def instance(self, name: str) -> Instance:
        return next(i for i in self.instances if i.name == name)

    def find_model(self, model_name: str) -> Instance | None:
        """The single instance of a model, or None when there is none or several."""
        found = [i for i in self.instances if i.model_name == model_name]
        return found[0] if len(found) == 1 else None


def port_type(var: ScalarVariable) -> str:
    return "Integer" if var.type == "Enumeration" else var.type


def compile_graph(scenario: Scenario, fmu_dir: Path | None = None) -> Graph:
    """Resolve FMUs, check the whole graph, order it. Raises ScenarioError with all problems."""
    fmu_dir = Path(fmu_dir) if fmu_dir is not None else fmu_library.default_fmu_dir()
    label = scenario.label
    problems: list[Problem] = []

    def bad(place: str, message: str) -> None:
        problems.append(Problem(label, place, message))

    models: dict[str, tuple[Path, ModelDescription]] = {}
    cache: dict[Path, ModelDescription] = {}
    for comp in scenario.components:
        try:
            path = fmu_library.resolve_fmu(comp.fmu, scenario.path.parent, fmu_dir)
            if path not in cache:
                cache[path] = fmu_library.read_description(path)
            models[comp.name] = (path, cache[path])
        except ValueError as err:
            bad(f"{comp.place}.fmu", str(err))

    variables = {name: {v.name: v for v in md.modelVariables} for name, (_, md) in models.items()}
    instance_names = [c.name for c in scenario.components]

    def lookup(ref: VarRef, place: str) -> ScalarVariable | None:
        if ref.instance not in instance_names:
            bad(place, f"unknown instance '{ref.instance}' in '{ref}'"
                       f"{did_you_mean(ref.instance, instance_names)}")
            return None
        if ref.instance not in variables:
            return None          # its FMU could not be read: already reported
        var = variables[ref.instance].get(ref.variable)
        if var is None:
            bad(place, f"{models[ref.instance][1].modelName} instance '{ref.instance}' has no "
                       f"variable '{ref.variable}'"
                       f"{did_you_mean(ref.variable, variables[ref.instance])}")
        return var

    def port(ref: VarRef, var: ScalarVariable) -> Port:
        return Port(ref, port_type(var), var.valueReference, var.causality)

    # Parameters and start values (shared ones go to every component that has them).
    start_values: dict[str, dict[str, Scalar]] = {}
    for name in scenario.parameters:
        takers = [c for c in scenario.components if c.name in variables
                  and _settable(variables[c.name].get(name))]
        if not takers and len(variables) == len(scenario.components):
            bad(f"parameters.{name}", f"no component has a parameter '{name}'")
    for comp in scenario.components:
        if comp.name not in variables:
            continue
        own = variables[comp.name]
        merged = {k: v for k, v in scenario.parameters.items() if _settable(own.get(k))}
        merged.update(comp.parameters)
        for key in comp.parameters:
            place = f"{comp.place}.parameters.{key}"
            var = own.get(key)
            if var is None:
                bad(place, f"{models[comp.name][1].modelName} has no parameter '{key}'"
                           f"{did_you_mean(key, [v for v in own if _settable(own[v])])}")
            elif not _settable(var):
                bad(place, f"'{key}' is {var.causality} ({var.variability}), "
                           "not a parameter or input whose start value can be set")
        for key, value in merged.items():
            var = own.get(key)
            if var is not None and _settable(var):
                place = (f"{comp.place}.parameters.{key}" if key in comp.parameters
                         else f"parameters.{key}")
                message = _type_problem(var, value)
                if message:
                    bad(place, message)
        start_values[comp.name] = merged
        _check_bundled_values(comp, models[comp.name][1], own, merged, bad,
                              scenario.experiment.start_time)

    # Connections.
    links: list[Link] = []
    drivers: dict[VarRef, str] = {}
    for conn in scenario.connections:
        src = lookup(conn.source, conn.place)
        dst = lookup(conn.target, conn.place)
        if src is None or dst is None:
            continue
        ok = True
        if src.causality != "output":
            bad(conn.place, f"'{conn.source}' is {'an' if src.causality[0] in 'aeiou' else 'a'} "
                            f"{src.causality}, not an output: a connection goes "
                            "[from output, to input]")
            ok = False
        if dst.causality != "input":
            bad(conn.place, f"'{conn.target}' is {'an' if dst.causality[0] in 'aeiou' else 'a'} "
                            f"{dst.causality}, not an input: a connection goes "
                            "[from output, to input]")
            ok = False
        if port_type(src) != port_type(dst):
            bad(conn.place, f"type mismatch: '{conn.source}' is {src.type}, "
                            f"'{conn.target}' is {dst.type}")
            ok = False
        if port_type(src) not in VALUE_TYPES and port_type(src) == port_type(dst):
            bad(conn.place, f"'{conn.source}' is {src.type}: connections carry Real, Integer "
                            "and Boolean values (set a String once as a parameter instead)")
            ok = False
        if conn.target in drivers:
            bad(conn.place, f"input '{conn.target}' already has a driver "
                            f"({drivers[conn.target]}); an input takes one connection")
            ok = False
        drivers.setdefault(conn.target, conn.place)
        if ok:
            links.append(Link(port(conn.source, src), port(conn.target, dst), conn.place))

    # Recorded variables.
    recorded: list[Port] = []
    if scenario.outputs is None:
        for comp in scenario.components:
            for var in (models[comp.name][1].modelVariables if comp.name in models else ()):
                if var.causality == "output" and port_type(var) in VALUE_TYPES:
                    recorded.append(port(VarRef(comp.name, var.name), var))
    else:
        seen = set()
        for ref, place in scenario.outputs:
            var = lookup(ref, place)
            if var is not None and port_type(var) not in VALUE_TYPES:
                bad(place, f"'{ref}' is {var.type}: only Real, Integer and Boolean variables "
                           "are recorded")
            elif var is not None and ref not in seen:
                seen.add(ref)
                recorded.append(port(ref, var))

    if problems:
        raise ScenarioError(problems)

    instances = [Instance(c.name, models[c.name][0], models[c.name][1], start_values[c.name],
                          c.place) for c in scenario.components]
    order, link_order = _dependency_order(instances, links, label)
    warnings = []
    for inst in instances:
        for var in inst.model.modelVariables:
            ref = VarRef(inst.name, var.name)
            if var.causality == "input" and ref not in drivers:
                start = inst.start_values.get(var.name, var.start)
                warnings.append(f"{label}: {inst.declared_at}: input '{var.name}' is not "
                                f"connected; it keeps its start value {start}")
    return Graph(scenario, tuple(order), tuple(link_order), tuple(recorded), tuple(warnings))


def _settable(var: ScalarVariable | None) -> bool:
    if var is None or var.variability == "constant":
        return False
    return var.causality in ("parameter", "input") or var.initial == "exact"


def _type_problem(var: ScalarVariable, value: Scalar) -> str | None:
    kind = port_type(var)
    ok = {"Real": is_number(value),
          "Integer": (isinstance(value, int) and not isinstance(value, bool)
                      and -2**31 <= value < 2**31),      # fmi2Integer is 32-bit
          "Boolean": isinstance(value, bool),
          "String": isinstance(value, str)}.get(kind, False)
    if ok:
        return None
    wanted = {"Real": "a number", "Integer": "a whole number from -2**31 to 2**31-1", "Boolean": "true or false",
              "String": "text (quote it)"}.get(kind, kind)
    return f"'{var.name}' is {kind}: expected {wanted}, got {show(value)}"


def _check_bundled_values(comp, md: ModelDescription, own, values, bad,
                          scenario_start: float = 0.0) -> None:
    """Our own FMUs' value rules, checked up front so a bad value is an input error (exit 2)."""
    def value(name):
        return values.get(name, _start(own[name]))

    if md.modelName in ("Center2Wheel", "Wheel2Center") and md.author == "mecanum_fmu":
        geometry = {k: value(k) for k in ("alpha", "L", "W", "R") if k in own}
        if len(geometry) == 4 and all(is_number(v) for v in geometry.values()):
            try:
                check_geometry(**geometry)
            except ValueError as err:
                name = str(err).split()[1]
                where = (f"{comp.place}.parameters.{name}" if name in comp.parameters
                         else f"parameters.{name}")
                bad(where, str(err))
        deviations = tuple(value(k) for k in ("dR1", "dR2", "dR3", "dR4") if k in own)
        if len(deviations) == 4 and is_number(geometry.get("R")):
            try:
                check_radius_deviations(geometry["R"], deviations)
            except ValueError as err:
                name = str(err).split()[1]
                bad(f"{comp.place}.parameters.{name}" if name in comp.parameters
                    else f"parameters.{name}", str(err))
    if md.modelName == "VelocitySource" and md.author == "mecanum_fmu":
        for key in ("vx_expr", "vy_expr", "w_expr"):
            text = value(key) if key in own else None
            if isinstance(text, str):
                try:
                    # evaluate once at the start: a constant part like 1/0 only fails then
                    compile_expression(text)(scenario_start)
                except ExpressionError as err:
                    bad(f"{comp.place}.parameters.{key}", str(err))


def _start(var: ScalarVariable):
    if var.start is None:
        return None
    kind = port_type(var)
    if kind == "Real":
        return float(var.start)
    if kind == "Integer":
        return int(var.start)
    if kind == "Boolean":
        return var.start in (True, "true", "1", 1)
    return var.start


def _dependency_order(instances: list[Instance], links: list[Link], label: str):
    """Step order of the instances and walking order of the links, from a variable-level
    dependency graph: a connection output -> input, and inside an FMU input -> output for each
    ModelStructure dependency. A cycle in it is an algebraic loop; a cycle through an FMU
    whose outputs do not depend on its inputs (an integrator) is not one."""
    graph: dict[str, set[str]] = {}
    link_of: dict[str, Link] = {}
    for link in links:
        graph.setdefault(str(link.target.ref), set()).add(str(link.source.ref))
        link_of[str(link.target.ref)] = link
    for inst in instances:
        inputs = [v for v in inst.model.modelVariables if v.causality == "input"]
        for unknown in inst.model.outputs:
            deps = unknown.dependencies
            if deps is None:      # not declared: FMI says it may depend on every input
                deps = inputs
            out = f"{inst.name}.{unknown.variable.name}"
            for dep in deps:
                if dep.causality == "input":
                    graph.setdefault(out, set()).add(f"{inst.name}.{dep.name}")
    sorter = graphlib.TopologicalSorter(graph)
    try:
        order = list(sorter.static_order())
    except graphlib.CycleError as err:
        cycle = err.args[1]
        places = sorted({link_of[n].place for n in cycle if n in link_of})
        raise ScenarioError([Problem(label, ", ".join(places) or "connections",
            "algebraic loop: " + " -> ".join(cycle) + " (every block on it has direct "
            "feedthrough; break it with a block whose outputs do not depend on its inputs)")]) from None
    position = {node: i for i, node in enumerate(order)}
    link_order = sorted(links, key=lambda l: position[str(l.target.ref)])
    # An instance steps after the latest of its connected inputs in the dependency order.
    last_input: dict[str, int] = {}
    for node, link in link_of.items():
        name = link.target.ref.instance
        last_input[name] = max(last_input.get(name, -1), position[node])
    declared = {inst.name: i for i, inst in enumerate(instances)}
    step_order = sorted(instances, key=lambda i: (last_input.get(i.name, -1), declared[i.name]))
    return step_order, link_order


def settable_parameters(inst: Instance) -> list[str]:
    """The names whose start value a scenario (or a sweep) may set on this instance."""
    return [v.name for v in inst.model.modelVariables if _settable(v)]


def check_start_values(graph: Graph, name: str, values: dict[str, Scalar]) -> list[tuple[str, str]]:
    """Check new start values for instance `name` (over its current ones) by the same rules as
    a scenario's parameters (settable, type, our FMUs' value rules). Returns (parameter,
    message) pairs."""
    inst = graph.instance(name)
    own = {v.name: v for v in inst.model.modelVariables}
    problems: list[tuple[str, str]] = []
    for key, value in values.items():
        var = own.get(key)
        if not _settable(var):
            problems.append((key, f"'{key}' cannot be set on {inst.model_name} instance '{name}'"))
        elif (message := _type_problem(var, value)) is not None:
            problems.append((key, message))
    if not problems:
        stub = type("Declared", (), {"place": name, "parameters": values})
        _check_bundled_values(stub, inst.model, own, {**inst.start_values, **values},
                              lambda place, message: problems.append(
                                  (place.rsplit(".", 1)[-1], message)),
                              graph.scenario.experiment.start_time)
    return problems
