"""Compile a Scenario against its FMUs' model descriptions into a checked, ordered Graph.

Everything that can be known before running is checked here, and every problem is reported
at once: unknown instances and variables, connection directions and types, inputs with two
drivers, parameters, and algebraic loops found from the FMUs' ModelStructure dependencies.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Callable

from fmpy.model_description import ModelDescription, ScalarVariable

from . import plausibility
from ..models import library as fmu_library
from ..models.catalog import SAMPLED_MODELS, bundled_model
from ..models.pose_error import pose_batch, pose_error
from ..models.drive_error import BODY_READS, MOTOR_READS, body_linear, motor_linear
from ..models.responses import has_response, response
from ..errors import Problem, ScenarioError
from ..masters import DEFAULT, entry as master_entry
from ..values import is_finite
from .dependencies import with_dependencies
from .document import Scalar, Scenario, VarRef, did_you_mean, is_number, show
from .step_order import dependency_order
from .tables import Breaks, Known, Table, source_breaks, source_known, table_or_none

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
    table: Table | None = field(default=None, repr=False)   # its `table`, read (tables.py)

    @property
    def model_name(self) -> str:
        return self.model.modelName

    def value(self, name: str) -> Scalar:
        """The start value this instance runs with: the scenario's, else the model's."""
        if name in self.start_values:
            return self.start_values[name]
        return start_value(self.variable(name))

    def variable(self, name: str) -> ScalarVariable:
        """The model's variable of that name (StopIteration where it has none)."""
        return next(v for v in self.model.modelVariables if v.name == name)

    @property
    def can_get_set_state(self) -> bool:
        return bool(self.model.coSimulation.canGetAndSetFMUstate)

    @property
    def can_vary_step(self) -> bool:
        """canHandleVariableCommunicationStepSize (false: pythonfmu3's default)."""
        return bool(self.model.coSimulation.canHandleVariableCommunicationStepSize)


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
    # per instance name, an error model the masters hand its held inputs to (the
    # PoseIntegrator's, models/pose_error.py): what the master cannot see on its own
    error_models: tuple[tuple[str, "ErrorModel"], ...] = ()
    # per instance name, the response of an FMU without a state (the Jacobian of its outputs
    # in its inputs, models/responses.py: a factory of (its linked inputs, the instance)),
    # through which the fixed-step masters' pair carries an error around a loop
    responses: tuple[tuple[str, Callable], ...] = ()
    # the outputs an error model reads that are neither recorded nor linked: the masters keep
    # them beside the others (the drive train's V and twist under a scenario's `outputs:`)
    watched: tuple[Port, ...] = ()
    # the FMUs the scenario layer knows nothing of (third-party: no bundled model): the
    # masters' pair may measure their response by probing them (master/probe.py)
    measured: tuple[str, ...] = ()

    def instance(self, name: str) -> Instance:
        return next(i for i in self.instances if i.name == name)

    @cached_property
    def breaks(self) -> Breaks:
        """Where its sources jump or kink (tables.source_breaks), from the start values it
        runs with (a sweep's graph has its own)."""
        return source_breaks(self.instances)

    @cached_property
    def known(self) -> tuple[Known, ...]:
        """Its sources' outputs known at every time apart from the run (tables.source_known)."""
        return source_known(self.instances)

    @cached_property
    def held(self) -> tuple[Link, ...]:
        """The links from a discrete output (a sample: it changes at its own instants) into
        an FMU with a continuous output: the masters that hold samples hold them at their
        value at the step's start (masters.Master.holds_samples). A reader whose outputs are
        all discrete is not held: it samples at its sources' instants and reads their newest
        values (the Odometry its Encoders')."""
        def variability(port: Port) -> str:
            return self.instance(port.ref.instance).variable(port.ref.variable).variability
        return tuple(l for l in self.links if variability(l.source) == "discrete"
                     and _continuous_output(self.instance(l.target.ref.instance)))

    @cached_property
    def settled(self) -> frozenset[str]:
        """The FMUs whose outputs a new sample moves at once: the readers of `held` links
        with an output that depends on an input, and what they feed through such outputs
        (the PathFollower fed the belief, then Center2Wheel, Wheel2Center); what the master
        reads again after a sample (stepping.settle)."""
        through = {i.name for i in self.instances
                   if any(u.dependencies != [] for u in i.model.outputs)}
        reached = {l.target.ref.instance for l in self.held} & through
        while True:
            more = {l.target.ref.instance for l in self.links
                    if l.source.ref.instance in reached} & through - reached
            if not more:
                return frozenset(reached)
            reached |= more

    @cached_property
    def sampled(self) -> tuple[str, ...]:
        """The models in it that sample at their own period (Encoder, Gyro, Odometry) or whose
        discrete outputs an FMU with a continuous output reads (`held`): a coarser step
        samples them differently (the Richardson estimate says so)."""
        return tuple(sorted(({i.model_name for i in self.instances} & set(SAMPLED_MODELS)) |
                            {self.instance(l.source.ref.instance).model_name
                             for l in self.held}))

    def find_model(self, model_name: str) -> Instance | None:
        """The single instance of a model, or None when there is none or several."""
        found = [i for i in self.instances if i.model_name == model_name]
        return found[0] if len(found) == 1 else None


