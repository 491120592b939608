"""Plausibility warnings (issue 24 item 3): valid values that are probably mistakes.

Reference values: unit factors by hand (60 mm = 0.06 m, 90 deg = pi/2 rad), the run's own span
from the scenario text, and for the stability limit the runs themselves: below the limit the
start error decays, above it the loop diverges.
"""
import math

import pytest

from helpers import ROOT, write_scenario
from mecanum_fmu.scenario import plausibility
from mecanum_fmu.cli import main
from mecanum_fmu.errors import SimulationError
from mecanum_fmu.runner import prepare, run

CIRCLE = ROOT / "scenarios" / "closed_loop" / "track_circle.yaml"


def circle(tmp_path, replace=(), name="loop"):
    text = CIRCLE.read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    return write_scenario(tmp_path, name, text)


def test_millimetres_and_degrees_are_named_with_the_fix(tmp_path, fmu_dir):
    path = circle(tmp_path, [("R: 0.06 ", "R: 60 "), ("L: 0.16 ", "L: 160 "),
                             ("W: 0.12 ", "W: 12 "), ("theta0: 0.5", "theta0: 90")])
    warnings = prepare(path, fmu_dir=fmu_dir).warnings
    expected = {"parameters.R": "R = 60 m", "parameters.L": "L = 160 m",
                "parameters.W": "W = 12 m", "components.pose.parameters.theta0": "theta0 = 90 rad"}
    fixes = {"parameters.R": ("millimetres", "R: 0.06"), "parameters.L": ("millimetres", "L: 0.16"),
             "parameters.W": ("millimetres", "W: 0.012", "centimetres", "W: 0.12"),
             "components.pose.parameters.theta0": ("degrees", f"theta0: {math.pi / 2:.6g}")}
    for place, value in expected.items():
        found = [w for w in warnings if f": {place}: " in w]
        assert len(found) == 1, (place, warnings)           # once, not per component
        assert value in found[0] and all(f in found[0] for f in fixes[place])


def test_plausible_values_give_no_warning(fmu_dir):
    """Every bundled scenario passes `validate --strict` (no false alarms)."""
    import yaml
    for path in sorted((ROOT / "scenarios").glob("**/*.yaml")):
        if "components" not in (yaml.safe_load(path.read_text()) or {}):
            continue                                         # a sweep file
        graph = prepare(path, fmu_dir=fmu_dir, build=False)
        assert plausibility.problems(graph.scenario, graph.instances) == [], path


def test_a_table_outside_the_run_span_is_named(tmp_path, fmu_dir):
    rows = "".join(f"{1.7e9 + 0.05 * i!r},0.1,0,0\n" for i in range(41))
    (tmp_path / "epoch.csv").write_text("time,vx,vy,w\n" + rows)
    (tmp_path / "short.csv").write_text("time,vx,vy,w\n0,0.1,0,0\n1,0.1,0,0\n")
    base = ("experiment: {{start_time: 0.0, stop_time: 2.0, step_size: 0.1}}\ncomponents:\n"
            "  source: {{fmu: VelocitySource, {spec}}}\n  pose: {{fmu: PoseIntegrator}}\n"
            "connections:\n  - [source.vx, pose.vx]\n  - [source.vy, pose.vy]\n"
            "  - [source.w, pose.w]\n")
    cases = {"parameters: {table: epoch.csv}": "the run sees only its first row",
             "parameters: {table: short.csv}": "outside it its end rows are held",
             "table: {file: epoch.csv, start: first_row}": None}
    for i, (spec, words) in enumerate(cases.items()):
        graph = prepare(write_scenario(tmp_path, f"s{i}", base.format(spec=spec)),
                        fmu_dir=fmu_dir)
        span = [w for w in graph.warnings if "components.source.table" in w]
        if words is None:
            assert span == []
        else:
            assert len(span) == 1 and words in span[0] and "the run 0 to 2 s" in span[0]


def test_a_length_too_large_in_any_unit_is_named(tmp_path, fmu_dir):
    """R = 1500 and L = 7000: no millimetre reading (1.5 m, 7 m) or centimetre one (15 m,
    70 m) is plausible either, and they are still far above 1 m and 5 m."""
    path = circle(tmp_path, [("R: 0.06 ", "R: 1500 "), ("L: 0.16 ", "L: 7000 ")])
    warnings = prepare(path, fmu_dir=fmu_dir).warnings
    for place, text in (("parameters.R", "R = 1500 m is implausibly large for a wheel radius; "
                                         "give it in metres (at most 1 m is plausible)"),
                        ("parameters.L", "L = 7000 m is implausibly large for a chassis length;"
                                         " give it in metres (at most 5 m is plausible)")):
        found = [w for w in warnings if f": {place}: " in w]
        assert len(found) == 1 and text in found[0], (place, warnings)


def test_strict_validation_makes_warnings_errors(tmp_path, capsys, fmu_dir):
    path = circle(tmp_path, [("R: 0.06 ", "R: 60 ")])
    assert main(["validate", str(path), "--fmu-dir", str(fmu_dir)]) == 0
    assert "warning:" in capsys.readouterr().err
    assert main(["validate", "--strict", str(path), "--fmu-dir", str(fmu_dir)]) == 2
    err = capsys.readouterr().err
    assert "error" in err and "R = 60 m" in err and "Traceback" not in err


def _diverges(path, fmu_dir, tmp_path) -> bool:
    try:
        outcome = run(prepare(path, fmu_dir=fmu_dir), tmp_path, plots=False,
                      log=lambda line: None)
    except SimulationError:                      # values stopped being finite
        return True
    position = outcome.summary["error"]["position"]
    return not (math.isfinite(position) and position < 0.01)   # from 0.36 m at the start


@pytest.mark.parametrize("master, limit", [("trapezoidal", 1.0), ("quadratic", 2.0),
                                           ("gauss-seidel", 2.0), ("jacobi", 0.445)])
def test_the_gain_warning_sits_at_the_stability_limit(tmp_path, fmu_dir, master, limit):
    assert plausibility.stability_limit(master, can_roll_back=True) == limit
    for factor, unstable in ((0.8, False), (1.25, True), (25.0, True)):    # h k = 50: GS
        step = factor * limit / 2.0                           # k = 2 1/s, the default
        path = circle(tmp_path, [("master: quadratic", f"master: {master}"),
                                 ('"1 - cos(t)"', '"0"'), ('"sin(t)"', '"0"'),   # x' = -k x
                                 ("theta0: 0.5", "theta0: 0.0"),       # no heading coupling
                                 ("step_size: 0.05", f"step_size: {step!r}"),
                                 ("stop_time: 10.0", "stop_time: 40.0")], f"{master}{factor}")
        warned = [w for w in prepare(path, fmu_dir=fmu_dir).warnings if "stability limit" in w]
        assert bool(warned) == unstable
        assert _diverges(path, fmu_dir, tmp_path / f"{master}{factor}") == unstable
        if warned:
            assert f"h k = {2.0 * step:.3g}" in warned[0] and master in warned[0]
