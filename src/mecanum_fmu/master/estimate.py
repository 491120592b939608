"""The coupling error of a run: which estimate it gets, and summary.json's words for it.

A fixed-step master's run gets the embedded pair (pair.py, pair_rows.py: from the run's own
rows, no extra doStep but the probes of the FMUs it measures, probe.py), or Richardson's
coarser runs (richardson.py) where the pair does not apply (the method says why) or by name;
the adaptive master's run its own (adaptive.py, trajectory.py); `estimate: none` none.
docs/masters.md, "The error estimate on every run".
"""
from __future__ import annotations

import dataclasses
import time
from fractions import Fraction

import numpy as np

from ..errors import SimulationError
from ..scenario.graph import Graph
from ..masters import DEFAULT_RELATIVE_TOLERANCE, DEFAULT_TOLERANCE, entry as master_entry
from ..results import BELOW_ROUND_OFF, Results, round_off
from .breakpoints import graph_breaks
from .pair import LOOP_METHOD, METHOD as PAIR_METHOD, pair_plan
from .pair_parts import PairPlan
from .pair_rows import PairRows
from .memory import held_at_end_advice, hidden_advice, undeclared
from .richardson import (FINER, ROUGH, coarse_experiment, coarse_factors, coarse_run,
                         richardson, room_for_coarser)

ADAPTIVE_METHOD = ("the adaptive master's: per recorded output the difference, over 3, of "
                   "the run and the same run stepped whole on its accepted steps (each step "
                   "of the run is the embedded pair's two halves), where an FMU has an error "
                   "model its own (a PoseIntegrator's: the hold's next term, the frame's "
                   "turning, the heading's lever arm, the error of the twist it is fed)")

# where the adaptive master found an FMU's response flat (adaptive._Loop._bent)
FLAT = ("; from t = {:.6g} s, where an FMU's response went flat while its input moved (a "
        "saturation inside it), each step also taken with the held inputs at their mean less "
        "and plus half their change, and a bend of the response inside the step counted "
        "(docs/masters.md, \"A kink inside an FMU's own equations\")")


def recorded_outputs(graph: Graph, results: Results) -> list[str]:
    """Every recorded Real output (the scenario's `outputs:`, by default every output of
    every FMU): what the estimate covers, for any FMUs."""
    return [str(p.ref) for p in graph.recorded if p.type == "Real" and str(p.ref) in
            results.names]


TURNED_OFF = "turned off (estimate: none; --estimate auto or richardson gives one)"


def coarse_plan(graph: Graph, exp, marks: np.ndarray | None = None, rough: bool = False
                ) -> tuple[Fraction, Fraction] | str | None:
    """The coarser steps the estimate steps (coarse_factors), or why it steps none (the
    reason its method gives), or None where a coarser run has nothing to do: the adaptive
    master (its own estimate) or no recorded Real output. master.simulate steps the factors
    on the run's own instances; error_estimate words the reason. `rough`: the pair found
    held inputs or a measured response that jump or bend at times the master does not know
    (PairRows.finish): the runs at h/2 and h/3 (richardson.ROUGH)."""
    why = _no_coarser(graph, exp)
    if why is not _SOME:
        return why
    if graph.sampled:       # (Richardson by name)
        return (FINER,)
    return ROUGH if rough else coarse_factors(graph, exp, marks)


def steps_coarser(graph: Graph, exp) -> bool:
    """Whether coarse_plan gives coarser steps, without working out which (master._start:
    the run keeps its t0 for them; which, it asks only where they are stepped)."""
    return _no_coarser(graph, exp) is _SOME


_SOME = object()    # _no_coarser: the estimate may step coarser runs


