"""Tests for the plots: figure contents against a hand-made run of the seed scenario
(docs/spec.md, Expected results)."""
import dataclasses
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg", force=True)

import matplotlib.pyplot as plt  # noqa: E402  (only to check that no pyplot figure leaks)
import numpy as np  # noqa: E402
import pytest  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
from mecanum_fmu.report import plots  # noqa: E402
from mecanum_fmu.models.catalog import Roles  # noqa: E402
from mecanum_fmu.report.ground_truth import Truth  # noqa: E402
from mecanum_fmu.results import Results  # noqa: E402

R, C, K = 0.06, 1.0, 0.16 + 0.12 * 1.0     # alpha = 45 deg: c = cot(alpha) = 1, k = L + W*c
ROLES = Roles("source", "c2w", "w2c", "pose")
PANEL_KEYS = ["path", "error", "velocities", "vy", "wheels", "twist", "theta"]
WHEEL_LABELS = ["w1 front-right", "w2 front-left", "w3 rear-left", "w4 rear-right"]


def make_run(n: int = 101, stop: float = 10.0, drop: tuple[str, ...] = ()):
    """Results and Truth for vx = sin t, vy = cos t, w = 0 (the exact unit circle)."""
    t = np.linspace(0.0, stop, n)
    dt = stop / max(n - 1, 1)
    vx, vy, w = np.sin(t), np.cos(t), np.zeros_like(t)
    cols = {"source.vx": vx, "source.vy": vy, "source.w": w,
            "c2w.w1": (-C * vx + vy + K * w) / R, "c2w.w2": (C * vx + vy - K * w) / R,
            "c2w.w3": (-C * vx + vy - K * w) / R, "c2w.w4": (C * vx + vy + K * w) / R,
            # reconstructed twist lags one sample behind (as a zero-order hold would)
            "w2c.vx": np.sin(t - dt), "w2c.vy": np.cos(t - dt), "w2c.w": w.copy(),
            "pose.x": 1 - np.cos(t), "pose.y": np.sin(t), "pose.theta": np.zeros_like(t)}
    cols = {k: v for k, v in cols.items() if k not in drop and k.split(".")[0] not in drop}
    data = np.empty(n, dtype=[("time", "f8")] + [(k, "f8") for k in cols])
    data["time"] = t
    for k, v in cols.items():
        data[k] = v
    results = Results(tuple(cols), data, "gauss-seidel", 0.0, stop, dt, max(n - 1, 0), 0.1)
    truth = Truth(t, 1 - np.cos(t), np.sin(t), np.zeros_like(t), vx, vy, w)
    return results, truth


def lines_by_label(ax):
    return {line.get_label(): line for line in ax.get_lines()}


@pytest.fixture
def run():
    return make_run()


@pytest.fixture
def figures(run):
    results, truth = run
    return plots.build_figures(results, ROLES, truth, title="circle")


def test_all_panels_in_order(figures):
    assert list(figures) == PANEL_KEYS
    for fig in figures.values():
        assert len(fig.axes) == 1
        assert fig.axes[0].get_title()
        assert all(not line.get_label().startswith("_") for line in fig.axes[0].get_lines())


def test_path_panel(run, figures):
    results, truth = run
    ax = figures["path"].axes[0]
    lines = lines_by_label(ax)
    np.testing.assert_array_equal(lines["simulated"].get_xdata(), results["pose.x"])
    np.testing.assert_array_equal(lines["simulated"].get_ydata(), results["pose.y"])
    np.testing.assert_array_equal(lines["ground truth"].get_xdata(), truth.x)
    np.testing.assert_array_equal(lines["ground truth"].get_ydata(), truth.y)
    assert tuple(lines["start"].get_xydata()[0]) == (0.0, 0.0)
    end = lines["end"].get_xydata()
    assert end.shape == (1, 2)
    np.testing.assert_allclose(end[0], (1.8390715290764525, -0.5440211108893698), rtol=1e-12)
    assert lines["start"].get_marker() not in ("None", "", None)
    assert lines["end"].get_marker() not in ("None", "", None)
    assert ax.get_aspect() == 1.0 and ax.get_adjustable() == "datalim"
    assert ax.get_xlabel() == "x [m] (right)" and ax.get_ylabel() == "y [m] (forward)"
    assert ax.get_legend() is not None
    assert any(gl.get_visible() for gl in ax.xaxis.get_gridlines())


