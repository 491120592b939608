"""When the hardware, not the step, was the limit: the motors' clamps and the wheels' slip.

Read from the recorded outputs of each DCMotor (V against +-V_supply, the current against
i_max) and each MecanumDynamics (slip1..slip4 against its regularisation speed eps): the
report names every motor that saturated and every contact that slid, as it names a
Center2Wheel's w_max (docs/robot.md, What the report says).
"""
from __future__ import annotations

import numpy as np

AT_LIMIT = 1.0 - 1e-6       # |V| >= V_supply * AT_LIMIT counts as at the clamp
SLIDING = 3.0               # |slip| >= SLIDING eps: tanh >= 0.995, the contact slides


def _span(time: np.ndarray, mask: np.ndarray) -> dict | None:
    if not mask.any():
        return None
    at = time[mask]
    dt = np.diff(time, append=time[-1])
    return {"from": float(at[0]), "to": float(at[-1]), "seconds": float(dt[mask].sum())}


def _motor(graph, results, name: str, time: np.ndarray) -> dict:
    inst = graph.instance(name)
    V_supply, i_max = float(inst.value("V_supply")), float(inst.value("i_max"))
    out = {"V_supply": V_supply, "i_max": i_max}
    if f"{name}.V" in results.names:
        out["voltage_clamp"] = _span(time, np.abs(results[f"{name}.V"]) >= V_supply * AT_LIMIT)
    if f"{name}.i" in results.names:
        out["current_limit"] = _span(time, np.abs(results[f"{name}.i"]) >= i_max * AT_LIMIT)
    return out


def _slips(graph, results, name: str, time: np.ndarray) -> dict:
    out = {}
    for k in range(1, 5):
        col = f"{name}.slip{k}"
        if col in results.names:
            slip = np.abs(np.asarray(results[col]))
            eps = np.asarray(results[f"{name}.eps"]) if f"{name}.eps" in results.names \
                else float(graph.instance(name).value("eps_min") or 1e-3)
            out[f"slip{k}"] = {"peak": float(slip.max()),
                               "sliding": _span(time, slip >= SLIDING * eps)}
    return out


def drive_train_limits(graph, results) -> dict | None:
    """{"motors": {name: limits}, "contacts": {name: slips}}, or None without a drive train."""
    models = {i.name: i.model_name for i in graph.instances}
    motors = [n for n, m in models.items() if m == "DCMotor"]
    bodies = [n for n, m in models.items() if m == "MecanumDynamics"]
    if not (motors or bodies) or not len(results.time):
        return None
    time = np.asarray(results.time)
    return {"motors": {n: _motor(graph, results, n, time) for n in motors},
            "contacts": {n: _slips(graph, results, n, time) for n in bodies}}


def limit_lines(limits: dict) -> list[str]:
    """Which reference judged the run, then one line per motor that hit a clamp and per body
    whose contacts slid."""
    lines = ["drive train: no closed form; the ground truth is the kinematic path (what the "
             "motors and the floor fall short of) and the error estimate judges the step"]
    for name, m in limits["motors"].items():
        for key, what in (("voltage_clamp", f"|V| at V_supply = {m['V_supply']:g} V"),
                          ("current_limit", f"|i| at i_max = {m['i_max']:g} A")):
            if (s := m.get(key)) is not None:
                lines.append(f"{name}: {what} for {s['seconds']:.3g} s (t = {s['from']:g} "
                             f"to {s['to']:g} s): the motor, not the step, is the limit")
    for name, contacts in limits["contacts"].items():
        slid = {k: c for k, c in contacts.items() if c["sliding"] is not None}
        peaks = ", ".join(f"{k} {c['peak']:.3g}" for k, c in contacts.items())
        lines.append(f"{name}: peak slip [m/s] {peaks}"
                     + (f"; sliding (|slip| >= {SLIDING:g} eps) on {', '.join(slid)}"
                        if slid else "; no contact slid"))
    return lines