def _no_coarser(graph: Graph, exp) -> str | None | object:
    """Where the estimate steps no coarser run, coarse_plan's answer (its reason, or None:
    nothing to do); else _SOME."""
    if exp.estimate == "none":
        return TURNED_OFF
    if not _fixed_with_reals(graph, exp):
        return None
    if graph.sampled and exp.estimate == "richardson":
        return _SOME
    if graph.sampled:
        return (f"{', '.join(graph.sampled)} sample at their own period: a coarser step moves "
                "their samples (a different model, not a coarser run of this one); a run at "
                "half the step keeps them, and how far it moves the outputs is the step's "
                "share (docs/robot.md, \"The step's share\"; --estimate richardson makes "
                "that run, at twice the run's cost)")
    return _SOME if room_for_coarser(exp) else FEW_STEPS


FEW_STEPS = "the run has fewer than 4 steps: no coarser runs to compare with"
LATE_END = ("unresolved (under Jacobi the last steps' true inputs lie past the run's values; "
            "extrapolated by the cubic and by the parabola, they disagree)")
TABLES = ("; a table's rows being closer than two steps, each held input's true mean is the "
          "table's own, through the linear map from the tables to it fitted on the run's rows")
LONE_PIECES = ("a table jumps at every step, and a held input may move between the jumps (a "
               "loop, an FMU with a state): its one value between two jumps does not tell how")


def _fixed_with_reals(graph: Graph, exp) -> bool:
    """A fixed-step master and some recorded Real output: a run that gets a pair or coarser
    runs (the adaptive master estimates its own; without a Real output there is nothing)."""
    return not master_entry(exp.master).adaptive and any(p.type == "Real"
                                                         for p in graph.recorded)


def wants_pair(graph: Graph, exp) -> bool:
    """Whether the run may get the pair: the estimate auto, a fixed-step master and some
    recorded Real output."""
    return exp.estimate == "auto" and _fixed_with_reals(graph, exp)


def pair_tap(graph: Graph, exp, real_slots: dict, n_steps: int, rolled_back: bool,
             memoryless: frozenset = frozenset()) -> PairRows | str | None:
    """The recorder's tap of the pair for this run (pair_rows.py), or why the pair does not
    apply (Richardson then estimates), or None where the run gets no pair: an estimate other
    than auto, the adaptive master, no recorded Real output. `rolled_back`: the run predicts,
    rolls back and corrects each step (master._rolls_back_loops); `memoryless`: pair_plan's."""
    if not wants_pair(graph, exp):
        return None
    plan = pair_plan(graph, real_slots, rolled_back, memoryless)
    if not isinstance(plan, PairPlan):
        return plan
    if n_steps < 4:
        return FEW_STEPS
    rows = PairRows(plan, exp, n_steps, graph_breaks(graph), graph.known)
    return LONE_PIECES if rows.held_move and rows.pieces.lone and rows.known is None else rows


def error_estimate(graph: Graph, results: Results, simulate) -> dict:
    """summary.json's `error_estimate` (per recorded Real output {"max", "end"}, in its unit,
    or None) and `error_estimate_method` (how it was made, or why there is none): the pair's
    where it applies (results.extra["pair"], or the run made again), else Richardson's. The
    coarser runs
    are those master.simulate stepped after the run (results.extra["coarse"], by factor),
    else made here with `simulate` (master.simulate, passed in: this module sits below it)."""
    names = recorded_outputs(graph, results)
    exp = graph.scenario.experiment
    if exp.estimate == "none":
        return _none(TURNED_OFF)
    if not names or not results.complete:
        return {}
    if results.steps_taken is not None:         # the adaptive master: its own estimate
        return _adaptive_estimate(results, exp)
    if ended := results.extra.get("ended"):
        return _to_its_end(graph, results, ended, simulate)
    pair, stepped = results.extra.get("pair", {}), results.extra.get("coarse", {})
    if pair.get("graph") is graph:
        pair = pair.get("found")
    else:
        pair, stepped = _pair_afresh(graph, results, simulate)
    found = _pair_estimate(graph, results, names, pair) \
        if isinstance(pair, dict) and pair["failed"] is None else \
        _coarse_estimate(graph, results, names, pair, stepped, simulate)
    if isinstance(pair, dict) and pair.get("advice"):   # memory.advice: the run's holds
        found["error_estimate_advice"] = pair["advice"]
    return found