def test_wheels_panel(run, figures):
    results, _ = run
    ax = figures["wheels"].axes[0]
    assert [line.get_label() for line in ax.get_lines()] == WHEEL_LABELS
    # with w = 0, w1 = w3 and w2 = w4: four distinguishable styles, the rear pair drawn over
    styles = {(line.get_linestyle(), line.get_linewidth()) for line in ax.get_lines()}
    assert len(styles) == 4
    lines = ax.get_lines()
    for under, over in zip(lines, lines[1:]):      # each thinner and on top of the one before
        assert over.get_zorder() > under.get_zorder()
        assert over.get_linewidth() < under.get_linewidth() or over.get_linestyle() != "-"
    assert [line.get_linestyle() for line in lines[2:]] == ["--", ":"]
    assert len({line.get_color() for line in lines}) == 4
    t = results.time
    expected = [(np.cos(t) - np.sin(t)) / R, (np.cos(t) + np.sin(t)) / R,
                (np.cos(t) - np.sin(t)) / R, (np.cos(t) + np.sin(t)) / R]
    for line, want in zip(ax.get_lines(), expected):
        np.testing.assert_array_equal(line.get_xdata(), t)
        np.testing.assert_allclose(line.get_ydata(), want, atol=1e-12)
    peak = max(np.abs(line.get_ydata()).max() for line in ax.get_lines())
    assert peak == pytest.approx(np.sqrt(2) / R, rel=1e-3)     # spec: 23.57 rad/s


def test_velocity_panels(run, figures):
    results, _ = run
    t = results.time
    lines = lines_by_label(figures["velocities"].axes[0])
    assert set(lines) == {"vx", "vy", "w"}
    np.testing.assert_array_equal(lines["vx"].get_xdata(), t)
    np.testing.assert_allclose(lines["vx"].get_ydata(), np.sin(t), atol=1e-15)
    np.testing.assert_allclose(lines["vy"].get_ydata(), np.cos(t), atol=1e-15)
    np.testing.assert_array_equal(lines["w"].get_ydata(), 0.0)
    vy = lines_by_label(figures["vy"].axes[0])
    assert list(vy) == ["vy"]
    np.testing.assert_allclose(vy["vy"].get_ydata(), np.cos(t), atol=1e-15)


def test_twist_panel_solid_vs_dashed(run, figures):
    results, _ = run
    lines = lines_by_label(figures["twist"].axes[0])
    for var in ("vx", "vy", "w"):
        cmd, rec = lines[f"{var} commanded"], lines[f"{var} reconstructed"]
        assert cmd.get_linestyle() == "-" and rec.get_linestyle() == "--"
        np.testing.assert_array_equal(cmd.get_ydata(), results[f"source.{var}"])
        np.testing.assert_array_equal(rec.get_ydata(), results[f"w2c.{var}"])
        assert cmd.get_color() == rec.get_color()


@pytest.mark.parametrize("role, gone", [("pose", {"path", "error", "theta"}), ("inverse", {"wheels"}),
                                        ("forward", {"twist"}),
                                        ("source", {"velocities", "vy", "error"})])
def test_missing_role_drops_panel(run, role, gone):
    results, truth = run
    roles = Roles(**{**ROLES.__dict__, role: None})
    figs = plots.build_figures(results, roles, truth)
    assert list(figs) == [k for k in PANEL_KEYS if k not in gone]
    assert len(plots.build_dashboard(results, roles, truth).axes) == len(figs)


def test_unrecorded_columns_drop_panel():
    results, truth = make_run(drop=("c2w", "pose.y"))
    figs = plots.build_figures(results, ROLES, truth)
    assert list(figs) == ["velocities", "vy", "twist", "theta"]


def test_partial_source_columns():
    results, truth = make_run(drop=("source.w",))
    figs = plots.build_figures(results, ROLES, truth)
    assert [l.get_label() for l in figs["velocities"].axes[0].get_lines()] == ["vx", "vy"]
    assert "w commanded" not in lines_by_label(figs["twist"].axes[0])
    assert "w reconstructed" in lines_by_label(figs["twist"].axes[0])


