"""A sweep file (YAML) -> the list of runs: each run's index and parameter values.

The file is data (``yaml.safe_load`` only). Everything is checked before anything runs and
every problem is reported at once (exit 2), naming the sweep file and the place:

    name: wheel_tolerance
    scenario: ../circle.yaml            # relative to this file
    experiment: {step_size: 0.05}       # optional overrides of the scenario's experiment
    grid: {source.w_expr: ["0", "0.5"]} # optional: the cartesian product of the value lists
    random: {samples: 1000, seed: 1, w2c.dR1: {normal: [0.0, 0.0003]}}

Run order: grid points first (the outer index, the last grid key varies fastest), then the
samples of each grid point: run = grid_point * samples + sample. The same `samples` draws
(one NumPy generator seeded with `seed`, parameters drawn in file order) are used at every grid
point, so grid points are compared on the same random wheels. Grid values are checked by the
scenario's own rules up front (a bad one is exit 2); a random draw that breaks them (say
R + dRi <= 0) makes that run a failed row with the reason, the rest of the study goes on.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import Problem, ScenarioError
from ..scenario.graph import Graph, check_start_values, settable_parameters, with_scenario
from ..models.blocks.profile_table import INTERPOLATIONS
from ..scenario.profiles import PROFILE_KEYS
from ..errors import did_you_mean
from ..scenario.document import (Scalar, VarRef, experiment_values, override_experiment, parse_ref,
                        read_yaml)
from ..values import is_finite, name_problem, scalar_problem, show, unknown_keys

_TOP_KEYS = ("name", "description", "scenario", "experiment", "grid", "random")
MAX_RUNS = 100_000              # grid points x samples; more is likely a typo (--max-runs)
DISTRIBUTIONS = {"normal": "[mean, sd] with sd >= 0", "uniform": "[low, high] with low <= high",
                 # whole numbers low <= n < high, for an Integer parameter (a noise seed per run)
                 "integers": "[low, high] whole numbers with low < high"}


@dataclass(frozen=True)
class Sweep:
    path: Path
    name: str
    scenario_path: Path
    experiment: dict[str, Any]
    grid: tuple[tuple[VarRef, tuple[Scalar, ...]], ...]
    samples: int                    # 0: no random part
    seed: int
    random: tuple[tuple[VarRef, str, tuple[float, float]], ...]
    # (follower, leader): a grid key naming several parameters, "m1.kp, m2.kp": one value
    # list, every one set to the leader's (the first's) value in each run
    linked: tuple[tuple[VarRef, VarRef], ...] = ()

    @property
    def varied(self) -> list[VarRef]:
        return ([ref for ref, _ in self.grid] + [f for f, _ in self.linked]
                + [ref for ref, _, _ in self.random])


@dataclass(frozen=True)
class Run:
    index: int
    values: dict[VarRef, Scalar]
    problem: str | None = None      # a draw the scenario's rules refuse: a failed row


def prepare_sweep(path: str | Path, load_graph: Callable[[Path], Graph],
                  max_runs: int = MAX_RUNS) -> tuple[Sweep, Graph,
                                                                                  list[Run]]:
    """The sweep file, its scenario's graph (load_graph(scenario path)) and the planned runs.
    Every problem is reported at once: those of the file's own structure together with those
    of its scenario and of every parameter name it varies (even one with a bad distribution).
    Raises ScenarioError."""
    sweep, problems, named = read_sweep(path, max_runs)
    graph = None
    if sweep.scenario_path == sweep.path.parent:      # no scenario given: reported already
        pass
    elif not sweep.scenario_path.is_file():
        problems.append(Problem(str(sweep.path), "scenario", f"{sweep.scenario_path} not found; "
                                "give the scenario path relative to the sweep file"))
    else:
        try:
            graph = apply_experiment(sweep, load_graph(sweep.scenario_path))
        except ScenarioError as err:
            problems += [p for p in err.problems if p not in problems]
    if graph is not None:
        problems += [p for p in parameter_problems(sweep, graph, named) if p not in problems]
    if problems or graph is None:
        raise ScenarioError(problems)
    return sweep, graph, plan_runs(sweep, graph)


def read_sweep(path: str | Path, max_runs: int = MAX_RUNS
               ) -> tuple[Sweep, list[Problem], list[tuple[str, VarRef]]]:
    """The sweep with its valid parts, every problem of the file's own structure, and every
    (place, parameter) it names."""
    path = Path(path)
    label = str(path)
    problems: list[Problem] = []

    def bad(place: str, message: str) -> None:
        problems.append(Problem(label, place, message))

    raw = read_yaml(path, label)
    if not isinstance(raw, dict):
        raise ScenarioError([Problem(label, "file", "a sweep file is a mapping with keys "
                                     + ", ".join(_TOP_KEYS))])
    unknown_keys(raw, _TOP_KEYS, "top level", bad)
    name = raw.get("name", path.stem)
    if (problem := name_problem(name)) is not None:      # the scenario's rule
        bad("name", problem)
    scenario = raw.get("scenario")
    if not isinstance(scenario, str) or not scenario:
        bad("scenario", "missing: the scenario file to sweep, relative to this file")
        scenario = ""
    experiment, _ = experiment_values(raw.get("experiment"), bad)
    named: list[tuple[str, VarRef]] = []
    grid, linked = _grid(raw.get("grid"), bad, named)
    samples, seed, random = _random(raw.get("random"), bad, named)
    if raw.get("grid") is None and raw.get("random") is None:
        bad("grid", "nothing to sweep: give a `grid:` of value lists and/or `random:` draws")
    seen = ([str(ref) for ref, _ in grid] + [str(ref) for ref, _ in linked]
            + [str(ref) for ref, _, _ in random])
    for dup in sorted({r for r in seen if seen.count(r) > 1}):
        bad(f"random.{dup}", f"'{dup}' is varied in both grid and random; vary it in one")
    total = math.prod(len(v) for _, v in grid) * max(samples, 1)
    if total > max_runs:
        bad("grid" if grid else "random.samples", f"{total:,} runs (grid points x samples) "
            f"is more than the limit of {max_runs:,} (each run is a row held in memory); "
            f"split the study, or give --max-runs {total} to run them all")
    sweep = Sweep(path, name if isinstance(name, str) else path.stem, path.parent / scenario,
                  experiment, grid, samples, seed, random, linked)
    return sweep, problems, named


def _ref(key, place: str, bad) -> VarRef | None:
    ref = parse_ref(key)
    if ref is None:
        bad(place, f"expected `instance.parameter`, got {show(key)}")
    return ref


def _grid(raw, bad, named: list) -> tuple[tuple, tuple]:
    """(the grid's (leader, values), the (follower, leader) pairs of keys naming several)."""
    if raw is None:
        return (), ()
    if not isinstance(raw, dict) or not raw:
        bad("grid", "empty: give at least one `instance.parameter: [values...]`, or leave "
                    "`grid:` out")
        return (), ()
    grid, linked = [], []
    for key, values in raw.items():
        place = f"grid.{key}"
        refs = [_ref(part.strip(), place, bad) for part in str(key).split(",")]
        named += [(place, r) for r in refs if r is not None]
        ref = refs[0] if all(refs) else None
        linked += [(r, ref) for r in refs[1:] if ref is not None]
        if not isinstance(values, list) or not values:
            bad(place, f"expected a non-empty list of values, got {show(values)}")
        elif (problem := next(filter(None, map(scalar_problem, values)), None)) is not None:
            bad(place, f"every value must be a finite number, true/false or text: {problem}")
        elif ref is not None:
            grid.append((ref, tuple(values)))
    return tuple(grid), tuple(linked)


def _random(raw, bad, named: list) -> tuple[int, int, tuple]:
    if raw is None:
        return 0, 0, ()
    if not isinstance(raw, dict):
        bad("random", f"expected a mapping with samples, seed and draws, got {show(raw)}")
        return 0, 0, ()
    samples, seed = raw.get("samples"), raw.get("seed", 0)
    if not isinstance(samples, int) or isinstance(samples, bool) or samples <= 0:
        bad("random.samples", f"expected a whole number > 0, got {show(samples)}")
        samples = 0
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        bad("random.seed", f"expected a whole number >= 0, got {show(seed)}")
        seed = 0
    draws = []
    for key, spec in raw.items():
        if key in ("samples", "seed"):
            continue
        place = f"random.{key}"
        ref = _ref(key, place, bad)
        if ref is not None:
            named.append((place, ref))
        kind, args = _distribution(spec, place, bad)
        if ref is not None and kind is not None:
            draws.append((ref, kind, args))
    if not draws:
        bad("random", "no parameter to draw: add `instance.parameter: {normal: [mean, sd]}`")
    return samples, seed, tuple(draws)


def _distribution(spec, place: str, bad):
    usage = "; ".join(f"{{{k}: {v}}}" for k, v in DISTRIBUTIONS.items())
    if not isinstance(spec, dict) or len(spec) != 1:
        bad(place, f"expected one distribution ({usage}), got {show(spec)}")
        return None, ()
    (kind, args), = spec.items()
    if kind not in DISTRIBUTIONS:
        bad(place, f"unknown distribution {show(kind)}{did_you_mean(str(kind), DISTRIBUTIONS)} "
                   f"(use {usage})")
        return None, ()
    if not (isinstance(args, list) and len(args) == 2 and all(is_finite(a) for a in args)):
        bad(f"{place}.{kind}", f"expected {DISTRIBUTIONS[kind]}, got {show(args)}")
        return None, ()
    if kind == "integers":
        if not all(float(v).is_integer() for v in args) or not args[0] < args[1]:
            bad(f"{place}.{kind}", f"expected {DISTRIBUTIONS[kind]}, got {show(args)}")
            return None, ()
        return kind, (int(args[0]), int(args[1]))
    a, b = float(args[0]), float(args[1])
    if (kind == "normal" and b < 0) or (kind == "uniform" and b < a):
        bad(f"{place}.{kind}", f"expected {DISTRIBUTIONS[kind]}, got {show(args)}")
        return None, ()
    return kind, (a, b)


def apply_experiment(sweep: Sweep, graph: Graph) -> Graph:
    """The graph with the sweep's experiment overrides, checked like a scenario's."""
    if not sweep.experiment:
        return graph
    scenario = override_experiment(graph.scenario, sweep.experiment, str(sweep.path))
    try:
        return with_scenario(graph, scenario)     # MecanumDynamics' h_ref follows the step
    except ScenarioError as err:        # a master the graph cannot run: the sweep's choice
        raise ScenarioError([Problem(str(sweep.path), "experiment", p.message)
                             for p in err.problems]) from None


def plan_runs(sweep: Sweep, graph: Graph) -> list[Run]:
    """Check every varied parameter against the graph, then list the runs in index order."""
    _check_parameters(sweep, graph)
    _check_profile_grid(sweep, graph)
    points = list(itertools.product(*(values for _, values in sweep.grid)))
    refs = [ref for ref, _ in sweep.grid]
    _check_grid_points(sweep, graph, refs, points)
    rng = np.random.default_rng(sweep.seed)
    draws = [(ref, getattr(rng, kind)(a, b, sweep.samples).tolist())
             for ref, kind, (a, b) in sweep.random]
    runs = []
    for point in points:
        for s in range(sweep.samples or 1):
            values = dict(zip(refs, point))
            values.update({follower: values[leader] for follower, leader in sweep.linked})
            values.update({ref: column[s] for ref, column in draws})
            problem = None
            if draws:
                problem = "; ".join(f"{ref}: {m}" for ref, m in _problems(graph, values)) or None
            runs.append(Run(len(runs), values, problem))
    return runs


def parameter_problems(sweep: Sweep, graph: Graph,
                       named: list[tuple[str, VarRef]] | None = None) -> list[Problem]:
    """A Problem for each varied parameter (or each one named, valid or not) the graph has not
    got, or cannot set, or (random draws) that is not Real."""
    problems = []
    names = [i.name for i in graph.instances]
    drawn = {str(ref): kind for ref, kind, _ in sweep.random}
    if named is None:
        named = [(f"grid.{ref}", ref) for ref, _ in sweep.grid] + [
            (f"random.{ref}", ref) for ref, _, _ in sweep.random]
    for place, ref in named:
        if ref.instance not in names:
            problems.append((place, f"unknown instance '{ref.instance}'"
                                    f"{did_you_mean(ref.instance, names)}"))
            continue
        inst = graph.instance(ref.instance)
        settable = settable_parameters(inst)
        var = next((v for v in inst.model.modelVariables if v.name == ref.variable), None)
        if var is None:
            problems.append((place, f"{inst.model_name} instance '{ref.instance}' has no "
                             f"parameter '{ref.variable}'{did_you_mean(ref.variable, settable)}"))
        elif ref.variable not in settable:
            problems.append((place, f"'{ref.variable}' is {var.causality} ({var.variability}) "
                                    f"and cannot be set; settable: {', '.join(settable)}"))
        elif place.startswith("random.") and str(ref) in drawn and var.type != (
                "Integer" if drawn[str(ref)] == "integers" else "Real"):
            problems.append((place, f"'{ref}' is {var.type}; random draws are real numbers, "
                                    "`integers` draws whole numbers for an Integer parameter "
                                    "(else sweep it with `grid:`)"))
    return [Problem(str(sweep.path), place, message) for place, message in problems]


def _check_parameters(sweep: Sweep, graph: Graph) -> None:
    problems = parameter_problems(sweep, graph)
    if problems:
        raise ScenarioError(problems)


def _check_profile_grid(sweep: Sweep, graph: Graph) -> None:
    """A VelocitySource's or PathFollower's `table` and `interpolation` are text its FMU takes as they are:
    the scenario loader reads a table's file into CSV text, which a grid value would skip
    (every run would fail), and an interpolation must be one the FMU knows."""
    problems = []
    for ref, values in sweep.grid:
        if graph.instance(ref.instance).model_name not in PROFILE_KEYS:   # takes a table
            continue
        if ref.variable == "table":
            problems.append(Problem(str(sweep.path), f"grid.{ref}", "a table is read from its "
                            "file when the scenario is loaded, not per run; sweep one scenario "
                            "per table (or vary the expressions, e.g. source.vx_expr)"))
        elif ref.variable == "interpolation" and (
                unknown := [v for v in values if v not in INTERPOLATIONS]):
            problems.append(Problem(str(sweep.path), f"grid.{ref}", f"{show(unknown[0])} is "
                            f"unknown; use {' or '.join(INTERPOLATIONS)}"))
    if problems:
        raise ScenarioError(problems)


def _check_grid_points(sweep: Sweep, graph: Graph, refs, points) -> None:
    problems: dict[tuple[str, str], Problem] = {}
    for point in points:
        for ref, message in _problems(graph, dict(zip(refs, point))):
            place = f"grid.{ref}" if ref in refs else f"grid (with {ref})"
            problems.setdefault((place, message), Problem(str(sweep.path), place, message))
    if problems:
        raise ScenarioError(list(problems.values()))


def _problems(graph: Graph, values: dict[VarRef, Scalar]) -> list[tuple[VarRef, str]]:
    """(parameter, message) for each of the scenario's rules these values break."""
    by_instance: dict[str, dict[str, Scalar]] = {}
    for ref, value in values.items():
        by_instance.setdefault(ref.instance, {})[ref.variable] = value
    return [(VarRef(name, key), message) for name, vals in by_instance.items()
            for key, message in check_start_values(graph, name, vals)]
