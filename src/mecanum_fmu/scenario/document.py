"""Load a scenario file (YAML) into frozen dataclasses, checking everything that needs no FMU.

Scenario files are data: they are read with ``yaml.safe_load`` only and nothing in them runs.
Every problem is collected and raised together as one ScenarioError.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

import yaml

from ..errors import Problem, ScenarioError, did_you_mean
from ..masters import (ADAPTIVE, DEFAULT as DEFAULT_MASTER, DEFAULT_ESTIMATE, ESTIMATES,
                       MASTERS, entry as master_entry)
from ..storage import NotARegularFile, read_regular
from ..values import (is_finite, is_number, name_problem, scalar_problem, show,
                     type_name as _type_name, unknown_keys as _unknown_keys, usable_name)

MAX_FILE_BYTES = 1_000_000
DEFAULT_EXPERIMENT = {"start_time": 0.0, "stop_time": 10.0, "step_size": 0.01,
                      "master": DEFAULT_MASTER, "tolerance": None, "relative_tolerance": None,
                      "estimate": DEFAULT_ESTIMATE}

Scalar = Union[bool, int, float, str]
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TOP_KEYS = ("name", "description", "experiment", "components", "connections", "outputs",
             "parameters", "recorded")
_COMPONENT_KEYS = ("fmu", "parameters", "description", "segments", "table", "waypoints",
                   "dependencies")


@dataclass(frozen=True)
class VarRef:
    """A reference `instance.variable` (the variable part may itself contain dots)."""
    instance: str
    variable: str

    def __str__(self) -> str:
        return f"{self.instance}.{self.variable}"


@dataclass(frozen=True)
class Experiment:
    start_time: float
    stop_time: float
    step_size: float
    master: str
    tolerance: float | None = None    # the adaptive master's error bound (masters.py)
    relative_tolerance: float | None = None   # its relative one (None: the registry's default)
    estimate: str = DEFAULT_ESTIMATE    # how the run's error is estimated (masters.ESTIMATES)


@dataclass(frozen=True)
class Component:
    name: str
    fmu: str                      # as written: a bundled model name or a path
    parameters: dict[str, Scalar]
    place: str                    # where it is declared, for messages
    table: Any = None             # its table, read once (tables.Table; profiles.py)
    # `dependencies: {x: [], y: [u]}`: the inputs each output depends on, for outputs whose
    # model description declares none (graph.with_dependencies): (output, (input, ...)) pairs
    dependencies: tuple = ()


@dataclass(frozen=True)
class Connection:
    source: VarRef
    target: VarRef
    place: str


@dataclass(frozen=True)
class Scenario:
    path: Path
    name: str
    description: str
    experiment: Experiment
    components: tuple[Component, ...]
    connections: tuple[Connection, ...]
    outputs: tuple[tuple[VarRef, str], ...] | None   # (reference, place); None: every output
    parameters: dict[str, Scalar] = field(default_factory=dict)   # shared by all components
    # pose instance -> the recorded path (time,x,y[,theta] text) it is held against
    recorded: dict[str, str] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """The file as the user named it, for messages."""
        return str(self.path)


def is_identifier(name: Any) -> bool:
    """The rule for instance names: letters, digits and _, not starting with a digit."""
    return isinstance(name, str) and _NAME.fullmatch(name) is not None


MAPPING_LABEL = "<scenario mapping>"    # the "file" of a scenario given as a mapping


def load_scenario(path: str | Path, parameters: dict | None = None) -> Scenario:
    """Read and check a scenario file; `parameters` ({"w2c.R": 0.061} or a shared {"R": ...})
    are set on its components first and checked by the same rules. Raises ScenarioError
    listing every problem found."""
    scenario, problems = read_scenario(path, parameters)
    if problems:
        raise ScenarioError(problems)
    return scenario


def load_scenario_dict(doc: Any, base_dir: str | Path = ".",
                       parameters: dict | None = None) -> Scenario:
    """A scenario given as a mapping (the keys of a scenario file), checked as a file is;
    relative FMU and table paths are taken from base_dir. Raises ScenarioError."""
    scenario, problems = scenario_from_doc(doc, Path(base_dir) / MAPPING_LABEL, parameters)
    if problems:
        raise ScenarioError(problems)
    return scenario


def read_scenario(path: str | Path, parameters: dict | None = None
                  ) -> tuple[Scenario | None, list[Problem]]:
    """The scenario (its valid parts, when some are wrong) and every problem of the file."""
    path = Path(path)
    return scenario_from_doc(read_yaml(path, str(path)), path, parameters)


def scenario_from_doc(doc: Any, path: Path, parameters: dict | None = None
                      ) -> tuple[Scenario | None, list[Problem]]:
    """The Scenario of a parsed document and every problem; None when nothing usable is left."""
    label = str(path)
    problems: list[Problem] = []

    def bad(place: str, message: str) -> None:
        problems.append(Problem(label, place, message))

    if doc is None:
        return None, [Problem(label, "file", "is empty: a scenario needs at least "
                                             "components (instance name: {fmu: NAME_OR_PATH})")]
    if not isinstance(doc, dict):
        return None, [Problem(label, "top level", f"expected a mapping with keys "
                              f"{', '.join(_TOP_KEYS)}, got {_type_name(doc)}")]
    if parameters:
        doc = with_parameters(doc, parameters, bad)
    _unknown_keys(doc, _TOP_KEYS, "top level", bad)
    name = doc.get("name", usable_name(path.stem) or "scenario")
    if (problem := name_problem(name)) is not None:
        bad("name", problem)
        name = usable_name(path.stem) or "scenario"
    description = doc.get("description", "")
    if not isinstance(description, str):
        bad("description", f"expected text, got {_type_name(description)}")
        description = ""
    experiment = parse_experiment(doc.get("experiment", {}), bad)
    shared = _parameters(doc.get("parameters", {}), "parameters", bad)
    components = _components(doc.get("components"), bad)
    components = _profiles(components, doc.get("components"), path, experiment.start_time,
                           problems)
    connections = _connections(doc.get("connections", []), bad)
    outputs = _outputs(doc.get("outputs"), bad)
    recorded = _recorded(doc.get("recorded"), components, path, experiment.start_time, problems)
    declared = doc.get("components")
    if problems and not (isinstance(declared, dict) and len(declared) == len(components)):
        return None, problems      # a component is missing: the graph's checks would mislead
    return Scenario(path, name, description, experiment, components, connections, outputs,
                    shared, recorded), problems


def with_parameters(doc: dict, parameters: dict, bad) -> dict:
    """doc with `instance.parameter: value` set in that component's parameters and a bare
    `name: value` in the shared ones (copies only what changes). A key naming no component
    goes to bad(place, message); the values are checked afterwards with the file's."""
    doc = dict(doc)
    components = doc.get("components")
    components = dict(components) if isinstance(components, dict) else {}
    for key, value in parameters.items():
        place = f"parameters[{show(key)}] (an argument, not in the file)"
        instance, dot, name = key.partition(".") if isinstance(key, str) else ("", "", "")
        if not isinstance(key, str) or not key or (dot and not (instance and name)):
            bad(place, "expected 'instance.parameter' (e.g. 'w2c.R') or a shared name ('R')")
        elif not dot:
            doc["parameters"] = _merged(doc.get("parameters"), key, value)
        elif instance not in components:
            bad(place, f"no component '{instance}'{did_you_mean(instance, components)}")
        else:
            spec = components[instance]
            spec = dict(spec) if isinstance(spec, dict) else {"fmu": spec}
            spec["parameters"] = _merged(spec.get("parameters"), name, value)
            components[instance] = spec
    if isinstance(doc.get("components"), dict):
        doc["components"] = components
    return doc