def test_empty_run(tmp_path):
    results, truth = make_run(n=0)
    assert plots.build_figures(results, ROLES, None) == {}
    assert len(plots.build_dashboard(results, ROLES, None).axes) == 0
    assert [p.name for p in plots.write_plots(results, ROLES, None, tmp_path)] == ["dashboard.png"]


def test_path_without_truth():
    results, _ = make_run()
    lines = lines_by_label(plots.build_figures(results, ROLES, None)["path"].axes[0])
    assert "ground truth" not in lines and "simulated" in lines


def test_decimation_keeps_last_point():
    results, truth = make_run(n=20001)
    figs = plots.build_figures(results, ROLES, truth)
    sim = lines_by_label(figs["path"].axes[0])["simulated"]
    x = sim.get_xdata()
    assert len(x) <= plots.MAX_POINTS + 1
    assert x[0] == results["pose.x"][0] and x[-1] == results["pose.x"][-1]
    idx = plots.decimate_index(len(results.time))
    np.testing.assert_array_equal(x, results["pose.x"][idx])
    np.testing.assert_array_equal(sim.get_ydata(), results["pose.y"][idx])
    wheel = figs["wheels"].axes[0].get_lines()[0]
    assert wheel.get_xdata()[-1] == results.time[-1] == 10.0
    assert wheel.get_ydata()[-1] == results["c2w.w1"][-1]


@pytest.mark.parametrize("n", [0, 1, 5000, 5001, 20001, 20003])
def test_decimate_index(n):
    idx = plots.decimate_index(n)
    if n <= plots.MAX_POINTS:
        np.testing.assert_array_equal(idx, np.arange(n))
        return
    assert idx[0] == 0 and idx[-1] == n - 1
    assert len(idx) <= plots.MAX_POINTS + 1 and np.all(np.diff(idx) > 0)


def test_write_plots(run, tmp_path):
    results, truth = run
    before = plt.get_fignums()
    paths = plots.write_plots(results, ROLES, truth, tmp_path / "out", title="circle")
    assert sorted(p.name for p in paths) == sorted(f"{k}.png" for k in ["dashboard"] + PANEL_KEYS)
    for path in paths:
        assert path.parent == tmp_path / "out"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 1000
    assert plt.get_fignums() == before
    dash = plots.build_dashboard(results, ROLES, truth, title="circle")
    assert len(dash.axes) == len(paths) - 1 == len(PANEL_KEYS)
    suptitle = dash.get_suptitle()
    assert "circle" in suptitle and "gauss-seidel" in suptitle and "0.1" in suptitle
    assert sorted(ax.get_title() for ax in dash.axes) == sorted(plots.PANELS[k].title
                                                                for k in PANEL_KEYS)


def test_write_plots_subset(run, tmp_path):
    results, truth = run
    roles = Roles("source", None, None, "pose")
    paths = plots.write_plots(results, roles, truth, tmp_path)
    assert sorted(p.name for p in paths) == ["dashboard.png", "error.png", "path.png", "theta.png",
                                             "velocities.png", "vy.png"]
    assert len(plots.build_dashboard(results, roles, truth).axes) == 5


def test_dashboard_uses_the_panel_drawers(run):
    results, truth = run
    dash = plots.build_dashboard(results, ROLES, truth)
    figs = plots.build_figures(results, ROLES, truth)
    for ax, (key, fig) in zip(dash.axes, figs.items()):
        got = [(l.get_label(), l.get_xydata().tolist()) for l in ax.get_lines()]
        want = [(l.get_label(), l.get_xydata().tolist()) for l in fig.axes[0].get_lines()]
        assert got == want, key


def test_cli_run_writes_dashboard(tmp_path):
    from mecanum_fmu.cli import main
    code = main(["run", str(ROOT / "scenarios" / "circle.yaml"), "--out", str(tmp_path),
                 "--step-size", "0.01", "--quiet"])
    assert code == 0
    for name in ["dashboard"] + PANEL_KEYS:
        path = tmp_path / f"{name}.png"
        assert path.is_file() and path.stat().st_size > 1000, name


