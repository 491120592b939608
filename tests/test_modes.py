"""The basic motions (scenarios/modes/), their wheel-sign patterns, the ICR and the animation.

The expected wheel signs are derived here from the matrix of docs/spec.md, Inverse kinematics,
independently of mecanum_fmu.models.modes; the closed forms come from docs/spec.md, Pose integration.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from mecanum_fmu.models import modes
from mecanum_fmu import runner

ROOT = Path(__file__).resolve().parents[1]
MODES_DIR = ROOT / "scenarios" / "modes"
ALPHA, L, W, R = math.pi / 4, 0.16, 0.12, 0.06

# mode -> (vx, vy, w) as commanded in scenarios/modes/<mode>.yaml
TWISTS = {
    "forward": (0.0, 0.3, 0.0), "backward": (0.0, -0.3, 0.0),
    "left": (-0.3, 0.0, 0.0), "right": (0.3, 0.0, 0.0), "diagonal": (-0.3, 0.3, 0.0),
    "spin_cw": (0.0, 0.0, -0.8), "spin_ccw": (0.0, 0.0, 0.8),
}


def spec_signs(vx, vy, w):
    """Signs of w1..w4 from docs/spec.md, Inverse kinematics: w = (1/R) A @ [vx, vy, w]."""
    c = 1.0 / math.tan(ALPHA)
    k = L + W * c
    A = np.array([[-c, 1, k], [c, 1, -k], [-c, 1, -k], [c, 1, k]])
    speeds = A @ np.array([vx, vy, w]) / R
    return ["0" if abs(s) < 1e-9 else ("+" if s > 0 else "-") for s in speeds]


def run_scenario(path, out, fmu_dir, **overrides):
    graph = runner.prepare(path, fmu_dir=fmu_dir, **overrides)
    return runner.run(graph, out, plots=False, log=lambda line: None)


def write_scenario(tmp_path, name, vx, vy, w, stop, step):
    text = (MODES_DIR / "forward.yaml").read_text()
    text = text.replace('vx_expr: "0", vy_expr: "0.3", w_expr: "0"',
                        f'vx_expr: "{vx!r}", vy_expr: "{vy!r}", w_expr: "{w!r}"')
    text = text.replace("stop_time: 4.0", f"stop_time: {stop!r}").replace(
        "step_size: 0.01 ", f"step_size: {step!r} ").replace("name: forward", f"name: {name}")
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def mode_runs(fmu_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("modes")
    return {m: run_scenario(MODES_DIR / f"{m}.yaml", out / m, fmu_dir) for m in TWISTS}


@pytest.mark.parametrize("mode", list(TWISTS))
def test_mode_commands_its_twist(mode, mode_runs):
    res = mode_runs[mode].results
    for var, value in zip(("vx", "vy", "w"), TWISTS[mode]):
        np.testing.assert_allclose(res[f"source.{var}"], value, atol=1e-15)
    assert res.time[-1] == pytest.approx(4.0)


@pytest.mark.parametrize("mode", list(TWISTS))
def test_mode_wheel_signs(mode, mode_runs):
    outcome = mode_runs[mode]
    res = outcome.results
    expected = spec_signs(*TWISTS[mode])
    for i, sign in enumerate(expected, start=1):
        col = res[f"c2w.w{i}"]
        if sign == "+":
            assert np.all(col > 1e-9), (mode, i)
        elif sign == "-":
            assert np.all(col < -1e-9), (mode, i)
        else:
            assert np.all(np.abs(col) < 1e-9), (mode, i)
    pattern = "  ".join(f"w{i} {s}" for i, s in enumerate(expected, start=1))
    assert modes.wheel_signs(*TWISTS[mode], ALPHA, L, W, R) == pattern
    assert outcome.summary["wheel_signs"] == pattern
    assert f"wheel signs (constant twist): {pattern}" in runner.report_lines(outcome.summary)


def test_seeds003_numbering():
    # M1 front-left = wheel 2, M2 rear-left = 3, M3 rear-right = 4, M4 front-right = 1.
    assert modes.seeds003_signs(["a", "b", "c", "d"]) == ["b", "c", "d", "a"]


def test_no_wheel_signs_for_a_changing_twist(fmu_dir, tmp_path):
    outcome = run_scenario(ROOT / "scenarios" / "circle.yaml", tmp_path, fmu_dir, stop_time=1.0)
    assert "wheel_signs" not in outcome.summary


@pytest.mark.parametrize("mode,direction", [
    ("forward", (0, 1)), ("backward", (0, -1)), ("left", (-1, 0)), ("right", (1, 0)),
    ("diagonal", (-1, 1))])
def test_translation_direction(mode, direction, mode_runs):
    res = mode_runs[mode].results
    x, y, theta = res["pose.x"], res["pose.y"], res["pose.theta"]
    np.testing.assert_allclose(theta, 0.0, atol=1e-12)
    d = np.array(direction, dtype=float) / np.hypot(*direction)
    travelled = np.column_stack((x, y)) @ d
    assert np.all(np.diff(travelled) > 0)                       # moves along the direction
    across = np.column_stack((x, y)) @ np.array([-d[1], d[0]])
    np.testing.assert_allclose(across, 0.0, atol=1e-12)         # and nowhere else
    assert travelled[-1] == pytest.approx(0.3 * np.hypot(*direction) * 4.0, abs=1e-9)


@pytest.mark.parametrize("mode,sense", [("spin_ccw", 1), ("spin_cw", -1)])
def test_spin_in_place(mode, sense, mode_runs):
    res = mode_runs[mode].results
    np.testing.assert_allclose(res["pose.x"], 0.0, atol=1e-9)
    np.testing.assert_allclose(res["pose.y"], 0.0, atol=1e-9)
    assert np.all(sense * np.diff(res["pose.theta"]) > 0)
    assert res["pose.theta"][-1] == pytest.approx(sense * 0.8 * 4.0, abs=1e-9)


@pytest.mark.parametrize("mode", ["forward", "left", "diagonal"])
def test_no_icr_without_rotation(mode, mode_runs):
    res = mode_runs[mode].results
    assert not np.any(res["w2c.has_icr"])
    np.testing.assert_array_equal(res["w2c.icr_x"], 0.0)
    np.testing.assert_array_equal(res["w2c.icr_y"], 0.0)


def test_spin_icr_is_the_centre(mode_runs):
    res = mode_runs["spin_ccw"].results
    assert np.all(res["w2c.has_icr"])
    np.testing.assert_allclose(res["w2c.icr_x"], 0.0, atol=1e-12)
    np.testing.assert_allclose(res["w2c.icr_y"], 0.0, atol=1e-12)


@pytest.mark.parametrize("v,w,stop,step", [(0.3, 0.7, 3.0, 0.01), (0.3, 0.7, 3.0, 0.25),
                                           (0.5, -1.3, 2.0, 0.037), (0.2, 2.0, 5.0, 0.1)])
def test_constant_twist_arc(v, w, stop, step, fmu_dir, tmp_path):
    """vx = 0, vy = v, w const: an arc of radius v/|w| about (-v/w, 0), exact for any step."""
    path = write_scenario(tmp_path, "arc", 0.0, v, w, stop, step)
    outcome = run_scenario(path, tmp_path / "out", fmu_dir)
    res = outcome.results
    t = res.time
    T = t[-1]
    assert T == pytest.approx(stop)
    x, y, theta = res["pose.x"], res["pose.y"], res["pose.theta"]
    # docs/spec.md, Pose integration: theta = w t, x' = -v sin(theta), y' = v cos(theta)
    assert theta[-1] == pytest.approx(w * T, abs=1e-9)
    assert x[-1] == pytest.approx(v / w * (math.cos(w * T) - 1.0), abs=1e-9)
    assert y[-1] == pytest.approx(v / w * math.sin(w * T), abs=1e-9)
    cx, cy = -v / w, 0.0
    np.testing.assert_allclose(np.hypot(x - cx, y - cy), v / abs(w), atol=1e-9)
    # The ICR: body (-vy/w, vx/w), rotated by theta and moved to the pose, stays at the centre.
    assert np.all(res["w2c.has_icr"])
    np.testing.assert_allclose(res["w2c.icr_x"], -v / w, atol=1e-12)
    np.testing.assert_allclose(res["w2c.icr_y"], 0.0, atol=1e-12)
    from mecanum_fmu.report.plots import _icr_world
    wx, wy = _icr_world(res, outcome.evaluation.roles)
    np.testing.assert_allclose(wx, cx, atol=1e-9)
    np.testing.assert_allclose(wy, cy, atol=1e-9)


def test_instantaneous_center_function():
    from mecanum_fmu.models.blocks.kinematics import instantaneous_center
    assert instantaneous_center(0.3, 0.4, 0.5) == (-0.8, 0.6, True)
    assert instantaneous_center(0.3, 0.4, 0.0) == (0.0, 0.0, False)
    assert instantaneous_center(0.3, 0.4, 1e-10) == (0.0, 0.0, False)
    x, y, has = instantaneous_center(0.3, 0.4, -2e-9)
    assert has and (x, y) == pytest.approx((0.4 / 2e-9, -0.3 / 2e-9))


def test_wheel2center_fmu_valid(built_fmus):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    path = built_fmus["Wheel2Center"]
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    names = [v.name for v in md.modelVariables]
    assert names[11:14] == ["icr_x", "icr_y", "has_icr"]
    assert names[14:] == ["dR1", "dR2", "dR3", "dR4"]     # appended: earlier references unchanged
    assert names[:11] == ["w1", "w2", "w3", "w4", "alpha", "L", "W", "R", "vx", "vy", "w"]
    deps = {o.variable.name: [d.name for d in o.dependencies] for o in md.outputs}
    assert deps["has_icr"] == deps["icr_x"] == ["w1", "w2", "w3", "w4"]


def test_figure_eight_closes(fmu_dir, tmp_path):
    res = run_scenario(MODES_DIR / "figure_eight.yaml", tmp_path, fmu_dir).results
    x, y, theta = res["pose.x"], res["pose.y"], res["pose.theta"]
    assert abs(x[-1]) < 1e-4 and abs(y[-1]) < 1e-4 and abs(theta[-1]) < 1e-6
    assert np.any(res["source.w"] > 0.5) and np.any(res["source.w"] < -0.5)
    # an 8: the path crosses itself - it passes through its middle x twice at the same y
    mid = 0.5 * (x.min() + x.max())
    crossings = np.nonzero(np.diff(np.sign(x - mid)))[0]
    assert len(crossings) == 2
    assert y[crossings[0]] == pytest.approx(y[crossings[1]], abs=1e-2)


def test_showcase_matches(fmu_dir, tmp_path):
    outcome = run_scenario(MODES_DIR / "showcase.yaml", tmp_path, fmu_dir)
    assert outcome.summary["match"]
    assert "wheel_signs" not in outcome.summary
    end = outcome.summary["end_pose"]
    assert (end["x"], end["y"], end["theta"]) == pytest.approx((-0.6, 0.6, 0.0), abs=1e-4)


def test_modes_doc_is_generated():
    text = (ROOT / "docs" / "modes.md").read_text()
    assert modes.markdown_table() in text
    assert "python -m mecanum_fmu.models.modes" in text


@pytest.fixture(scope="module")
def circle_run(fmu_dir, tmp_path_factory):
    """The seed circle's run, drawn by both test_animation cases."""
    return run_scenario(ROOT / "scenarios" / "circle.yaml", tmp_path_factory.mktemp("circle"),
                        fmu_dir)


