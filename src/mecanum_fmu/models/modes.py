"""The basic motions of a mecanum chassis and their wheel-sign patterns (table 2-1 of the
mecanum platform analysis, "Motion Model and Application Analysis of the Mecanum-Wheel
Omnidirectional Mobile Robot"; docs/spec.md, Basic motions).

A wheel-sign pattern is the sign of each wheel speed w1..w4 that the inverse kinematics
(docs/spec.md, Inverse kinematics) gives for a twist: it is meaningful only while the twist
is constant.

    python -m mecanum_fmu.models.modes        # print the markdown table of docs/modes.md
    python -m mecanum_fmu.models.modes omni   # the same motions on the omni X-drive
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .blocks.kinematics import DEFAULT_GEOMETRY, center_to_wheel
from .blocks.omni import omni_center_to_wheel
from .catalog import Roles, find_roles

SIGN_TOL = 1e-9               # |wi| below this (times max(1, max |wj|)) counts as 0

# The mecanum platform analysis (docs/spec.md, Basic motions) numbers its motors M1 front-left,
# M2 rear-left, M3 rear-right, M4 front-right:
# Mi = our wheel SEEDS003_WHEEL[i - 1] (ours: 1 front-right, 2 front-left, 3 rear-left, 4 rear-right).
SEEDS003_WHEEL = (2, 3, 4, 1)


@dataclass(frozen=True)
class Mode:
    key: str                  # scenarios/modes/<key>.yaml
    name: str
    vx: float                 # body frame: +X right [m/s]
    vy: float                 # +Y forward [m/s]
    w: float                  # counter-clockwise [rad/s]
    direction: str            # what the car does, in our frame


MODES = (
    Mode("forward", "forward", 0.0, 0.3, 0.0, "moves along +Y"),
    Mode("backward", "backward", 0.0, -0.3, 0.0, "moves along -Y"),
    Mode("left", "sideways left", -0.3, 0.0, 0.0, "moves along -X"),
    Mode("right", "sideways right", 0.3, 0.0, 0.0, "moves along +X"),
    Mode("diagonal", "diagonal forward-left", -0.3, 0.3, 0.0, "moves along (-X, +Y)"),
    Mode("spin_cw", "spin clockwise", 0.0, 0.0, -0.8, "turns in place, theta decreasing"),
    Mode("spin_ccw", "spin counter-clockwise", 0.0, 0.0, 0.8, "turns in place, theta increasing"),
)


def _sign(value: float, tol: float) -> str:
    return "0" if abs(value) <= tol else ("+" if value > 0 else "-")


def wheel_sign_list(vx: float, vy: float, w: float, alpha: float = DEFAULT_GEOMETRY["alpha"],
                    L: float = DEFAULT_GEOMETRY["L"], W: float = DEFAULT_GEOMETRY["W"],
                    R: float = DEFAULT_GEOMETRY["R"], tol: float = SIGN_TOL) -> list[str]:
    """Signs ("+", "-", "0") of w1..w4 for the twist (vx, vy, w), our wheel numbering."""
    speeds = center_to_wheel(vx, vy, w, alpha, L, W, R)
    scale = tol * max(1.0, max(abs(s) for s in speeds))
    return [_sign(s, scale) for s in speeds]


def wheel_signs(vx: float, vy: float, w: float, alpha: float = DEFAULT_GEOMETRY["alpha"],
                L: float = DEFAULT_GEOMETRY["L"], W: float = DEFAULT_GEOMETRY["W"],
                R: float = DEFAULT_GEOMETRY["R"], tol: float = SIGN_TOL) -> str:
    """The wheel-sign pattern of a constant twist, e.g. "w1 -  w2 +  w3 -  w4 +"."""
    signs = wheel_sign_list(vx, vy, w, alpha, L, W, R, tol)
    return "  ".join(f"w{i} {s}" for i, s in enumerate(signs, start=1))


def seeds003_signs(signs: list[str]) -> list[str]:
    """Our w1..w4 signs reordered as the mecanum platform analysis' M1..M4
    (docs/spec.md, Basic motions)."""
    return [signs[wheel - 1] for wheel in SEEDS003_WHEEL]


def geometry_of(start_values: Mapping | None) -> dict[str, float]:
    """alpha, L, W, R from an instance's start values, defaults where not set."""
    values = dict(start_values or {})
    return {k: float(values.get(k, v)) for k, v in DEFAULT_GEOMETRY.items()}


def graph_geometry(graph, roles: Roles | None = None) -> dict[str, float]:
    """alpha, L, W, R of a graph's kinematics instance (inverse first, else forward);
    defaults where not set or where the graph has neither. roles: find_roles(graph)."""
    roles = roles if roles is not None else find_roles(graph)
    name = roles.inverse or roles.forward
    return geometry_of(graph.instance(name).start_values if name else None)