def _adaptive_estimate(results: Results, exp) -> dict:
    """error_estimate's for the adaptive master: its own estimate (adaptive.estimate_of), its
    tolerances and steps, and advice: where it held inputs at their end values, and where
    the estimate exceeds the tolerance (_over_tolerance)."""
    tol = exp.tolerance or DEFAULT_TOLERANCE
    rtol = DEFAULT_RELATIVE_TOLERANCE if exp.relative_tolerance is None \
        else exp.relative_tolerance
    estimate = results.extra["error_estimate"]
    advice = held_at_end_advice(results.extra.get("held_at_end", {})) + \
        hidden_advice(results.extra.get("hidden_state", ())) + \
        _over_tolerance(results, estimate, tol, rtol)
    flat = results.extra.get("flat_at")
    method = ADAPTIVE_METHOD + ("" if flat is None else FLAT.format(flat))
    return {"error_estimate": estimate, "error_estimate_method": method,
            "tolerance": tol, "relative_tolerance": rtol,
            "steps_taken": results.steps_taken, "steps_rejected": results.steps_rejected,
            **({"error_estimate_advice": advice} if advice else {})}


def _over_tolerance(results: Results, estimate: dict, tol: float, rtol: float) -> list[str]:
    """The words for the outputs whose estimated largest error exceeds the tolerance (tol +
    rtol x the output's largest |value|), with the tolerance that would about meet it. The
    step control holds the signed sum of the steps' own errors under the tolerance; errors
    that the FMUs' dynamics carry on and grow (a lightly damped loop: a spring under a P
    controller, 2.7x at 1e-4) it does not see, the estimate does."""
    over = {}
    for name, found in estimate.items():
        worst = found.get("max")
        if isinstance(worst, float):
            allowed = tol + rtol * float(np.max(np.abs(results[name]), initial=0.0))
            if worst > allowed:
                over[name] = worst / allowed
    if not over:
        return []
    ratio = max(over.values())
    named = ", ".join(f"{name} ({factor:.2g}x)" for name, factor in over.items())
    return [f"the estimated error exceeds the tolerance on {named}: the errors the steps make "
            "grow along the run (the FMUs' dynamics carry them on) beyond the step control's "
            f"share of them; --tolerance {0.8 * tol / ratio:.2g} would about hold them within "
            f"{tol:g}"]


def _coarse_estimate(graph: Graph, results: Results, names: list[str], pair, stepped: dict,
                     simulate) -> dict:
    """Richardson's estimate where the pair does not apply (`pair`: why; `stepped`: the
    coarser runs master.simulate made)."""
    exp = graph.scenario.experiment
    marks = graph_breaks(graph).times()
    rough = isinstance(pair, dict) and pair.get("rough", False)
    factors = coarse_plan(graph, exp, marks, rough)
    if isinstance(factors, str):
        return _none(factors)
    coarse = []
    stepped = stepped.get("runs", {}) if stepped.get("graph") is graph else {}
    for factor in factors:
        run = stepped.get(factor) or coarse_run(graph, coarse_experiment(exp, factor), names,
                                                simulate, results.time)
        if isinstance(run, str):
            return _none(f"the same run at {float(factor)}x the step failed ({run})")
        coarse.append(run)
    found = richardson(graph, results, names, factors, coarse, marks, rough)
    why = pair["failed"] if isinstance(pair, dict) else pair
    if why:
        found["error_estimate_method"] += f" (the embedded pair does not apply: {why})"
    return found