@pytest.mark.heavy(12)
@pytest.mark.parametrize("max_frames", [100, 17])
def test_animation(max_frames, circle_run, tmp_path):
    from PIL import Image

    from mecanum_fmu.report.animation import write_animation
    outcome = circle_run
    geometry = outcome.evaluation.geometry
    assert (geometry["L"], geometry["W"]) == (0.16, 0.12)
    path = write_animation(outcome.results, outcome.evaluation, tmp_path / "a.gif",
                           max_frames=max_frames)
    assert path.is_file() and path.stat().st_size < 2_000_000
    with Image.open(path) as im:
        assert 2 <= im.n_frames <= max_frames
        assert 100 <= im.width <= 1000 and 100 <= im.height <= 1000


def test_animation_frames_keep_their_layout_and_move_the_car(circle_run):
    # the still parts are drawn once: the y tick labels (the left 40 pixels) are the same in
    # every frame (when each frame ran the constrained layout again, they moved by a pixel
    # between frames), while the car and its path change
    from mecanum_fmu.report.animation import _frames, build_scene, frame_indices
    outcome = circle_run
    fig, update, n = build_scene(outcome.results, outcome.evaluation.roles,
                                 outcome.evaluation.truth, outcome.evaluation.geometry)
    frames = [np.asarray(f) for f in _frames(fig, update, frame_indices(n, 5))]
    assert len(frames) == 5
    assert all(np.array_equal(frames[0][:, :40], f[:, :40]) for f in frames[1:])
    assert all(not np.array_equal(a, b) for a, b in zip(frames, frames[1:]))


