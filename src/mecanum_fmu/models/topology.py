"""Which blocks drive which pose: the one topology query the evaluation of a run rests on.

A PoseIntegrator integrates the body twist at its inputs. Walking upstream from its `vx` input
past any kinematics pair (inverse then forward kinematics pass a twist through unchanged) ends
at the block that commands that twist: its *origin* (a VelocitySource, FieldToBody, Bicycle,
PathFollower or any other FMU). The roles (catalog.find_roles) name the single instance of each
bundled block, for the plots.
"""
from __future__ import annotations

from dataclasses import dataclass

from .catalog import Roles, find_roles
from .modes import graph_geometry

# blocks a body twist passes through unchanged: model -> the input to follow upstream
PASS_THROUGH = {"Wheel2Center": "w1", "OmniWheel2Center": "w1",
                "Center2Wheel": "vx", "OmniCenter2Wheel": "vx",
                # the drive train (docs/robot.md): the twist the motors and the floor allow
                "MecanumDynamics": "w1", "DCMotor": "w_ref"}
LIMITER = "Center2Wheel"        # the block with a wheel speed limit (w_max)


@dataclass(frozen=True)
class Drive:
    """What drives one pose."""
    pose: str                   # the PoseIntegrator instance
    origin: str | None          # the block whose body twist it integrates (None: unconnected)
    model: str | None           # the origin's model name
    chain: tuple[str, ...]      # the kinematics blocks in between, pose side first
    limiter: str | None         # a Center2Wheel in the chain (its w_max may saturate the wheels)
    w_max: float = 0.0          # the limiter's wheel speed limit [rad/s]; 0: none


@dataclass(frozen=True)
class Topology:
    roles: Roles                # the single instance of each bundled role (the plots' view)
    drives: tuple[Drive, ...]   # one per PoseIntegrator, in the scenario's order
    geometry: dict[str, float]  # alpha, L, W, R of the kinematics (modes.graph_geometry)
    follower_feed: str | None = None    # the instance that drives the follower's x input


def upstream(graph, instance: str, var: str) -> tuple[str, str] | None:
    """(instance, output) that drives instance.var, or None when it is not connected."""
    for link in graph.links:
        if link.target.ref.instance == instance and link.target.ref.variable == var:
            return link.source.ref.instance, link.source.ref.variable
    return None


def drive_of(graph, pose: str) -> Drive:
    """Walk upstream from the pose's twist input past every kinematics block."""
    found, chain = upstream(graph, pose, "vx"), []
    while found is not None and found[0] not in chain:
        model = graph.instance(found[0]).model_name
        if model not in PASS_THROUGH:
            break
        chain.append(found[0])
        found = upstream(graph, found[0], PASS_THROUGH[model])
    origin = found[0] if found is not None and found[0] not in chain else None
    limiter = next((n for n in chain if graph.instance(n).model_name == LIMITER), None)
    w_max = float(graph.instance(limiter).value("w_max") or 0.0) if limiter else 0.0
    return Drive(pose, origin, graph.instance(origin).model_name if origin else None,
                 tuple(chain), limiter, w_max)


def topology(graph) -> Topology:
    """The roles, for every PoseIntegrator (in the scenario's order) what drives it, and what
    feeds the follower's pose input (the evaluation's belief asks)."""
    poses = [c.name for c in graph.scenario.components
             if graph.instance(c.name).model_name == "PoseIntegrator"]
    roles = find_roles(graph)
    feed = upstream(graph, roles.follower, "x") if roles.follower is not None else None
    return Topology(roles, tuple(drive_of(graph, p) for p in poses), graph_geometry(graph, roles),
                    feed[0] if feed is not None else None)
