"""How scenario YAML reads: numbers as users write them, each problem once."""
from pathlib import Path

import pytest

from helpers import ROOT
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.runner import prepare
from mecanum_fmu.scenario.document import load_scenario

CIRCLE = (ROOT / "scenarios" / "circle.yaml").read_text()


@pytest.mark.parametrize("text, value", [("1e-3", 1e-3), ("2E5", 2e5), ("1.5e+2", 150.0),
                                         ("-4e1", -40.0), ("0.06", 0.06)])
def test_exponents_without_a_dot_are_numbers(tmp_path, text, value):
    """YAML 1.1 would read 1e-3 as text; a scenario reads it as the number it says."""
    path = tmp_path / "s.yaml"
    path.write_text(CIRCLE.replace("  R: 0.06 ", f"  R: {text} "))
    assert load_scenario(path).parameters["R"] == value


def test_quoted_numbers_stay_text(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(CIRCLE.replace("  R: 0.06 ", "  R: '1e-3' "))
    assert load_scenario(path).parameters["R"] == "1e-3"


def test_a_shared_parameter_problem_is_reported_once(tmp_path, fmu_dir):
    """L goes to both kinematics blocks; a bad L is one problem, not one per block."""
    path = tmp_path / "s.yaml"
    path.write_text(CIRCLE.replace("  L: 0.16 ", "  L: -1.0 "))
    with pytest.raises(ScenarioError) as info:
        prepare(path, fmu_dir=fmu_dir, build=False)
    assert [p.place for p in info.value.problems] == ["parameters.L"]


@pytest.mark.parametrize("name, choices, expect", [
    ("w5", ["w", "w1", "w2", "w3", "w4", "vx"], "w4"),        # the nearest number, not 'w'
    ("w0", ["w", "w1", "w2", "w3", "w4"], "w1"),
    ("dR7", ["R", "dR1", "dR2", "dR3", "dR4"], "dR4"),
    ("Centre2Wheel", ["VelocitySource", "Center2Wheel", "Wheel2Center"], "Center2Wheel"),
    ("POSEINTEGRATOR", ["PoseIntegrator", "PathFollower"], "PoseIntegrator"),   # any case
    ("quadratc", ["quadratic", "trapezoidal", "gauss-seidel", "jacobi"], "quadratic"),
])
def test_did_you_mean(name, choices, expect):
    from mecanum_fmu.errors import did_you_mean
    assert did_you_mean(name, choices) == f"; did you mean '{expect}'?"


def test_did_you_mean_stays_quiet_when_nothing_is_close():
    from mecanum_fmu.errors import did_you_mean
    assert did_you_mean("zzz", ["vx", "vy", "w"]) == ""
    assert did_you_mean(5, ["w5"]) == ""


def test_a_mapping_takes_relative_paths_from_base_dir(tmp_path):
    """load_scenario_dict: a table path is found in base_dir, as next to a scenario file."""
    from mecanum_fmu.scenario import load_scenario_dict
    (tmp_path / "log.csv").write_text("time,vx,vy,w\n0,0,1,0\n1,0,1,0\n")
    doc = {"name": "from_dict", "components": {
        "source": {"fmu": "VelocitySource", "parameters": {"table": "log.csv"}}}}
    scenario = load_scenario_dict(doc, base_dir=tmp_path)
    assert scenario.name == "from_dict"
    assert scenario.components[0].parameters["table"].startswith("time,vx,vy,w")
    with pytest.raises(ScenarioError, match="log.csv"):
        load_scenario_dict(doc, base_dir=tmp_path / "elsewhere")