def _to_its_end(graph: Graph, results: Results, ended: dict, simulate) -> dict:
    """The estimate of a run that an FMU ended before its stop time (master._ended): that of
    the same run with its stop time where it ended, made again (its own pair's tap was laid
    out for the whole run); its cost, the run made again included, against the run's."""
    tick = time.perf_counter()
    exp = dataclasses.replace(graph.scenario.experiment, stop_time=ended["time"])
    short = dataclasses.replace(graph, scenario=dataclasses.replace(graph.scenario,
                                                                    experiment=exp))
    found = error_estimate(short, dataclasses.replace(results, stop_time=exp.stop_time,
                                                      extra={}), simulate)
    if found.get("error_estimate") is not None:
        found["error_estimate_method"] += (
            f" (the run to t = {ended['time']:g} s, where {ended['by']} asked to end it, made "
            "again for it)")
        found["error_estimate_cost"] = round((time.perf_counter() - tick) / max(
            results.wall_time, 1e-12), 3)
    return found


def _pair_afresh(graph: Graph, results: Results, simulate) -> tuple:
    """The pair of a run made without it (master.simulate without with_estimate): the run
    made again with it, or why the pair does not apply (None: the run gets none); and where
    the pair fails on it, the coarser runs it stepped (results.extra["coarse"]; kept only
    where `results` holds every row, the rows they keep being those of the run made again)."""
    from .plan import Buffers
    from .recorder import step_count
    exp = graph.scenario.experiment
    n = step_count(exp)
    # (whether the pair applies does not depend on the hold it rebuilds: rolled_back False;
    # it may where the probes before the run find FMUs without a state: memory.py)
    slots, maybe = Buffers(graph, freeze=False).real_slots, undeclared(graph)
    tap = pair_tap(graph, exp, slots, n, False)
    if not isinstance(tap, PairRows) and not (
            maybe and isinstance(pair_tap(graph, exp, slots, n, False, maybe), PairRows)):
        return tap, {}
    every = len(results.time) == n + 1
    try:
        again = simulate(graph, exp, keep_rows=None if every else 2, with_estimate=True)
    except SimulationError as err:
        return f"the run made again for it failed ({err})", {}
    if ended := again.extra.get("ended"):      # an FMU that does not end where it did
        return (f"the run made again for it ended at t = {ended['time']:g} s, where "
                f"{ended['by']} asked"), {}
    return again.extra["pair"]["found"], again.extra.get("coarse", {}) if every else {}


def _pair_estimate(graph: Graph, results: Results, names: list[str], pair: dict) -> dict:
    """summary.json's estimate from the pair (pair_rows.PairRows.finish)."""
    estimate = {}
    for name in names:
        worst, end, other = pair["estimate"].get(name, (0.0, 0.0, 0.0))
        floor = round_off(np.asarray(results[name], dtype=float), results.steps)
        end = BELOW_ROUND_OFF if max(end, other) <= floor else \
            LATE_END if abs(other - end) > 0.5 * end else end
        estimate[name] = {"max": worst if worst > floor else BELOW_ROUND_OFF, "end": end}
        if name in pair.get("unresolved_end", {}):
            estimate[name]["end"] = pair["unresolved_end"][name]
        if name in pair.get("unresolved", {}):
            estimate[name] = dict.fromkeys(("max", "end"), pair["unresolved"][name])
    models = ", ".join(pair["models"]) or "none here"
    through = pair.get("through", [])
    return {"error_estimate": estimate,
            "error_estimate_method": PAIR_METHOD.format(
                steps=f"no extra doStep but the probes' {pair['probe_calls']}"
                if pair.get("probe_calls") else "no extra doStep",
                models=models, loop=LOOP_METHOD.format(through=", ".join(through)) if through
                else "", other="the other " if through else "",
                lag=" (under Jacobi, a step late per FMU with direct feedthrough)"
                if pair["lagged"] else "") + (TABLES if pair.get("tables") else ""),
            "error_estimate_cost": round(pair["seconds"] / max(
                results.wall_time - pair.get("probe_seconds", 0.0), 1e-12), 3)}


def _none(reason: str) -> dict:
    return {"error_estimate": None, "error_estimate_method": f"no estimate: {reason}"}