# FMI 3.0 types the master's kinds hold exactly (Float64 is FMI 2.0's Real, Int32 its Integer)
_FMI3_KINDS = {"Float64": "Real", "Int32": "Integer"}


def _continuous_output(inst: Instance) -> bool:
    return any(v.causality == "output" and v.variability == "continuous"
               for v in inst.model.modelVariables)


def port_type(var: ScalarVariable) -> str:
    """The master's kind of a variable: Real, Integer, Boolean or String (FMI 2.0 and 3.0);
    anything else (an FMI 3.0 array, Float32, Int64, ...) is its FMI type, and refused."""
    if getattr(var, "dimensions", None):
        return type_text(var)
    if var.type == "Enumeration":
        return "Integer"
    return _FMI3_KINDS.get(var.type, var.type)


def type_text(var: ScalarVariable) -> str:
    """The variable's type for a message: Float64, or e.g. 'a Float64 array [4]'."""
    dims = getattr(var, "dimensions", None)
    if not dims:
        return var.type
    sizes = ", ".join(str(d.start) if d.start is not None else "?" for d in dims)
    return f"a {var.type} array [{sizes}]"


def compile_graph(scenario: Scenario, fmu_dir: Path | None = None) -> Graph:
    """Resolve FMUs, check the whole graph, order it. Raises ScenarioError with all problems.
    Never builds: a bundled FMU that is missing or stale is reported with the command that
    builds it."""
    check = _Checker(scenario, Path(fmu_dir) if fmu_dir is not None
                     else fmu_library.default_fmu_dir())
    start_values = check.start_values()
    links, drivers = check.links()
    recorded = check.recorded()
    if check.problems:
        raise ScenarioError(check.problems)
    instances = [Instance(c.name, check.models[c.name][0], check.models[c.name][1],
                          start_values[c.name], c.place,
                          _table(c, start_values[c.name], check.models[c.name][1].modelName))
                 for c in scenario.components]
    order, link_order = dependency_order(instances, links, scenario.label)
    models = _error_models(order)
    graph = _runnable(Graph(scenario, tuple(order), tuple(link_order), tuple(recorded), (),
                            models, _responses(order), _watched(order, models, recorded, links),
                            tuple(i.name for i in order if bundled_model(i.model) is None)))
    return dataclasses.replace(graph, warnings=tuple(
        check.warnings + _unconnected_inputs(instances, drivers, scenario.label)
        + _rollback_warning(scenario, order, links) + _variable_step_warning(scenario, order)
        + plausibility.warnings(scenario, order)))


def _watched(order: list[Instance], models: tuple, recorded: list[Port], links: list[Link]
             ) -> tuple[Port, ...]:
    """The outputs the error models read that no link and no recording keeps (Graph.watched)."""
    kept = {p.ref for p in recorded} | {l.source.ref for l in links}
    by_name = {inst.name: inst for inst in order}
    watched = []
    for name, model in models:
        variables = {v.name: v for v in by_name[name].model.modelVariables}
        watched += [_port(VarRef(name, r), variables[r]) for r in model.reads
                    if r in variables and VarRef(name, r) not in kept]
    return tuple(watched)