# ------------------------------------------------------------------ issue 24, item 5

def frame_of(path):
    """The dashboard frame the plot worker lays out for a bundled scenario (no run needed)."""
    from mecanum_fmu.models.topology import topology
    from mecanum_fmu.report.plot_worker import _frame_hint
    from mecanum_fmu.runner import prepare
    graph = prepare(ROOT / "scenarios" / path)
    return plots.dashboard_frame(*_frame_hint(graph, topology(graph).roles))


def titles(frame):
    return dict(zip(frame.keys, (ax.get_title() for ax in frame.figure.axes)))


def test_theta_panel(run, figures):
    results, truth = run
    ax = figures["theta"].axes[0]
    assert ax.get_ylabel() == "θ [rad]" and "θ" in figures["theta"].axes[0].get_title()
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == [
        "ground truth", "simulated (end 0.000 rad = 0.0°)"]
    np.testing.assert_array_equal(lines[1].get_ydata(), results["pose.theta"])
    low, high = ax.get_ylim()
    assert high - low >= 0.2            # theta = 0 throughout: no zoom into round-off


def test_error_panel_is_the_distance_to_the_truth(run, figures):
    results, truth = run
    ax = figures["error"].axes[0]
    assert ax.get_yscale() == "log"
    distance = ax.get_lines()[0]
    assert distance.get_label().startswith("distance to ground truth [m], end ")
    # pose = truth exactly here: every error sits on the floor of 1e-12, and the panel says so
    np.testing.assert_array_equal(distance.get_ydata(), 1e-12)
    assert any("round-off" in t.get_text() for t in ax.texts)
    results.data["pose.x"] += 0.01                       # 1 cm off everywhere
    ax = plots.build_figures(results, ROLES, truth)["error"].axes[0]
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), 0.01, rtol=1e-9)
    assert not ax.texts


def icr_run(has_icr: float):
    """make_run with the forward block's ICR columns: body (1, 0) when has_icr, else none."""
    results, truth = make_run()
    names = results.names + ("w2c.icr_x", "w2c.icr_y", "w2c.has_icr")
    data = np.empty(len(results.time), dtype=results.data.dtype.descr + [(n, "f8") for n in names[-3:]])
    for name in results.data.dtype.names:
        data[name] = results.data[name]
    data["w2c.icr_x"], data["w2c.icr_y"], data["w2c.has_icr"] = has_icr, 0.0, has_icr
    return Results(names, data, *[getattr(results, f) for f in (
        "master", "start_time", "stop_time", "step_size", "steps", "wall_time")]), truth


def test_icr_panel_says_pure_translation():
    results, truth = icr_run(0.0)
    ax = plots.build_figures(results, ROLES, truth)["icr"].axes[0]
    assert [t.get_text() for t in ax.texts] == ["pure translation: no ICR (w = 0)"]
    assert [line.get_label() for line in ax.get_lines()] == ["path"]
    results, truth = icr_run(1.0)
    ax = plots.build_figures(results, ROLES, truth)["icr"].axes[0]
    assert not ax.texts
    icr = lines_by_label(ax)["ICR"]
    np.testing.assert_allclose(icr.get_xdata(), results["pose.x"] + 1.0)   # theta = 0


def test_closed_loop_shows_path_and_tracking_error_once():
    frame = frame_of("closed_loop/track_circle.yaml")
    assert frame.keys[:2] == ["tracking", "tracking_error"]
    assert "path" not in frame.keys and "error" not in frame.keys
    assert titles(frame)["tracking"] == "Reference path vs actual path"
    assert titles(frame)["tracking_error"] == "Tracking error"
    assert len(set(titles(frame).values())) == len(frame.keys)


def test_omni_dashboard_speaks_in_the_world_frame():
    frame = frame_of("chassis/omni_field_circle.yaml")
    assert titles(frame)["velocities"] == "Input velocities (world frame)"
    assert titles(frame)["vy"] == "vY(t) (world frame)"
    assert {"wheels", "twist", "theta"} <= set(frame.keys)       # no longer two empty cells
    assert len(frame.keys) >= 2 * math.ceil(len(frame.keys) / 2) - 1
    results, truth = make_run()
    roles = Roles("source", None, None, "pose", frame="source", omni_inverse="c2w")
    figs = plots.build_figures(results, roles, truth)
    assert [l.get_label() for l in figs["velocities"].axes[0].get_lines()] == [
        "vX (world)", "vY (world)", "ω"]
    assert [l.get_label() for l in figs["wheels"].axes[0].get_lines()] == [
        "w1 front-left", "w2 rear-left", "w3 rear-right", "w4 front-right"]   # docs/chassis.md