def test_run_animate_flag(fmu_dir, tmp_path):
    # what is checked is that run(animate=True) writes the GIF and lists it: 6 rows (6 frames)
    # show that as well as 51 did; test_animation draws the full 100 frames
    graph = runner.prepare(MODES_DIR / "spin_ccw.yaml", fmu_dir=fmu_dir, stop_time=0.05)
    outcome = runner.run(graph, tmp_path, plots=False, animate=True, log=lambda line: None)
    gif = tmp_path / "animation.gif"
    assert gif in outcome.files and gif.is_file()


def test_an_interrupted_animation_leaves_no_gif(fmu_dir, tmp_path, monkeypatch):
    """Ctrl-C while the GIF is being written: no animation.gif (nor its temporary file) is
    left that looks complete; the results before it are kept."""
    from PIL import Image
    def half_written(self, fp, *args, **kwargs):
        Path(fp).write_bytes(b"GIF89a")          # a GIF's first bytes, then the interrupt
        raise KeyboardInterrupt
    monkeypatch.setattr(Image.Image, "save", half_written)
    graph = runner.prepare(MODES_DIR / "spin_ccw.yaml", fmu_dir=fmu_dir, stop_time=0.05)
    with pytest.raises(KeyboardInterrupt):
        runner.run(graph, tmp_path, plots=False, animate=True, log=lambda line: None)
    assert not (tmp_path / "animation.gif").exists()
    assert not [p.name for p in tmp_path.iterdir() if "animation" in p.name]
    assert (tmp_path / "results.csv").is_file()


def test_icr_panel(mode_runs, fmu_dir, tmp_path):
    from mecanum_fmu.report import plots
    outcome = mode_runs["spin_ccw"]
    roles = outcome.evaluation.roles
    figures = plots.build_figures(outcome.results, roles, outcome.truth)
    assert list(figures)[-1] == "icr"
    lines = {line.get_label(): line for line in figures["icr"].axes[0].get_lines()}
    np.testing.assert_allclose(lines["ICR"].get_xydata(), 0.0, atol=1e-9)   # spins about its centre
    forward = mode_runs["forward"]
    figures = plots.build_figures(forward.results, roles, forward.truth)
    labels = [line.get_label() for line in figures["icr"].axes[0].get_lines()]
    assert "ICR" not in labels
    notes = [text.get_text() for text in figures["icr"].axes[0].texts]
    assert any("pure translation: no ICR" in n for n in notes)
