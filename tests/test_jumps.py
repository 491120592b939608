"""The fixed-step masters at jumps on communication points (docs/masters.md, "Jumps on the
grid"): a piecewise-constant twist whose jumps fall on steps is integrated exactly by the
quadratic, trapezoidal and Gauss-Seidel masters, each step taking the value of its own
interval; a jump inside a step stays first order.

The reference end poses are closed forms, computed here: over a segment of constant twist
(vx, vy, w) the pose equations of docs/spec.md, Pose integration, integrate to a straight line
(w = 0) or an arc, and a run of segments composes them.
"""
import math

import numpy as np
import pytest
import yaml

from mecanum_fmu import master
from mecanum_fmu.master.breakpoints import CUT, step_cuts
from mecanum_fmu.models.topology import topology
from mecanum_fmu.report.evaluation import evaluate
from mecanum_fmu.runner import prepare

from helpers import ROOT

EXACT = ("quadratic", "trapezoidal", "gauss-seidel")
TARGET = 1e-9      # [m], [rad]: the bound at the scenario's own step
SEGMENTS = [{"duration": 1}, {"duration": 2, "vy": 0.3}, {"duration": 1.5, "vx": -0.3, "w": 0.4},
            {"duration": 2, "vx": 0.2, "vy": 0.1, "w": -0.6}, {"duration": 1}]


def closed_form(segments: list[dict], stop: float) -> tuple[float, float, float]:
    """The end pose at `stop` of segments from (0, 0, 0): each segment's constant twist
    integrated exactly (docs/spec.md, Pose integration), the rest at rest."""
    x = y = theta = 0.0
    t = 0.0
    for seg in segments:
        tau = min(seg["duration"], stop - t)
        if tau <= 0:
            break
        vx, vy, w = (seg.get(k, 0.0) for k in ("vx", "vy", "w"))
        if w == 0:
            x += (vx * math.cos(theta) - vy * math.sin(theta)) * tau
            y += (vx * math.sin(theta) + vy * math.cos(theta)) * tau
        else:
            end = theta + w * tau
            s, c = math.sin(end) - math.sin(theta), math.cos(end) - math.cos(theta)
            x += (vx * s + vy * c) / w
            y += (-vx * c + vy * s) / w
            theta = end
        t += seg["duration"]
    return x, y, theta


def _end(graph, pose: str) -> tuple[float, float, float]:
    results = master.simulate(graph, graph.scenario.experiment)
    return tuple(results.final(f"{pose}.{k}") for k in ("x", "y", "theta"))


def _showcase(stop: float) -> tuple[dict, list[dict]]:
    doc = yaml.safe_load((ROOT / "scenarios/modes/showcase.yaml").read_text())
    doc["experiment"]["stop_time"] = stop
    return doc, doc["components"]["source"]["segments"]


@pytest.mark.parametrize("name", EXACT)
@pytest.mark.parametrize("stop", [16.0, 10.5, 12.5])
def test_showcase_is_exact_at_its_step(name, stop, fmu_dir):
    """modes/showcase at h = 0.01: to its end at rest, and stopped while it moves diagonally
    (10.5 s) or spins (12.5 s), where no cancellation at rest helps."""
    doc, segments = _showcase(stop)
    end = _end(prepare(doc, master_name=name, fmu_dir=fmu_dir), "pose")
    assert end == pytest.approx(closed_form(segments, stop), abs=TARGET)


def _three_chassis(segments: list[dict], stop: float, step: float) -> dict:
    """A mecanum car, an omni X-drive and a larger mecanum car on one segments source."""
    chassis = {"mecanum": ("Center2Wheel", "Wheel2Center", {"L": 0.16, "W": 0.12, "R": 0.06}),
               "omni": ("OmniCenter2Wheel", "OmniWheel2Center", {"L": 0.2, "R": 0.05}),
               "big": ("Center2Wheel", "Wheel2Center", {"L": 0.3, "W": 0.25, "R": 0.1})}
    components = {"command": {"fmu": "VelocitySource", "segments": segments}}
    connections = []
    for name, (c2w, w2c, geometry) in chassis.items():
        components[f"{name}_c2w"] = {"fmu": c2w, "parameters": geometry}
        components[f"{name}_w2c"] = {"fmu": w2c, "parameters": geometry}
        components[f"{name}_pose"] = {"fmu": "PoseIntegrator"}
        connections += [[f"command.{v}", f"{name}_c2w.{v}"] for v in ("vx", "vy", "w")]
        connections += [[f"{name}_c2w.w{i}", f"{name}_w2c.w{i}"] for i in range(1, 5)]
        connections += [[f"{name}_w2c.{v}", f"{name}_pose.{v}"] for v in ("vx", "vy", "w")]
    return {"name": "three_chassis", "components": components, "connections": connections,
            "experiment": {"start_time": 0.0, "stop_time": stop, "step_size": step}}