@pytest.mark.parametrize("path", ["circle.yaml", "closed_loop/track_circle.yaml",
                                  "chassis/omni_field_circle.yaml", "chassis/bicycle_circle.yaml",
                                  "modes/showcase.yaml", "profiles/joystick.yaml"])
def test_titles_fit_their_panel(path):
    frame = frame_of(path)
    fig = frame.figure
    renderer = fig.canvas.get_renderer()
    half = fig.bbox.width / 2
    for ax in fig.axes:
        assert ax.title.get_window_extent(renderer).width < 0.9 * half, ax.get_title()
    assert fig._suptitle.get_window_extent(renderer).width < fig.bbox.width


def test_animation_legend_names_the_wheel_arrows():
    from mecanum_fmu.models.modes import geometry_of
    from mecanum_fmu.report.animation import WHEEL_COLORS, build_scene
    results, truth = make_run()
    fig, update, n = build_scene(results, ROLES, truth,
                                 geometry_of({"L": 0.16, "W": 0.12, "R": R}))
    legend = fig.axes[0].get_legend()
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels[-4:] == WHEEL_LABELS and {"ground truth", "path"} <= set(labels)
    assert "rim speed" in legend.get_title().get_text()
    colors = [h.get_color() for h in legend.legend_handles[-4:]]
    assert colors == list(WHEEL_COLORS)
    arrows = fig.axes[0].collections[0]
    np.testing.assert_array_equal(arrows.get_facecolors(),
                                  matplotlib.colors.to_rgba_array(WHEEL_COLORS))


def test_sweep_plots_colour_each_grid_point_with_its_own_truth_and_mean(tmp_path, monkeypatch):
    from mecanum_fmu.sweep import plots as sweep_plots
    from mecanum_fmu.sweep.cluster import prepare_sweep
    from mecanum_fmu.sweep.worker import RunResult
    path = tmp_path / "s.yaml"
    path.write_text(f"name: s\nscenario: {ROOT / 'scenarios' / 'circle.yaml'}\n"
                    "grid:\n  source.w_expr: ['0', '0.5']\n"
                    "random:\n  samples: 4\n  seed: 1\n  w2c.dR1: {normal: [0.0, 0.0003]}\n")
    sweep, graph, runs = prepare_sweep(path)
    assert len(runs) == 8
    results, errors = {}, {}
    for r in runs:                      # made-up end points and errors, 4 per grid point
        point, k = divmod(r.index, 4)
        ends = {"pose.x": [1.0, 3.0][point] + 0.1 * k, "pose.y": [0.0, 2.0][point]}
        results[r.index] = RunResult(r.index, "ok", "", ends, np.zeros((3, 2)) + point, 0.1, 0.1)
        errors[r.index] = {"error.position": [0.001, 0.01][point] * (k + 1)}
    drawn = {}

    def keep(fig, out):                 # the figure as it is saved, before it is cleared
        drawn[out.name] = fig
        return out
    monkeypatch.setattr(sweep_plots, "_save", keep)
    sweep_plots.write_sweep_plots(tmp_path, sweep, graph, runs, results, errors)

    ax = drawn["end_points.png"].axes[0]
    dots = ax.collections
    assert len(dots) == 2 and not np.allclose(dots[0].get_facecolor(), dots[1].get_facecolor())
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "source.w_expr=0: 4 end points" in labels and "source.w_expr=0.5: 4 end points" in labels
    assert "mean (1.1500, 0.0000)" in labels and "mean (3.1500, 2.0000)" in labels
    stars = [line for line in ax.get_lines() if line.get_marker() == "*"]
    assert len(stars) == 2                                      # a truth per grid point
    np.testing.assert_allclose(stars[0].get_xydata()[0], (1.8390715, -0.5440211), atol=1e-6)
    assert np.hypot(*(stars[1].get_xydata()[0] - stars[0].get_xydata()[0])) > 0.1

    ax = drawn["error_histogram.png"].axes[0]
    assert ax.get_title() == "s: end-point error"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["source.w_expr=0: mean 2.50 mm, max 4.00 mm",
                      "source.w_expr=0.5: mean 25.00 mm, max 40.00 mm"]

    ax = drawn["paths.png"].axes[0]
    truths = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert len(truths) == 2 and not np.allclose(truths[0].get_xydata(), truths[1].get_xydata())
    for fig in drawn.values():                                  # titles that fit
        ax = fig.axes[0]
        fig.canvas.draw()
        assert ax.title.get_window_extent().width < fig.bbox.width * 0.95, ax.get_title()


