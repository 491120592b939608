"""The one place where a run is compared with its ground truth.

`evaluate(graph, results, topo=topology(graph))` takes the topology (models.topology: which
blocks drive which pose, asked once by the caller), solves each pose's truth
(report.ground_truth: expressions, tables, segments, field-oriented and car-like commands, a
follower's reference, saturated wheels) and returns, per pose, the end pose, the truth, the
error, match, wheel-speed saturation and any failure it caught (a truth that fails costs only
itself). `run`, `sweep`, the plots, the animation and the chassis comparison all take its
answer.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..models.modes import constant_twist_signs
from ..models.topology import Drive, Topology
from ..results import Results
from .drive_train import drive_train_limits, limit_lines
from .ground_truth import pose_truth
from .truth import Truth

AXES = ("x", "y", "theta")
SATURATED = 1.0 - 1e-9      # a wheel at w_max * SATURATED or more is at its limit


@dataclass(frozen=True)
class Saturation:
    """A Center2Wheel limited the wheel speeds during the run."""
    instance: str
    w_max: float
    first: float            # the first and last recorded times at the limit [s]
    last: float
    in_truth: bool          # the truth saturates too (open loop); not a follower's reference

    def as_dict(self) -> dict:
        return {"instance": self.instance, "w_max": self.w_max, "from": self.first,
                "to": self.last, "in_ground_truth": self.in_truth}


@dataclass(frozen=True)
class PoseEvaluation:
    pose: str
    drive: Drive
    end: dict[str, float] | None            # the run's end pose (None: not recorded)
    truth: Truth | None = field(default=None, repr=False)
    saturation: Saturation | None = None
    failure: str | None = None              # why there is no truth, when it failed

    @property
    def error(self) -> dict[str, float] | None:
        """dx, dy, dtheta and position of the end pose against the truth's."""
        if self.truth is None or self.end is None:
            return None
        ref = dict(zip(AXES, self.truth.end))
        error = {f"d{k}": self.end[k] - ref[k] for k in AXES}
        error["position"] = math.hypot(error["dx"], error["dy"])
        return error

    @property
    def match(self) -> bool | None:
        """The end points agree at 3 decimals."""
        if self.truth is None or self.end is None:
            return None
        ref, end = dict(zip(AXES, self.truth.end)), self.end
        return round(end["x"], 3) == round(ref["x"], 3) and round(end["y"], 3) == round(ref["y"], 3)

    def as_dict(self) -> dict:
        out = {"end_pose": self.end}
        if self.truth is not None and self.error is not None:
            out["reference_end_pose"] = dict(zip(AXES, self.truth.end))
            out["error"], out["match"] = self.error, self.match
        if self.saturation is not None:
            out["saturation"] = self.saturation.as_dict()
        if self.failure is not None:
            out["ground_truth_error"] = self.failure
        return out


@dataclass(frozen=True)
class Evaluation:
    topology: Topology
    poses: tuple[PoseEvaluation, ...]
    wheel_signs: str | None
    belief: dict | None = None    # an Odometry's end drift from the pose (docs/robot.md)
    drive_train: dict | None = None     # the motors' clamps and the contacts' slip

    @property
    def roles(self):
        return self.topology.roles

    @property
    def geometry(self) -> dict[str, float]:
        """alpha, L, W, R of the kinematics (the animation's car)."""
        return self.topology.geometry

    @property
    def single(self) -> PoseEvaluation | None:
        """The pose of a one-pose run ("the car")."""
        return self.poses[0] if len(self.poses) == 1 else None

    @property
    def truth(self) -> Truth | None:
        return self.single.truth if self.single is not None else None

    @property
    def failure(self) -> str | None:
        failed = [p for p in self.poses if p.failure]
        if self.single is not None or len(failed) <= 1:
            return failed[0].failure if failed else None
        return "; ".join(f"{p.pose}: {p.failure}" for p in failed)

    def summary(self) -> dict:
        """The summary.json entries: one pose flat (end_pose, reference_end_pose, error,
        match), several under "poses"; wheel_signs; ground_truth_error when a truth failed."""
        out: dict = {}
        if self.single is not None and self.single.end is not None:
            out.update(self.single.as_dict())
            out.pop("ground_truth_error", None)
        elif len(self.poses) > 1:
            out["poses"] = {p.pose: p.as_dict() for p in self.poses if p.end is not None}
        if self.belief is not None and self.single is not None:
            out["belief"] = self.belief
        if self.wheel_signs is not None:
            out["wheel_signs"] = self.wheel_signs
        if self.failure is not None:
            out["ground_truth_error"] = self.failure
        if self.drive_train is not None:
            out["drive_train"] = self.drive_train
        return out


def evaluate(graph, results: Results, *, topo: Topology,
             truths: dict[str, Truth | None] | None = None, with_truth: bool = True) -> Evaluation:
    """Compare the run with its truth, pose by pose. `topo`: the graph's models.topology,
    asked once by the caller; `truths`: already solved (a sweep solves one per distinct
    profile); `with_truth=False`: end poses only (a run that failed). What is read from the
    results comes first, the truths (through models/) last."""
    ends = [(drive, _end_pose(results, drive.pose)) for drive in topo.drives]
    belief, limits = _belief(results, topo), drive_train_limits(graph, results)
    judged = [(drive, end, _saturation(results, drive)) for drive, end in ends
              if end is not None and with_truth and len(results.time)]
    compared = {}
    for drive, end, saturation in judged:
        if truths is not None and drive.pose in truths:
            truth, failure = truths[drive.pose], None
        else:
            truth, failure = solve_truth(graph, drive, results.time)
        compared[drive.pose] = PoseEvaluation(drive.pose, drive, end, truth, saturation, failure)
    poses = tuple(compared.get(drive.pose) or PoseEvaluation(drive.pose, drive, end)
                  for drive, end in ends)
    signs = (constant_twist_signs(graph, results, topo.roles, topo.geometry)
             if len(results.time) else None)
    return Evaluation(topo, poses, signs, belief, limits)


