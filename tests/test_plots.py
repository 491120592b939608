"""Tests for the plots: figure contents against a hand-made run of the seed scenario
(docs/spec.md, Expected results)."""
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