def _merged(mapping: Any, key: str, value: Any) -> Any:
    """mapping (a dict or nothing) with key set; anything else is left for its own message."""
    if mapping is None:
        return {key: value}
    return {**mapping, key: value} if isinstance(mapping, dict) else mapping


def read_yaml(path: Path, label: str) -> Any:
    """The YAML document at path, read as data (UniqueKeyLoader, a safe_load loader); a bad file
    raises ScenarioError naming the place."""
    def fail(place: str, message: str):
        return ScenarioError([Problem(label, place, message)])

    try:
        text = read_regular(path, MAX_FILE_BYTES, "a scenario file").decode("utf-8")
    except NotARegularFile as err:
        raise fail("file", str(err)) from None
    except FileNotFoundError:
        raise fail("file", "not found; check the path") from None
    except IsADirectoryError:
        raise fail("file", "is a folder; give a scenario .yaml file") from None
    except UnicodeDecodeError as err:
        raise fail("file", f"is not UTF-8 text ({err.reason} at byte {err.start})") from None
    except OSError as err:
        raise fail("file", f"cannot be read: {err.strerror}") from None
    try:
        return yaml.load(text, Loader=UniqueKeyLoader)     # safe_load, duplicate keys refused
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark
        place = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "YAML"
        raise fail(place, f"YAML syntax error: {err.problem or err}") from None
    except (yaml.YAMLError, RecursionError) as err:
        raise fail("YAML", f"cannot be parsed: {type(err).__name__}") from None