def _belief(results: Results, topo: Topology) -> dict | None:
    """The Odometry's end pose and its drift from the (single) true pose, and whether the
    follower is fed by it (a loop closed on belief: the tracking error is the drift)."""
    odom, drives = topo.roles.odometry, topo.drives
    end = _end_pose(results, odom) if odom is not None and len(drives) == 1 else None
    true = _end_pose(results, drives[0].pose) if end is not None else None
    if true is None:
        return None
    drift = {f"d{k}": end[k] - true[k] for k in AXES}
    drift["position"] = math.hypot(drift["dx"], drift["dy"])
    fed = topo.roles.follower is not None and topo.follower_feed == odom
    return {"instance": odom, "end_pose": end, "drift": drift, "closes_the_loop": fed}


def solve_truth(graph, drive: Drive, times: np.ndarray) -> tuple[Truth | None, str | None]:
    """The pose's truth, or why it failed (e.g. an expression that fails between the recorded
    times)."""
    try:
        truth = pose_truth(graph, drive, times)
    except Exception as err:    # any failure of the truth costs only itself
        return None, f"{type(err).__name__}: {err}"
    if truth is not None and not np.all(np.isfinite(truth.end)):
        return None, f"its end pose {truth.end} is not finite"
    return truth, None


def _end_pose(results: Results, pose: str) -> dict[str, float] | None:
    cols = [f"{pose}.{k}" for k in AXES]
    if not len(results.time) or not all(c in results.names for c in cols):
        return None
    return {k: results.final(c) for k, c in zip(AXES, cols)}


def _saturation(results: Results, drive: Drive) -> Saturation | None:
    """When the drive's Center2Wheel held its wheels at w_max (read from its recorded outputs)."""
    w_max = drive.w_max
    cols = [f"{drive.limiter}.w{i}" for i in range(1, 5)]
    if not w_max > 0 or not all(c in results.names for c in cols):
        return None
    peak = np.max(np.abs(np.column_stack([results[c] for c in cols])), axis=1)
    at = np.asarray(results.time)[peak >= w_max * SATURATED]
    if not len(at):
        return None
    return Saturation(drive.limiter, w_max, float(at[0]), float(at[-1]),
                      drive.model != "PathFollower")


def saturation_words(s: dict) -> str:
    return (f"the wheels saturate at w_max = {s['w_max']:g} rad/s ({s['instance']}, "
            f"t = {s['from']:g} to {s['to']:g} s)")


def mismatch_hint(entry: dict) -> str:
    """Why the end points may differ: the saturation the truth does not model, else the step."""
    s = entry.get("saturation")
    if s is not None and not s["in_ground_truth"]:
        return (f"{saturation_words(s)} and the ground truth (the reference) does not; "
                "a smaller step changes nothing")
    if entry.get("belief", {}).get("closes_the_loop"):
        return ("the follower is fed the odometry's belief, not the true pose: the gap is the "
                "belief's drift, most of which a smaller step does not remove (halving the "
                "step shows the step's share: docs/robot.md, \"The step's share\")")
    if "drive_train" in entry:
        return ("motors and floor lie between the command and the pose, and the ground truth "
                "is the kinematic path: the error estimate says how much of it is the step")
    return "the end points differ at 3 decimals; try a smaller step"


def report_lines(summary: dict) -> list[str]:
    """The evaluation's part of the run's report, from its summary."""
    lines = []
    if "end_pose" in summary:
        end = summary["end_pose"]
        lines.append(f"end point (co-simulation): x = {end['x']:.3f}, y = {end['y']:.3f}")
        if "reference_end_pose" in summary:
            ref, err = summary["reference_end_pose"], summary["error"]
            lines.append(f"end point (ground truth):  x = {ref['x']:.3f}, y = {ref['y']:.3f}")
            lines.append(f"error: dx = {err['dx']:.3e}, dy = {err['dy']:.3e}, "
                         f"|e| = {err['position']:.3e} m")
            lines.append("match!" if summary["match"] else f"no match ({mismatch_hint(summary)})")
        if (s := summary.get("saturation")) is not None and s["in_ground_truth"]:
            lines.append(f"{saturation_words(s)}; the ground truth saturates them too")
    if (b := summary.get("belief")) is not None:
        d = b["drift"]
        lines.append(f"belief ({b['instance']}) - true pose at the end: dx = {d['dx']:.3e}, "
                     f"dy = {d['dy']:.3e}, |e| = {d['position']:.3e} m, dtheta = "
                     f"{d['dtheta']:.3e} rad")
    for name, p in summary.get("poses", {}).items():
        lines.append(pose_line(name, p))
    if "wheel_signs" in summary:
        lines.append(f"wheel signs (constant twist): {summary['wheel_signs']}")
    if "drive_train" in summary:
        lines += limit_lines(summary["drive_train"])
    return lines


def pose_line(name: str, p: dict) -> str:
    end = p["end_pose"]
    line = f"{name}: end x = {end['x']:.3f}, y = {end['y']:.3f}, theta = {end['theta']:.3f}"
    if "reference_end_pose" in p:
        ref = p["reference_end_pose"]
        line += (f"; ground truth x = {ref['x']:.3f}, y = {ref['y']:.3f}; |e| = "
                 f"{p['error']['position']:.3e} m, "
                 + ("match" if p["match"] else f"no match ({mismatch_hint(p)})"))
    elif "ground_truth_error" in p:
        line += f"; no ground truth ({p['ground_truth_error']})"
    return line
