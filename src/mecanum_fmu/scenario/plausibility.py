"""Plausibility: values that are valid but probably not what the user meant. Warnings, not
errors (`validate --strict` makes them errors, exit 2); compile_graph adds them to
Graph.warnings.

- Units: a wheel radius, half-track or wheelbase whose size suggests millimetres or
  centimetres (R: 60), a start heading whose size suggests degrees (theta0: 90).
- A table (VelocitySource profile, PathFollower path) that does not cover the run's time span:
  outside it the end rows are held (epoch timestamps hold the first row for the whole run).
- A follower gain that makes the closed loop unstable at the chosen step: on x' = -k x closed
  through the integrator each master is stable for h k below its registry entry's loop limit
  (masters.py, docs/masters.md).
- A sampled block (Encoder, Gyro, Odometry) whose period is not a whole number of steps:
  its samples do not land on communication points (docs/robot.md, Sample times).

Instances are duck-typed (graph.Instance): .name, .model_name, .declared_at, .start_values,
.value(name), .can_get_set_state, .table (tables.Table); this module imports nothing of
graph.py.
"""
from __future__ import annotations

import math

from ..errors import Problem
from ..masters import entry as master_entry
from ..models.catalog import SAMPLED_MODELS
from ..values import is_finite

LENGTHS = {"R": (0.005, 1.0), "L": (0.01, 5.0), "W": (0.01, 5.0), "l": (0.05, 10.0)}
LENGTH_MODELS = ("Center2Wheel", "Wheel2Center", "OmniCenter2Wheel", "OmniWheel2Center",
                 "Bicycle")
ANGLES = {"PoseIntegrator": ("theta0",)}
_SMALLER = (("millimetres", 1e-3), ("centimetres", 1e-2))


def stability_limit(master: str, can_roll_back: bool) -> float | None:
    """The largest stable h k of a loop stepped by `master` (None: none stated): the
    registry's (masters.py), rolled back when the master and every FMU can."""
    how = master_entry(master)
    if how.rolls_back and can_roll_back and how.rolled_back_loop_limit is not None:
        return how.rolled_back_loop_limit
    return how.loop_limit


def problems(scenario, instances) -> list[Problem]:
    """Every plausibility finding of a compiled scenario, as Problems (file, place, message)."""
    found: list[Problem] = []
    for inst in instances:
        for place, message in (_units(scenario, inst) + _table_span(scenario, inst)
                               + _stability(scenario, inst, instances)
                               + _sampling(scenario, inst)):
            problem = Problem(scenario.label, place, message)
            if problem not in found:        # a shared parameter is seen by every taker
                found.append(problem)
    return found


def warnings(scenario, instances) -> list[str]:
    """problems() as the warning lines Graph.warnings holds."""
    return [str(p) for p in problems(scenario, instances)]


def _place(scenario, inst, name: str) -> str:
    own = next((c for c in scenario.components if c.name == inst.name), None)
    if own is not None and name in own.parameters:
        return f"{inst.declared_at}.parameters.{name}"
    return f"parameters.{name}" if name in scenario.parameters else inst.declared_at


def _given(inst, name: str):
    value = inst.start_values.get(name)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return value if math.isfinite(value) else None


def _units(scenario, inst) -> list[tuple[str, str]]:
    out = []
    if inst.model_name in LENGTH_MODELS:
        for name, (low, high) in LENGTHS.items():
            value = _given(inst, name)
            if value is None or value <= high:
                continue
            fits = [f"{unit} (then give metres, {name}: {value * scale:g})"
                    for unit, scale in _SMALLER if low <= value * scale <= high]
            reading = (f"it looks like {' or '.join(fits)}" if fits else
                       f"give it in metres (at most {high:g} m is plausible)")
            out.append((_place(scenario, inst, name),
                        f"{name} = {value:g} m is implausibly large for a "
                        f"{'wheel radius' if name == 'R' else 'chassis length'}; {reading}"))
    for name in ANGLES.get(inst.model_name, ()):
        value = _given(inst, name)
        if value is not None and 2 * math.pi < abs(value) <= 360:
            out.append((_place(scenario, inst, name),
                        f"{name} = {value:g} rad is {abs(value) / (2 * math.pi):.1f} turns; it "
                        f"looks like degrees (then give radians, {name}: {math.radians(value):.6g})"))
    return out


def _table_span(scenario, inst) -> list[tuple[str, str]]:
    if inst.table is None:
        return []
    span = inst.table.span
    exp = scenario.experiment
    if span[0] <= exp.start_time and span[1] >= exp.stop_time:
        return []
    first, last = span
    outside = last <= exp.start_time or first >= exp.stop_time
    held = ("the run sees only its " + ("last" if last <= exp.start_time else "first")
            + " row" if outside else "outside it its end rows are held")
    return [(f"{inst.declared_at}.table", f"the table covers t = {first:.10g} to {last:.10g} s, "
             f"the run {exp.start_time:g} to {exp.stop_time:g} s: {held} (timestamps in "
             "another unit or epoch? use table: {file: ..., units: {time: ms}, start: "
             "first_row} or an offset)")]


def _sampling(scenario, inst) -> list[tuple[str, str]]:
    if inst.model_name not in SAMPLED_MODELS:
        return []
    period, exp = inst.value("period"), scenario.experiment
    if not (is_finite(period) and period > 0) or master_entry(exp.master).adaptive:
        return []           # (the adaptive master is refused: graph.adaptive_samples)
    ratio = period / exp.step_size
    if abs(ratio - round(ratio)) <= 1e-9 * max(1.0, ratio) and round(ratio) >= 1:
        return []
    what = (f"{math.ceil(1 / ratio - 1e-9)} samples fall in one step and only the last is seen"
            if ratio < 1 else "a sample between two steps is taken at its own time but seen "
            "at the next step, up to one step late")
    return [(_place(scenario, inst, "period"),
             f"period = {period:g} s is not a whole number of steps of {exp.step_size:g} s: "
             f"{what}; use a step of period/n (e.g. {period / max(1, math.ceil(ratio)):g} s)")]


def _stability(scenario, inst, instances) -> list[tuple[str, str]]:
    if inst.model_name != "PathFollower":
        return []
    exp = scenario.experiment
    limit = stability_limit(exp.master, all(i.can_get_set_state for i in instances))
    if limit is None:
        return []
    out = []
    for name in ("k_pos", "k_theta"):
        gain = inst.value(name)
        if isinstance(gain, (int, float)) and math.isfinite(gain) and gain * exp.step_size >= limit:
            out.append((_place(scenario, inst, name),
                        f"{name} = {gain:g} 1/s with step {exp.step_size:g} s gives h k = "
                        f"{gain * exp.step_size:.3g}, at or above the stability limit "
                        f"{limit:g} of the {exp.master} master on this loop: the run will "
                        f"diverge; use a step below {limit / gain:.3g} s or a smaller gain"))
    return out