def _table(comp, values: dict[str, Scalar], model_name: str) -> Table | None:
    """The component's table as the loader read it, or (an SSP's, a start value the loader
    did not read) read now."""
    if comp.table is not None and comp.table.text == values.get("table"):
        return comp.table
    return table_or_none(values.get("table"), model_name)


def _adaptive_problems(scenario: Scenario, order: list[Instance]) -> list[Problem]:
    """The adaptive master rejects and retakes steps with fmi2Get/SetFMUstate: an FMU that
    cannot save its state is named (master/adaptive.py)."""
    exp = scenario.experiment
    return rollback_problems(scenario.label, exp.master, exp.tolerance,
                             [inst.name for inst in order if not inst.can_get_set_state])


def chosen_by(tolerance: float | None) -> tuple[str, str]:
    """Where the user chose the adaptive master, and the end of the fix that undoes it: a
    tolerance (the file's or --tolerance), else the master named (`master:` or --master)."""
    if tolerance is not None:
        return "experiment.tolerance (or --tolerance)", ", and drop the tolerance"
    return "experiment.master (or --master)", ""


def rollback_problems(label: str, master_name: str, tolerance: float | None, unable: list[str],
                      why: str = "canGetAndSetFMUstate is false") -> list[Problem]:
    """The refusal of a master that rejects and retakes steps (the adaptive one) on the FMUs
    in `unable`, which cannot save their state (`why`): at compile time here, from the
    model descriptions, and by master.simulate, from the loaded FMUs' functions."""
    how = master_entry(master_name)
    if not how.adaptive or not unable:
        return []
    place, undo = chosen_by(tolerance)
    return [Problem(label, place, f"the {how.name} master rejects and retakes steps with "
                    "fmi2Get/SetFMUstate, which " + ", ".join(map(repr, unable))
                    + f" cannot do ({why}); choose a fixed-step master (e.g. {DEFAULT})"
                    + undo)]


def _runnable(graph: Graph) -> Graph:
    """The graph, or ScenarioError where its master cannot run it (the adaptive master on
    FMUs that cannot save their state, or that sample): compiling and a changed experiment
    (with_scenario) refuse alike."""
    refused = _adaptive_problems(graph.scenario, list(graph.instances)) or \
        adaptive_samples(graph)
    if refused:
        raise ScenarioError(refused)
    return graph


def adaptive_samples(graph: Graph, master_name: str | None = None,
                     tolerance: float | None = None) -> list[Problem]:
    """The adaptive master cannot step FMUs that sample at their own instants: each sample
    is a jump inside some step, which its step control shrinks the step to bracket, down to
    the smallest step, at the first sample (the fixed-step masters hold samples exactly:
    docs/masters.md, "Samples"). Checked at compile time and again by master.simulate (an
    experiment changed after it: `master_name`, the master it runs under, `tolerance` its
    tolerance; without them, the graph's own)."""
    if master_name is None:
        master_name, tolerance = (graph.scenario.experiment.master,
                                  graph.scenario.experiment.tolerance)
    how = master_entry(master_name)
    if not how.adaptive or not graph.sampled:
        return []
    place, undo = chosen_by(tolerance)
    return [Problem(graph.scenario.label, place, f"the {how.name} master cannot step "
                    f"{', '.join(graph.sampled)}, which sample at their own instants: each "
                    "sample is a jump its step control cannot bracket (the run would stop at "
                    f"the first one); choose a fixed-step master (e.g. {DEFAULT}) with a step "
                    "that divides the sample period" + undo)]


@dataclass(frozen=True)
class ErrorModel:
    """An FMU's error model in the two forms the masters take: `stepwise(blend, names, inst)`
    for the adaptive master (master/adaptive.py), `batch(names, inst)` for the fixed-step
    masters' embedded pair (master/pair.py); each gives None where it does not apply."""
    stepwise: Callable
    batch: Callable
    reads: tuple[str, ...] = ()     # the outputs its batch form linearises about


POSE_MODEL = ErrorModel(pose_error, pose_batch)


def _no_stepwise(blend, names, inst) -> None:
    """The drive train's models have no form for the adaptive master."""
    return None