@pytest.mark.parametrize("name", EXACT)
def test_chassis_on_one_segments_source_are_exact(name, fmu_dir):
    """Every pose, ending in the fourth segment (moving and turning), at h = 0.01."""
    graph = prepare(_three_chassis(SEGMENTS, 6.0, 0.01), master_name=name, fmu_dir=fmu_dir)
    results = master.simulate(graph, graph.scenario.experiment)
    exact = closed_form(SEGMENTS, 6.0)
    for pose in ("mecanum_pose", "omni_pose", "big_pose"):
        end = tuple(results.final(f"{pose}.{k}") for k in ("x", "y", "theta"))
        assert end == pytest.approx(exact, abs=TARGET), pose


def test_a_jump_inside_a_step_stays_first_order(fmu_dir):
    """Jumps at 1.005 and 2.015 s are mid-step at h = 0.01 and at h = 0.002: nothing is cut
    there, and the Gauss-Seidel error falls with the step as h (first order, a ratio of 5),
    far above the on-grid case."""
    segments = [{"duration": 1.005, "vy": 0.3}, {"duration": 1.01, "vx": -0.3, "w": 0.4},
                {"duration": 2.0, "vx": 0.2}]
    exact = np.array(closed_form(segments, 3.0)[:2])
    errors = []
    for h in (0.01, 0.002):
        doc = _three_chassis(segments, 3.0, h)
        end = _end(prepare(doc, master_name="gauss-seidel", fmu_dir=fmu_dir), "mecanum_pose")
        errors.append(float(np.hypot(*(np.array(end[:2]) - exact))))
    assert errors[0] > 1e-5
    assert errors[0] / errors[1] == pytest.approx(5.0, rel=0.2)


@pytest.mark.parametrize("name", EXACT)
def test_recorded_path_matches_at_its_own_step(name, fmu_dir):
    """The follower's feed-forward jumps at every row of the 10 Hz path (h = 0.05): the run
    matches its truth (3 decimals, docs/spec.md, Tolerances); it did not before the cut."""
    graph = prepare(ROOT / "scenarios/closed_loop/recorded_path.yaml", master_name=name,
                    fmu_dir=fmu_dir)
    results = master.simulate(graph, graph.scenario.experiment)
    (pose,) = evaluate(graph, results, topo=topology(graph)).poses
    assert pose.match, pose.error


def test_cuts_on_either_side_of_a_grid_point():
    """A jump on t_j or an ulp before it cuts the step that ends there (left value first);
    an ulp after it cuts the next step at the jump; one mid-step cuts nothing."""
    h, start = 0.1, 0.0
    t3 = start + 3 * h                       # 0.30000000000000004
    before, after = np.nextafter(t3, 0), np.nextafter(t3, 1)
    cuts = step_cuts(np.array([t3, 0.55, 0.7]), start, h, 10, 1.0)
    assert sorted(cuts) == [2, 6]
    assert cuts[2].inside == (pytest.approx(t3 - CUT * h, abs=1e-18),)
    assert cuts[2].restart == (False, True)
    cut = step_cuts(np.array([before]), start, h, 10, 1.0)[2]
    assert cut.inside[0] < before and cut.restart == (False, True)
    cut = step_cuts(np.array([after]), start, h, 10, 1.0)[3]
    assert cut.inside[-1] == after and cut.restart[-2:] == (True, False)
    # a jump on the stop time that ends a short last step (1.0 -> 1.005): that step is cut
    last = step_cuts(np.array([1.005]), 0.0, 0.01, 101, 1.005)
    assert list(last) == [100] and last[100].restart == (False, True)
    assert 1.0 < last[100].inside[0] < 1.005
