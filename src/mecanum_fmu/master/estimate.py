"""The coupling error of a run, estimated by Richardson extrapolation between step sizes.

The same graph is stepped again by the same master at 2h and 4h (0.75x the run's doStep
calls). On the times the three runs share, d1 = y_h - y_2h and d2 = y_2h - y_4h. The observed
order p = log2(max|d2| / max|d1|), bounded to [1, the master's order], gives the error of the
run itself, e_h ~ d1 / (2^p - 1), at every multiple of 2h; at the end, where the leading
term may cancel (a path that closes on itself), the end values' own observed order is taken
where it is higher, up to the order + 1 (docs/masters.md,
"The error estimate"). A difference that is within the round-off of the outputs is reported
as "below round-off", never as a made-up number; where the coarser runs cannot be made
(fewer than four steps, a coarser run that fails) the estimate says why and gives no number.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import SimulationError
from ..graph import Graph
from ..masters import DEFAULT_TOLERANCE, entry as master_entry
from ..models.catalog import bundled_model
from ..results import BELOW_ROUND_OFF, Results

METHOD = ("Richardson extrapolation: the run repeated at 2h and 4h, e ~ (y_h - y_2h)/(2^p - 1) "
          "with the observed order p bounded to [1, {order}]")
ADAPTIVE_METHOD = ("the adaptive master's per-step errors (the cubic hold's next term from the "
                   "twist, the frame's turning, the heading's lever arm), summed")
_END = np.iinfo(np.int64).max
_ROUND_OFF = 8 * np.finfo(float).eps    # per step, relative to the output's size


def pose_outputs(graph: Graph, results: Results) -> list[str]:
    """The recorded x, y, theta of every PoseIntegrator: what the estimate covers."""
    names = []
    for inst in graph.instances:
        model = bundled_model(inst.model)
        if model is not None and model.role == "pose":
            names += [n for n in (f"{inst.name}.{k}" for k in ("x", "y", "theta"))
                      if n in results.names]
    return names


def error_estimate(graph: Graph, results: Results, simulate) -> dict:
    """summary.json's `error_estimate` (per pose output {"max", "end"}, in its unit, or None)
    and `error_estimate_method` (how it was made, or why there is none). `simulate` is
    master.simulate (passed in: this module sits below it)."""
    names = pose_outputs(graph, results)
    exp = graph.scenario.experiment
    if not names or not results.complete:
        return {}
    if results.steps_taken is not None:         # the adaptive master: its own estimate
        return {"error_estimate": results.extra["error_estimate"],
                "error_estimate_method": ADAPTIVE_METHOD,
                "tolerance": exp.tolerance or DEFAULT_TOLERANCE,
                "steps_taken": results.steps_taken, "steps_rejected": results.steps_rejected}
    if (exp.stop_time - exp.start_time) < 4 * exp.step_size * (1 - 1e-9):
        return _none("the run has fewer than 4 steps: no coarser runs to compare with")
    coarse = []
    for factor in (2, 4):
        try:
            coarse.append(_coarse_run(graph, dataclasses.replace(
                exp, step_size=factor * exp.step_size), names, simulate))
        except SimulationError as err:
            return _none(f"the same run at {factor}x the step failed ({err})")
    order = master_entry(exp.master).order
    fine = (results.time, {n: np.asarray(results[n], dtype=float) for n in names})
    estimate = {n: _richardson(exp, results.steps, fine, coarse[0][1:], coarse[1][1:], n, order)
                for n in names}
    cost = sum(c[0] for c in coarse) / max(results.wall_time, 1e-12)
    return {"error_estimate": estimate, "error_estimate_method": METHOD.format(order=order),
            "error_estimate_cost": round(cost, 3)}


def _none(reason: str) -> dict:
    return {"error_estimate": None, "error_estimate_method": f"no estimate: {reason}"}


def _coarse_run(graph: Graph, exp, names: list[str], simulate) -> tuple:
    """(stepping seconds, times, {name: values}) of the run at exp's step: only the pose
    columns are kept (a sink), so that a long run costs little memory."""
    parts: list[np.ndarray] = []
    results = simulate(graph, exp, sink=lambda chunk: parts.append(chunk[["time"] + names]),
                       keep_rows=2)
    rows = np.concatenate(parts)
    return results.wall_time, rows["time"], {n: np.asarray(rows[n], dtype=float) for n in names}


def _keys(exp, times: np.ndarray, every: float) -> np.ndarray:
    """A key per row: its index on the grid of step `every`, -1 off the grid; the end (stop
    time, common to every run) gets the largest key."""
    k = (times - exp.start_time) / every
    keys = np.where(np.abs(k - np.round(k)) < 1e-6, np.round(k), -1).astype(np.int64)
    keys[-1] = _END
    return keys


def _common(exp, every: float, *runs: tuple) -> list[np.ndarray]:
    """The values of each (times, values) run on the times they all share, in time order."""
    keys = [_keys(exp, t, every) for t, _ in runs]
    shared = keys[0][keys[0] >= 0]
    for k in keys[1:]:
        shared = np.intersect1d(shared, k[k >= 0])
    return [v[np.isin(k, shared)] for (_, v), k in zip(runs, keys)]


def _richardson(exp, steps: int, fine: tuple, mid: tuple, coarse: tuple, name: str,
                order: int) -> dict:
    h = exp.step_size
    pick = lambda run: (run[0], run[1][name])      # noqa: E731
    f2, m2 = _common(exp, 2 * h, pick(fine), pick(mid))
    f4, m4, c4 = _common(exp, 4 * h, pick(fine), pick(mid), pick(coarse))
    d1, d1_4, d2 = f2 - m2, f4 - m4, m4 - c4
    scale = max(1.0, float(np.max(np.abs(f2))))
    floor = _ROUND_OFF * scale * max(steps, 1)
    if np.max(np.abs(d1)) <= floor:
        return {"max": BELOW_ROUND_OFF, "end": BELOW_ROUND_OFF}
    p = _order(np.max(np.abs(d2)), np.max(np.abs(d1_4)), floor, order)
    # at the end the leading term may cancel (a path that closes): its own order where higher
    p_end = max(p, _order(abs(d2[-1]), abs(d1_4[-1]), floor, order + 1))
    end = abs(float(d1[-1])) / (2.0 ** p_end - 1.0)
    return {"max": float(np.max(np.abs(d1))) / (2.0 ** p - 1.0),
            "end": end if end > floor else BELOW_ROUND_OFF}


def _order(coarse: float, fine: float, floor: float, highest: int) -> float:
    """The observed order log2(coarse/fine), bounded to [1, highest]."""
    ratio = coarse / max(fine, floor)
    return min(max(math.log2(ratio), 1.0), float(highest)) if ratio > 0 else 1.0