class UniqueKeyLoader(yaml.SafeLoader):
    """yaml.SafeLoader (safe_load's loader) that refuses a key given twice in one mapping:
    plain YAML silently keeps the last value. Merge keys (<<) may still be overridden."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    first = seen.get(key)
                except TypeError:       # unhashable: the base class reports it
                    continue
                if first is not None:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark,
                        f"duplicate key {show(key)} (first given on line {first}); keep one",
                        key_node.start_mark)
                seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


# YAML 1.1 (PyYAML) reads 1e-3 and 2E5 as text: a float needs a dot and a signed exponent
# there. Users write them as numbers (YAML 1.2 does), so such plain scalars are floats here.
UniqueKeyLoader.yaml_implicit_resolvers = {
    first: list(resolvers) for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def parse_experiment(raw: Any, bad) -> Experiment:
    """The experiment from a mapping of its keys (defaults for those left out); problems go to
    bad(place, message). Scenario files and SSP annotations both come through here."""
    values, ok = experiment_values(raw, bad)
    experiment = Experiment(**{**DEFAULT_EXPERIMENT, **values})
    if ok:
        for problem in check_experiment(experiment):
            bad(*problem)
    return experiment


def experiment_values(raw: Any, bad) -> tuple[dict[str, Any], bool]:
    """The valid entries of a mapping of experiment keys (a scenario's `experiment:`, a sweep's
    overrides), and whether every time was a finite number; problems go to bad."""
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        bad("experiment", f"expected a mapping (start_time, stop_time, step_size, master), "
                          f"got {_type_name(raw)}")
        raw = {}
    _unknown_keys(raw, tuple(DEFAULT_EXPERIMENT), "experiment", bad)
    values: dict[str, Any] = {}
    ok = True
    for key in ("start_time", "stop_time", "step_size"):
        if key not in raw:
            continue
        value = raw[key]
        if not is_number(value):
            bad(f"experiment.{key}", f"expected a number of seconds, got {show(value)}")
            ok = False
        elif not is_finite(value):
            bad(f"experiment.{key}", f"{show(value)} is not a finite number")
            ok = False
        else:
            values[key] = float(value)
    if "master" in raw:
        if isinstance(raw["master"], str) and raw["master"] in MASTERS:
            values["master"] = raw["master"]
        else:
            bad("experiment.master", f"unknown master {show(raw['master'])}"
                f"{did_you_mean(raw['master'], MASTERS)} (choose one of {', '.join(MASTERS)})")
    if "tolerance" in raw:
        _tolerance(raw, values, bad)
    if "relative_tolerance" in raw:
        _relative_tolerance(raw, values, bad)
    if "estimate" in raw:
        if problem := estimate_problem(raw["estimate"], values.get("master")):
            bad("experiment.estimate", problem)
        else:
            values["estimate"] = raw["estimate"]
    return values, ok


def estimate_problem(value: Any, master: Any) -> str | None:
    """Why `value` cannot be the estimate of a run with `master` (None: none chosen), or None
    (the one rule of a file, a sweep, the command line and the Python API)."""
    if not isinstance(value, str) or value not in ESTIMATES:
        return (f"unknown estimate {show(value)}{did_you_mean(value, tuple(ESTIMATES))} "
                f"(choose one of {', '.join(ESTIMATES)})")
    if value == "richardson" and master in MASTERS and master_entry(master).adaptive:
        return ("the adaptive master estimates its error itself, step by step (Richardson "
                "needs a fixed step): drop the estimate richardson (`estimate:` or --estimate)"
                " or the tolerance")
    return None


def _tolerance(raw: dict, values: dict, bad) -> None:
    """experiment.tolerance: a number > 0; it chooses the adaptive master (masters.py)."""
    value = raw["tolerance"]
    problem = tolerance_problem(value, values.get("master"))
    if problem:
        bad("experiment.tolerance", problem)
    else:
        values["tolerance"], values["master"] = float(value), ADAPTIVE


def tolerance_problem(value: Any, master: Any) -> str | None:
    """Why `value` cannot be the tolerance of a run with `master` (None: none chosen), or None:
    a finite number > 0, and only for an adaptive master (the one rule of a file, a sweep,
    the command line and the Python API)."""
    if not is_number(value) or not is_finite(value) or not value > 0:
        return f"expected a number > 0 (e.g. 1e-4), got {show(value)}"
    if master in MASTERS and not master_entry(master).adaptive:
        return (f"the {master} master takes a fixed step and would ignore the tolerance: drop "
                f"the master {master} (`master:` or --master; a tolerance chooses the adaptive "
                "master) or the tolerance")
    return None


def _relative_tolerance(raw: dict, values: dict, bad) -> None:
    """experiment.relative_tolerance in a file (relative_tolerance_problem)."""
    value = raw["relative_tolerance"]
    problem = relative_tolerance_problem(value, values.get("tolerance"))
    if problem:
        bad("experiment.relative_tolerance", problem)
    else:
        values["relative_tolerance"] = float(value)


def relative_tolerance_problem(value: Any, tolerance: Any) -> str | None:
    """Why `value` cannot be the relative tolerance beside `tolerance` (None: none given), or
    None: a finite number >= 0, and only beside an absolute tolerance (the one rule of a
    file and of an experiment made in code)."""
    if not is_number(value) or not is_finite(value) or not value >= 0:
        return f"expected a number >= 0 (e.g. 1e-3), got {show(value)}"
    if tolerance is None:
        return ("it weighs the adaptive master's error: give a tolerance (the absolute one) "
                "beside it, or drop it")
    return None


def override_experiment(scenario: "Scenario", changes: dict[str, Any], label: str,
                        where: str = "") -> "Scenario":
    """The scenario with experiment values replaced (command-line options, a sweep's
    `experiment:`), checked by the scenario's own rules; problems are raised, placed at
    `<place><where>` in `label`."""
    if not changes:
        return scenario
    experiment = dataclasses.replace(scenario.experiment, **changes)
    problems = [Problem(label, f"{place}{where}", message)
                for place, message in check_experiment(experiment)]
    if problems:
        raise ScenarioError(problems)
    return dataclasses.replace(scenario, experiment=experiment)


def check_experiment(exp: Experiment) -> list[tuple[str, str]]:
    """(place, message) for each inconsistency; also used for command-line overrides."""
    out = []
    for key in ("start_time", "stop_time", "step_size"):
        if not math.isfinite(getattr(exp, key)):
            out.append((f"experiment.{key}", f"{getattr(exp, key)} is not a finite number"))
    if out:
        return out
    if exp.step_size <= 0:
        out.append(("experiment.step_size", f"{exp.step_size} must be > 0"))
    if exp.stop_time <= exp.start_time:
        out.append(("experiment.stop_time",
                    f"{exp.stop_time} must be after start_time {exp.start_time}"))
    elif exp.step_size > exp.stop_time - exp.start_time:
        out.append(("experiment.step_size", f"{exp.step_size} is longer than the run "
                    f"({exp.stop_time - exp.start_time} s); use a smaller step"))
    elif exp.step_size > 0 and (exp.stop_time - exp.start_time) / exp.step_size > 1e8:
        out.append(("experiment.step_size", f"{exp.step_size} gives more than 1e8 steps; "
                    "use a larger step"))
    elif exp.step_size > 0 and (problem := _quantised(exp)):
        out.append(("experiment.step_size", problem))
    return out + _tolerance_problems(exp)


def _quantised(exp: Experiment) -> str | None:
    """Why the step is too fine for the times it steps through, or None: a step must span at
    least the spacing of doubles near them, else steps collapse onto the same times (near
    1e15 s doubles are 0.125 s apart: a 0.05 s step would take steps of 0 and 0.125 s); at or
    above it the grid may still round (tests/test_run_output.py runs 1e15 s at 0.125 s), but
    every step advances."""
    spacing = math.ulp(max(abs(exp.start_time), abs(exp.stop_time)))
    if exp.step_size >= spacing:
        return None
    return (f"{exp.step_size:g} s is finer than the times can resolve near "
            f"{max(abs(exp.start_time), abs(exp.stop_time)):g} s (doubles {spacing:g} s apart: "
            "steps would collapse onto the same times); shift the run's times towards 0 (a "
            f"table's start: first_row or offset) or use a step of at least {spacing:g} s")


def _tolerance_problems(exp: Experiment) -> list[tuple[str, str]]:
    """The tolerances of an experiment made in code (prepare's arguments, a sweep): the
    absolute one under tolerance_problem (the one rule), the relative one a number >= 0
    beside it."""
    out = []
    if exp.tolerance is not None and (problem := tolerance_problem(exp.tolerance, exp.master)):
        out.append(("experiment.tolerance", problem))
    if exp.relative_tolerance is not None and (
            problem := relative_tolerance_problem(exp.relative_tolerance, exp.tolerance)):
        out.append(("experiment.relative_tolerance", problem))
    if problem := estimate_problem(exp.estimate, exp.master):
        out.append(("experiment.estimate", problem))
    return out


def _parameters(raw: Any, place: str, bad) -> dict[str, Scalar]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        bad(place, f"expected a mapping of name: value, got {_type_name(raw)}")
        return {}
    out = {}
    for key, value in raw.items():
        if not isinstance(key, str):
            bad(place, f"parameter name {show(key)} must be text")
        elif (problem := scalar_problem(value)) is not None:
            bad(f"{place}.{key}", problem)
        else:
            out[key] = value
    return out


def _components(raw: Any, bad) -> tuple[Component, ...]:
    if raw is None:
        bad("components", "missing: declare at least one component "
                          "(instance name: {fmu: NAME_OR_PATH})")
        return ()
    if not isinstance(raw, dict) or not raw:
        bad("components", f"expected a mapping of instance name -> {{fmu: ...}}, "
                          f"got {_type_name(raw) if raw != {} else 'an empty mapping'}")
        return ()
    out = []
    for name, spec in raw.items():
        place = f"components.{name}"
        if not is_identifier(name):
            bad("components", f"instance name {show(name)} must be an identifier (letters, digits, _)")
            continue
        if isinstance(spec, str):
            spec = {"fmu": spec}          # shorthand: `name: VelocitySource`
        if not isinstance(spec, dict):
            bad(place, f"expected a mapping with key fmu, got {_type_name(spec)}")
            continue
        _unknown_keys(spec, _COMPONENT_KEYS, place, bad)
        fmu = spec.get("fmu")
        if not isinstance(fmu, str) or not fmu.strip():
            bad(f"{place}.fmu", "missing or empty: a bundled model name (e.g. Center2Wheel) "
                                "or a path to a .fmu file")
            continue
        params = _parameters(spec.get("parameters", {}), f"{place}.parameters", bad)
        out.append(Component(name, fmu, params, place, dependencies=_dependencies(
            spec.get("dependencies", {}), f"{place}.dependencies", bad)))
    return tuple(out)


def _dependencies(raw: Any, place: str, bad) -> tuple:
    """`dependencies: {output: [input, ...]}` as (output, (input, ...)) pairs; the names are
    checked against the FMU when the graph is built (graph.with_dependencies)."""
    if not isinstance(raw, dict):
        bad(place, f"expected a mapping of output: [inputs it depends on] (e.g. {{x: []}} for "
                   f"an output that depends on no input), got {_type_name(raw)}")
        return ()
    out = []
    for output, inputs in raw.items():
        names = inputs if isinstance(inputs, list) else None
        if not isinstance(output, str) or names is None or \
                not all(isinstance(n, str) for n in names):
            bad(f"{place}.{output}", "expected an output's name and a list of the FMU's "
                                     f"input names (may be empty: []), got {show(inputs)}")
            continue
        out.append((output, tuple(names)))
    return tuple(out)


def _profiles(components: tuple[Component, ...], raw: Any, path: Path, start_time: float,
              problems: list[Problem]) -> tuple[Component, ...]:
    """VelocitySources and PathFollowers get their table as CSV text (profiles.py)."""
    from .profiles import PROFILE_KEYS, resolve_profile
    out = []
    for comp in components:
        spec = raw[comp.name] if isinstance(raw[comp.name], dict) else {}
        if comp.fmu in PROFILE_KEYS:
            params, table = resolve_profile(comp.fmu, spec, comp.parameters, path.parent,
                                            start_time, comp.place, str(path), problems.append)
            comp = dataclasses.replace(comp, parameters=params, table=table)
        for key in (k for k in ("segments", "table", "waypoints") if k in spec):
            if key not in PROFILE_KEYS.get(comp.fmu, ()):
                problems.append(Problem(str(path), f"{comp.place}.{key}", f"{key}: only a "
                                        + " or ".join(m for m, keys in PROFILE_KEYS.items()
                                                      if key in keys) + " has one"))
        out.append(comp)
    return tuple(out)


def _recorded(raw: Any, components: tuple[Component, ...], path: Path, start_time: float,
              problems: list[Problem]) -> dict[str, str]:
    """`recorded: {pose: {file: day1, topic: /odom}}`: the paths each pose is held against."""
    if raw is None:
        return {}
    from .profiles import recorded_paths
    poses = [c.name for c in components if c.fmu == "PoseIntegrator"]
    return recorded_paths(raw, poses, path.parent, start_time, str(path), problems.append)


def parse_ref(text: Any) -> VarRef | None:
    if not isinstance(text, str) or "." not in text:
        return None
    instance, variable = text.split(".", 1)
    if not instance or not variable:
        return None
    return VarRef(instance, variable)


def _connections(raw: Any, bad) -> tuple[Connection, ...]:
    if raw is None:
        return ()
    if not isinstance(raw, list):
        bad("connections", f"expected a list of [from output, to input] pairs, got {_type_name(raw)}")
        return ()
    out = []
    for i, item in enumerate(raw):
        place = f"connections[{i}]"
        if isinstance(item, dict) and set(item) == {"from", "to"}:
            item = [item["from"], item["to"]]
        if not isinstance(item, list) or len(item) != 2:
            bad(place, f"expected a pair [instance.output, instance.input], got {show(item)}")
            continue
        refs = [parse_ref(x) for x in item]
        for x, ref in zip(item, refs):
            if ref is None:
                bad(place, f"{show(x)} is not of the form instance.variable")
        if all(refs):
            out.append(Connection(refs[0], refs[1], place))
    return tuple(out)


def _outputs(raw: Any, bad):
    if raw is None:
        return None
    if not isinstance(raw, list):
        bad("outputs", f"expected a list of instance.variable, got {_type_name(raw)}")
        return None
    out = []
    for i, item in enumerate(raw):
        ref = parse_ref(item)
        if ref is None:
            bad(f"outputs[{i}]", f"{show(item)} is not of the form instance.variable")
        else:
            out.append((ref, f"outputs[{i}]"))
    return tuple(out)