# per bundled model name: the error models of the drive train (models/drive_error.py)
_DRIVE_MODELS = {"DCMotor": ErrorModel(_no_stepwise, motor_linear, MOTOR_READS),
                 "MecanumDynamics": ErrorModel(_no_stepwise, body_linear, BODY_READS)}


def _error_models(order: list[Instance]) -> tuple[tuple[str, ErrorModel], ...]:
    """The bundled models' error models (Graph.error_models)."""
    return tuple((inst.name, m) for inst in order if (m := _error_model(inst)) is not None)


def _error_model(inst: Instance) -> ErrorModel | None:
    if _role(inst) == "pose":
        return POSE_MODEL
    return _DRIVE_MODELS.get(inst.model_name) if bundled_model(inst.model) is not None else None


def _responses(order: list[Instance]) -> tuple[tuple[str, Callable], ...]:
    """The bundled models' responses (Graph.responses)."""
    return tuple((inst.name, response) for inst in order
                 if bundled_model(inst.model) is not None and has_response(inst.model_name))


def _role(inst: Instance) -> str | None:
    model = bundled_model(inst.model)
    return model.role if model is not None else None


def _rollback_warning(scenario: Scenario, order: list[Instance], links: list[Link]) -> list[str]:
    """A master that rolls back steps a loop twice, restoring the state in between: every FMU
    must be able to get and set its state. Without, it steps the loop once (as the trapezoidal
    master)."""
    position = {inst.name: i for i, inst in enumerate(order)}
    loop = any(position[l.source.ref.instance] > position[l.target.ref.instance] for l in links)
    unable = [inst.name for inst in order if not inst.can_get_set_state]
    name = scenario.experiment.master
    if not master_entry(name).rolls_back or not loop or not unable:
        return []
    return [f"{scenario.label}: the {name} master takes each step of a feedback loop twice, "
            f"rolling back with fmi2SetFMUstate, which {', '.join(repr(n) for n in unable)} "
            f"cannot do (canGetAndSetFMUstate is false): the loop is stepped once on "
            f"extrapolated inputs instead, as by the trapezoidal master"]


def _variable_step_warning(scenario: Scenario, order: list[Instance]) -> list[str]:
    """The adaptive master varies the communication step; an FMU may declare that it cannot
    handle that (canHandleVariableCommunicationStepSize false: pythonfmu3's default). It is
    stepped anyway, as FMPy steps it; the warning says so and what keeps the step fixed."""
    how = master_entry(scenario.experiment.master)
    fixed = [inst.name for inst in order if not inst.can_vary_step]
    if not how.adaptive or not fixed:
        return []
    return [f"{scenario.label}: the {how.name} master varies the communication step, which "
            f"{', '.join(repr(n) for n in fixed)} declare(s) it cannot handle "
            "(canHandleVariableCommunicationStepSize is false); it is stepped so anyway, and a "
            "fixed-step master (drop the tolerance) keeps the step it declares"]