@pytest.mark.parametrize("offset", [0.0, 1e-9, 1e-6, 1e-3, 1e-12])
def test_minor_log_ticks_are_matplotlibs_own_pixels(run, offset):
    """The error panel draws its log axis' minor ticks as one line of markers: the same
    pixels as matplotlib's own minor ticks, for errors of many sizes (none past ten decades)."""
    from matplotlib import ticker
    from mecanum_fmu.report import panels
    results, truth = run
    truth = Truth(truth.time, truth.x + offset * truth.time, truth.y,
                  truth.theta + offset * np.sin(truth.time), truth.vx, truth.vy, truth.w)

    def pixels(own_ticks: bool):
        with matplotlib.rc_context(plots.DRAW_RC):   # as drawn on the dashboard, in its cell
            fig = plots.build_dashboard(results, ROLES, truth)
            ax = fig.axes[PANEL_KEYS.index("error")]
            if own_ticks:                     # matplotlib's minor ticks back, ours gone
                mark = next(a for a in ax.artists if isinstance(a, panels.MinorLogTicks))
                ax.yaxis.set_minor_locator(mark._locator)
                ax.yaxis.set_minor_formatter(ticker.NullFormatter())
                mark.remove()
            fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba()).copy(), ax

    ours, ax = pixels(False)
    theirs, ax_theirs = pixels(True)
    assert len(ax.yaxis.get_minorticklocs()) == 0            # no Tick objects of ours
    assert np.array_equal(ours, theirs)
    if offset in (0.0, 1e-6):
        assert len(ax_theirs.yaxis.get_minorticklocs()) > 20   # there were ticks to draw


def test_a_recording_is_a_panel_pair_of_the_dashboard(run):
    """A scenario's `recorded:` (docs/bags.md): the dashboard holds recorded.png's two panels.
    The recording is the closed-form circle 0.1 m ahead (+Y), so the error panel is 0.1 m."""
    results, truth = run
    t = np.linspace(0.0, 10.0, 41)
    table = "time,x,y\n" + "".join(f"{a!r},{1 - math.cos(a)!r},{math.sin(a) + 0.1!r}\n"
                                   for a in t.tolist())
    roles = dataclasses.replace(ROLES, recorded=(("pose", table),))
    frame = plots.build_figures(results, roles, truth, title="circle")
    pair = ["recorded_path", "recorded_error"]
    assert list(frame)[:len(PANEL_KEYS) + 2] == PANEL_KEYS[:2] + pair + PANEL_KEYS[2:]
    path = lines_by_label(frame["recorded_path"].axes[0])
    assert np.allclose(path["pose: recorded"].get_ydata(), np.sin(t) + 0.1)
    err = frame["recorded_error"].axes[0]
    (line,) = err.get_lines()
    # the circle read linearly between 0.25 s rows: off by at most dt^2/8 = 7.8e-3 m
    assert np.allclose(line.get_ydata(), 0.1, atol=7.9e-3) and err.get_yscale() == "log"
    assert line.get_label().startswith("pose, end 1.00e-01")
    dash = plots.build_dashboard(results, roles, truth, title="circle")
    titles = [ax.get_title() for ax in dash.axes]
    assert "Recorded against simulated" in titles and "Simulated minus recorded" in titles
    # without a recording neither panel is drawn
    assert "recorded_path" not in plots.build_figures(results, ROLES, truth, title="circle")