def constant_twist_signs(graph, results, roles: Roles, geometry: Mapping[str, float],
                         tol: float = 1e-12) -> str | None:
    """The wheel-sign pattern of a run whose commanded twist is constant; None otherwise
    (no source, twist not recorded, empty run, or a twist that changes). geometry: alpha,
    L, W, R of its kinematics (graph_geometry)."""
    if roles.source is None or len(results.time) == 0:
        return None
    cols = [f"{roles.source}.{v}" for v in ("vx", "vy", "w")]
    if not all(c in results.names for c in cols):
        return None
    twist = []
    for c in cols:
        values = np.asarray(results[c], dtype=float)
        if not np.all(np.isfinite(values)) or np.ptp(values) > tol * max(1.0, np.max(np.abs(values))):
            return None
        twist.append(float(values[0]))
    if (omni := graph.find_model("OmniCenter2Wheel")) is not None and roles.inverse is None:
        return omni_constant_twist_signs(graph, omni, roles.source, twist)
    try:
        return wheel_signs(*twist, **geometry)
    except (ArithmeticError, ValueError):
        return None


def markdown_table(geometry: Mapping | None = None) -> str:
    """The seven modes: twist, our wheel signs w1..w4 and the mecanum platform analysis' M1..M4."""
    g = geometry_of(geometry)
    head = ("| mode | vx [m/s] | vy [m/s] | w [rad/s] | w1 FR | w2 FL | w3 RL | w4 RR "
            "| M1 FL | M2 RL | M3 RR | M4 FR | the car |")
    rule = "|" + "---|" * 13
    rows = [head, rule]
    for m in MODES:
        ours = wheel_sign_list(m.vx, m.vy, m.w, **g)
        seeds = seeds003_signs(ours)
        rows.append(f"| {m.name} (`scenarios/modes/{m.key}.yaml`) | {m.vx:g} | {m.vy:g} | {m.w:g} | "
                    + " | ".join(ours) + " | " + " | ".join(seeds) + f" | {m.direction} |")
    return "\n".join(rows)


# The omni X-drive ("Kinematics of a four-wheel omni-wheel chassis", docs/chassis.md) in
# that document's numbering: 1 front-left, 2 rear-left, 3 rear-right, 4 front-right; a positive wheel speed
# pushes the chassis counter-clockwise.
OMNI_GEOMETRY = {"L": 0.2, "R": 0.05}


def omni_wheel_sign_list(vx: float, vy: float, w: float, L: float = OMNI_GEOMETRY["L"],
                         R: float = OMNI_GEOMETRY["R"], tol: float = SIGN_TOL) -> list[str]:
    """Signs ("+", "-", "0") of the omni X-drive's w1..w4 for the twist (vx, vy, w)."""
    speeds = omni_center_to_wheel(vx, vy, w, L, R)
    scale = tol * max(1.0, max(abs(s) for s in speeds))
    return [_sign(s, scale) for s in speeds]


def omni_constant_twist_signs(graph, omni, source: str, twist: list[float]) -> str | None:
    """The omni X-drive's pattern when the source's twist drives it directly (not, e.g.,
    through FieldToBody, where the body twist turns with the heading); else None."""
    fed = {(l.target.ref.variable, l.source.ref.instance, l.source.ref.variable)
           for l in graph.links if l.target.ref.instance == omni.name}
    if not all((v, source, v) in fed for v in ("vx", "vy", "w")):
        return None
    g = {k: float(omni.start_values.get(k, v)) for k, v in OMNI_GEOMETRY.items()}
    signs = omni_wheel_sign_list(*twist, **g)
    return "  ".join(f"w{i} {s}" for i, s in enumerate(signs, start=1))


def omni_markdown_table(geometry: Mapping | None = None) -> str:
    """The seven modes on the omni X-drive: twist and wheel signs w1..w4 (its own numbering)."""
    g = {k: float(dict(geometry or {}).get(k, v)) for k, v in OMNI_GEOMETRY.items()}
    rows = ["| mode | vx [m/s] | vy [m/s] | w [rad/s] | w1 FL | w2 RL | w3 RR | w4 FR "
            "| the chassis |", "|" + "---|" * 9]
    for m in MODES:
        signs = omni_wheel_sign_list(m.vx, m.vy, m.w, **g)
        rows.append(f"| {m.name} | {m.vx:g} | {m.vy:g} | {m.w:g} | " + " | ".join(signs)
                    + f" | {m.direction} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> None:
    import sys
    if (sys.argv[1:] if argv is None else argv) == ["omni"]:
        g = OMNI_GEOMETRY
        print(f"<!-- python -m mecanum_fmu.models.modes omni; L = {g['L']:g} m, R = {g['R']:g} m -->")
        print(omni_markdown_table())
        return
    g = DEFAULT_GEOMETRY
    print(f"<!-- python -m mecanum_fmu.models.modes; alpha = {math.degrees(g['alpha']):g} deg, "
          f"L = {g['L']:g} m, W = {g['W']:g} m, R = {g['R']:g} m -->")
    print(markdown_table())


if __name__ == "__main__":
    main()