class _Checker:
    """Collects every problem of one scenario while resolving its parts against the FMUs."""

    def __init__(self, scenario: Scenario, fmu_dir: Path):
        self.scenario, self.problems, self.warnings = scenario, [], []
        self.models: dict[str, tuple[Path, ModelDescription]] = {}
        cache: dict[Path, ModelDescription] = {}
        for comp in scenario.components:
            try:
                path = fmu_library.resolve_fmu(comp.fmu, scenario.path.parent, fmu_dir)
                stale = fmu_library.stale_warning(comp.fmu, fmu_dir)
                if stale and stale not in self.warnings:
                    self.warnings.append(stale)
                if path not in cache:
                    cache[path] = fmu_library.read_description(path)
                    problem = fmu_library.loading_problem(path, cache[path])
                    if problem:
                        self.bad(f"{comp.place}.fmu", problem)
                self.models[comp.name] = (path, with_dependencies(
                    cache[path], comp.dependencies, f"{comp.place}.dependencies", self.bad))
            except ValueError as err:
                self.bad(f"{comp.place}.fmu", str(err))
        self.variables = {name: {v.name: v for v in md.modelVariables}
                          for name, (_, md) in self.models.items()}
        self.instance_names = [c.name for c in scenario.components]

    def bad(self, place: str, message: str) -> None:
        problem = Problem(self.scenario.label, place, message)
        if problem not in self.problems:     # a shared parameter is checked per taker
            self.problems.append(problem)

    def lookup(self, ref: VarRef, place: str) -> ScalarVariable | None:
        if ref.instance not in self.instance_names:
            self.bad(place, f"unknown instance '{_clip(ref.instance)}' in '{_clip(str(ref))}'"
                            f"{did_you_mean(ref.instance, self.instance_names)}")
            return None
        if ref.instance not in self.variables:
            return None          # its FMU could not be read: already reported
        var = self.variables[ref.instance].get(ref.variable)
        if var is None:
            self.bad(place, f"{self.models[ref.instance][1].modelName} instance "
                            f"'{ref.instance}' has no variable '{ref.variable}'"
                            f"{did_you_mean(ref.variable, self.variables[ref.instance])}")
        return var

    def start_values(self) -> dict[str, dict[str, Scalar]]:
        """Parameters and start values; shared ones go to every component that has them."""
        scenario = self.scenario
        for name in scenario.parameters:
            takers = [c for c in scenario.components if c.name in self.variables
                      and _settable(self.variables[c.name].get(name))]
            if not takers and len(self.variables) == len(scenario.components):
                self.bad(f"parameters.{name}", f"no component has a parameter '{name}'")
        return {comp.name: self._component_values(comp) for comp in scenario.components
                if comp.name in self.variables}

    def _component_values(self, comp) -> dict[str, Scalar]:
        own, md = self.variables[comp.name], self.models[comp.name][1]
        merged = _merged_parameters(self.scenario, comp, own)
        model = bundled_model(md)
        merged.update(_step_value(model, own, merged, self.scenario.experiment.step_size))
        for key in comp.parameters:
            var = own.get(key)
            if var is None:
                self.bad(f"{comp.place}.parameters.{key}", f"{md.modelName} has no parameter "
                         f"'{key}'{did_you_mean(key, [v for v in own if _settable(own[v])])}")
            elif not _settable(var):
                self.bad(f"{comp.place}.parameters.{key}", f"'{key}' is {var.causality} "
                         f"({var.variability}), not a parameter or input whose start value "
                         "can be set")
        for key, value in merged.items():
            var = own.get(key)
            if var is not None and _settable(var):
                message = _type_problem(var, value)
                if message:
                    self.bad(self._place(comp, key), message)
        if model is not None:
            values = {name: merged.get(name, start_value(var)) for name, var in own.items()}
            for key, message in model.check(values, self.scenario.experiment.start_time):
                self.bad(self._place(comp, key), message)
        return merged

    def _place(self, comp, key: str) -> str:
        return (f"{comp.place}.parameters.{key}" if key in comp.parameters
                else f"parameters.{key}")

    def links(self) -> tuple[list[Link], dict[VarRef, str]]:
        links: list[Link] = []
        drivers: dict[VarRef, str] = {}
        for conn in self.scenario.connections:
            src, dst = self.lookup(conn.source, conn.place), self.lookup(conn.target, conn.place)
            if src is None or dst is None:
                continue
            messages = _connection_problems(conn, src, dst, drivers)
            for message in messages:
                self.bad(conn.place, message)
            drivers.setdefault(conn.target, conn.place)
            if not messages:
                links.append(Link(_port(conn.source, src), _port(conn.target, dst), conn.place))
        return links, drivers

    def recorded(self) -> list[Port]:
        if self.scenario.outputs is None:
            return [_port(VarRef(comp.name, var.name), var)
                    for comp in self.scenario.components
                    for var in (self.models[comp.name][1].modelVariables
                                if comp.name in self.models else ())
                    if var.causality == "output" and port_type(var) in VALUE_TYPES]
        recorded, seen = [], set()
        for ref, place in self.scenario.outputs:
            var = self.lookup(ref, place)
            if var is not None and port_type(var) not in VALUE_TYPES:
                self.bad(place, f"'{ref}' is {type_text(var)}: only Real, Integer and "
                                "Boolean variables are recorded (FMI 3.0: Float64, Int32)"
                                + _ARRAY_HINT * bool(getattr(var, "dimensions", None)))
            elif var is not None and ref not in seen:
                seen.add(ref)
                recorded.append(_port(ref, var))
        return recorded


_ARRAY_HINT = ("; this master moves scalars: use the array's scalar variables (e.g. "
               "w1..w4 for wheel_speeds)")


def _merged_parameters(scenario: Scenario, comp, own: dict) -> dict[str, Scalar]:
    """A component's parameters: the scenario's shared ones that it has (and can set), then
    its own, which win."""
    merged = {k: v for k, v in scenario.parameters.items() if _settable(own.get(k))}
    merged.update(comp.parameters)
    return merged


def _step_value(model, own: dict, merged: dict, step_size) -> dict[str, Scalar]:
    """The bundled model's step_parameter (catalog.Model: MecanumDynamics' h_ref) at the
    experiment's step_size, unless the scenario sets it; nothing for a step that is no
    positive finite number (the experiment's check reports it)."""
    name = model.step_parameter if model is not None else None
    if name is None or name in merged or not _settable(own.get(name)):
        return {}
    usable = is_finite(step_size) and step_size > 0
    return {name: float(step_size)} if usable else {}


def with_scenario(graph: Graph, scenario: Scenario) -> Graph:
    """The graph under the scenario's experiment as changed after compiling (a sweep's
    `experiment:`): each bundled model's step_parameter that the scenario leaves unset
    follows the new step_size, as compiling would have set it. A master the graph cannot run
    under (the adaptive one on FMUs that cannot save their state or that sample) is refused
    as compiling refuses it: ScenarioError."""
    instances = []
    for inst in graph.instances:
        comp = next(c for c in scenario.components if c.name == inst.name)
        own = {v.name: v for v in inst.model.modelVariables}
        merged = _merged_parameters(scenario, comp, own)
        step = _step_value(bundled_model(inst.model), own, merged,
                           scenario.experiment.step_size)
        instances.append(dataclasses.replace(inst, start_values={**inst.start_values, **step})
                         if step else inst)
    return _runnable(dataclasses.replace(graph, scenario=scenario, instances=tuple(instances)))


def _clip(text: str, limit: int = 80) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _port(ref: VarRef, var: ScalarVariable) -> Port:
    return Port(ref, port_type(var), var.valueReference, var.causality)


def _connection_problems(conn, src: ScalarVariable, dst: ScalarVariable,
                         drivers: dict[VarRef, str]) -> list[str]:
    problems = []
    for ref, var, wanted in ((conn.source, src, "output"), (conn.target, dst, "input")):
        if var.causality != wanted:
            article = "an" if var.causality[0] in "aeiou" else "a"
            problems.append(f"'{ref}' is {article} {var.causality}, not an {wanted}: a "
                            "connection goes [from output, to input]")
    arrays = any(getattr(v, "dimensions", None) for v in (src, dst))
    if port_type(src) != port_type(dst):
        problems.append(f"type mismatch: '{conn.source}' is {type_text(src)}, "
                        f"'{conn.target}' is {type_text(dst)}" + _ARRAY_HINT * arrays)
    elif port_type(src) not in VALUE_TYPES:
        problems.append(f"'{conn.source}' is {type_text(src)}: connections carry Real, "
                        "Integer and Boolean values (FMI 3.0: Float64, Int32)"
                        + (_ARRAY_HINT if arrays else
                           " (set a String once as a parameter instead)"))
    if conn.target in drivers:
        problems.append(f"input '{conn.target}' already has a driver "
                        f"({drivers[conn.target]}); an input takes one connection")
    return problems


def _unconnected_inputs(instances: list[Instance], drivers, label: str) -> list[str]:
    warnings = []
    for inst in instances:
        for var in inst.model.modelVariables:
            if var.causality == "input" and VarRef(inst.name, var.name) not in drivers:
                start = inst.start_values.get(var.name, var.start)
                warnings.append(f"{label}: {inst.declared_at}: input '{var.name}' is not "
                                f"connected; it keeps its start value {start}")
    return warnings


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


def start_value(var: ScalarVariable):
    """The start value a model description declares, as a Python value (None: none)."""
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
    model = bundled_model(inst.model)
    if not problems and model is not None:
        merged = {n: inst.value(n) for n in own} | values
        problems = model.check(merged, graph.scenario.experiment.start_time)
    return problems
