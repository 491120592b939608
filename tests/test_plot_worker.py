"""The fast plot path (issue 11, item 8; issue 20, item 5): each panel's PNG is cut whole from
the one drawn dashboard, the drawing runs in a worker process in two stages (every panel but the
ground truth's as soon as the results exist, the truth's when it does), a failing worker costs
only the plots, and `validate` loads neither matplotlib nor scipy."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from dataclasses import replace
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from matplotlib.image import imread

from helpers import ROOT, test_fmus, write_scenario
from test_plots import PANEL_KEYS, ROLES, make_run
from mecanum_fmu.report import plots
from mecanum_fmu.report.plot_worker import PlotFailed, PlotWorker

CIRCLE = ROOT / "scenarios" / "circle.yaml"


def judged(roles, truth):
    """What the worker reads of a run's Evaluation: its roles and the single pose's truth."""
    return SimpleNamespace(roles=roles, truth=truth)


def find_in(big: np.ndarray, small: np.ndarray) -> list[tuple[int, int]]:
    """Every (row, column) where `small` appears pixel for pixel in `big` (RGBA uint8)."""
    h, w = small.shape[:2]
    mid = h // 2
    needle = small[mid].tobytes()
    found = []
    for y in range(mid, big.shape[0] - (h - mid) + 1):
        row, start = big[y].tobytes(), 0
        while (at := row.find(needle, start)) >= 0:
            if at % big.shape[2] == 0 and at // big.shape[2] <= big.shape[1] - w:
                x = at // big.shape[2]
                if np.array_equal(big[y - mid:y - mid + h, x:x + w], small):
                    found.append((y - mid, x))
            start = at + 1
    return found


def ink(pixels: np.ndarray) -> np.ndarray:
    return (pixels[..., :3] < 255).any(axis=2)       # not the white background


@pytest.fixture(scope="module")
def drawn_here(tmp_path_factory) -> list:
    """The PNGs of make_run() drawn in this process, once for the module: the reference the
    worker's files are compared with byte for byte (make_run's data are fixed)."""
    results, truth = make_run()
    return plots.write_plots(results, ROLES, truth, tmp_path_factory.mktemp("plots"),
                             title="circle")


@pytest.fixture(scope="module")
def written(drawn_here):
    return {p.stem: np.round(imread(p) * 255).astype(np.uint8) for p in drawn_here}


def test_every_panel_is_a_whole_piece_of_the_dashboard(written):
    dash = written["dashboard"]
    assert sorted(written) == sorted(PANEL_KEYS + ["dashboard"])
    places = []
    for key, panel in written.items():
        if key == "dashboard":
            continue
        h, w = panel.shape[:2]
        # two columns, three rows: a panel is a bit less than a cell of the dashboard
        assert 0.4 * dash.shape[1] < w <= dash.shape[1] / 2, key
        assert 0.2 * dash.shape[0] < h <= dash.shape[0] / 3, key
        assert ink(panel).mean() > 0.05, key                # drawn, not blank
        found = find_in(dash, panel)
        assert len(found) == 1, (key, found)                # cut from the dashboard, once
        places.append((found[0], (h, w)))
        # nothing cut off: the outermost rows and columns are background
        edge = ink(panel)
        assert not edge[0].any() and not edge[-1].any(), key
        assert not edge[:, 0].any() and not edge[:, -1].any(), key
    for i, ((y, x), (h, w)) in enumerate(places):           # no two panels share pixels
        for (y2, x2), (h2, w2) in places[i + 1:]:
            assert y + h <= y2 or y2 + h2 <= y or x + w <= x2 or x2 + w2 <= x


def test_the_dashboard_is_not_blank_and_has_the_panels(written):
    dash = written["dashboard"]
    assert dash.shape[1] == plots.DASHBOARD_SIZE[0] * plots.DPI
    assert ink(dash).mean() > 0.05


def test_worker_writes_the_same_files_as_drawing_here(drawn_here, tmp_path):
    results, truth = make_run()
    there = PlotWorker.start().finish(results, judged(ROLES, truth), tmp_path / "there", title="circle")
    assert [p.name for p in there] == [p.name for p in drawn_here]
    for a, b in zip(drawn_here, there):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_worker_failure_is_reported_with_its_reason(tmp_path):
    results, truth = make_run()
    (tmp_path / "dashboard.png").mkdir()                    # cannot be written
    with pytest.raises(PlotFailed, match="dashboard.png"):
        PlotWorker.start().finish(results, judged(ROLES, truth), tmp_path)


def test_cancelled_worker_ends():
    """The worker waits for its first message on stdin, so it is still running when cancelled;
    cancel kills it, waits for it (no zombie) and drops it, so a later finish draws here."""
    worker = PlotWorker.start()
    proc = worker._proc
    assert proc is not None and proc.poll() is None     # started, blocked reading its stdin
    worker.cancel()
    assert proc.returncode == -signal.SIGKILL           # killed and waited for
    assert proc.stdin.closed and proc.stdout.closed
    assert worker._proc is None
    worker.cancel()                                     # a second cancel does nothing


def test_failed_run_keeps_the_tables_and_writes_no_plots(tmp_path, tmp_path_factory):
    """A run whose FMU fails mid-way (fresh process, plots on): exit 1, the rows up to the
    failure are kept, the worker is stopped without drawing."""
    breaker = test_fmus(tmp_path_factory)["mtest_failing"]
    scenario = write_scenario(tmp_path, "fails", f"""\
name: fails
experiment: {{start_time: 0.0, stop_time: 10.0, step_size: 0.1, master: gauss-seidel}}
components:
  source: {{fmu: VelocitySource}}
  breaker: {{fmu: {breaker}, parameters: {{mode: 0}}}}
  pose: {{fmu: PoseIntegrator}}
connections: [[source.vx, pose.vx], [source.vy, pose.vy], [source.w, pose.w]]
""")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "run", str(scenario), "--out",
                           str(out)], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "breaker" in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["results.csv", "summary.json"]
    assert len((out / "results.csv").read_text().splitlines()) > 40     # rows up to t = 5 s


def test_validate_loads_neither_matplotlib_nor_scipy(fmu_dir):
    code = ("import json, sys\n"
            "from mecanum_fmu.cli import main\n"
            f"code = main(['validate', {str(CIRCLE)!r}, '--fmu-dir', {str(fmu_dir)!r}])\n"
            "print(json.dumps([code, sorted(sys.modules)]))\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    exit_code, modules = json.loads(proc.stdout.splitlines()[-1])
    assert exit_code == 0 and ": ok - 4 components" in proc.stdout
    heavy = [m for m in modules if m.split(".")[0] in ("matplotlib", "scipy", "PIL")]
    assert heavy == []
    ours = {m for m in modules if m.startswith("mecanum_fmu.")}
    assert {"mecanum_fmu.scenario.graph", "mecanum_fmu.scenario.document"} <= ours  # it validated
    assert not ours & {"mecanum_fmu.report.plots", "mecanum_fmu.master", "mecanum_fmu.report.animation"}


def test_the_frame_drawn_before_the_run_ends_fits_the_run(fmu_dir, tmp_path):
    """The worker builds the dashboard's frame from the graph alone; for the seed circle it
    has the run's six panels and title, and drawing into it gives the same bytes."""
    from mecanum_fmu.report.plot_worker import _frame_hint
    from mecanum_fmu.runner import prepare, run
    graph = prepare(CIRCLE, fmu_dir=fmu_dir)
    outcome = run(graph, tmp_path / "run", plots=False)
    stand_in, roles, title = _frame_hint(graph, outcome.evaluation.roles)
    frame = plots.dashboard_frame(stand_in, roles, title)
    assert frame.keys == plots.available_panels(outcome.results, roles) == PANEL_KEYS + ["icr"]
    assert frame.figure.get_suptitle() == "circle - quadratic, step 0.05 s"
    here = plots.write_plots(outcome.results, roles, outcome.truth, tmp_path / "here", title)
    worker = PlotWorker.start()
    worker.expect(graph, roles)
    there = worker.finish(outcome.results, outcome.evaluation, tmp_path / "there", title)
    assert [p.name for p in there] == [p.name for p in here]
    for a, b in zip(here, there):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_without_a_worker_the_plots_are_drawn_here(tmp_path):
    """No worker process (it could not start): finish() draws in this process instead."""
    results, truth = make_run()
    paths = PlotWorker(None).finish(results, judged(ROLES, truth), tmp_path, title="circle")
    assert sorted(p.name for p in paths) == sorted(f"{k}.png" for k in ["dashboard"] + PANEL_KEYS)
    assert all(p.stat().st_size > 1000 for p in paths)


def drawn(ax) -> list:
    """What a panel drew: each line's label and points, each text (notes), the y scale."""
    return ([(line.get_label(), line.get_xydata().tolist()) for line in ax.get_lines()]
            + [text.get_text() for text in ax.texts] + [ax.get_yscale()])


@pytest.mark.parametrize("roles", [ROLES, replace(ROLES, follower="source")],
                         ids=["open loop", "closed loop"])
def test_the_panels_marked_truth_are_those_that_draw_it(roles):
    """The draft draws the panels not marked `truth` before the truth exists: each of them
    must draw the same with and without it, and each marked one must draw it."""
    results, truth = make_run()
    keys = plots.available_panels(results, roles)
    assert {k for k in keys if plots.PANELS[k].truth} == (
        {"tracking", "tracking_error", "theta"} if roles.follower else {"path", "error", "theta"})
    for key in keys:
        with_truth, without = (plots.new_figure((4, 3)).add_subplot() for _ in range(2))
        plots.PANELS[key].draw(with_truth, results, roles, truth)
        plots.PANELS[key].draw(without, results, roles, None)
        assert (drawn(with_truth) != drawn(without)) == plots.PANELS[key].truth, key


def test_two_stages_give_the_pixels_of_one_whole_draw():
    """The draft leaves the truth's cells empty; the finish draws them in: the dashboard is,
    pixel for pixel, the one drawn at once with every panel."""
    results, truth = make_run()
    with matplotlib.rc_context(plots.DRAW_RC):
        whole = plots.build_dashboard(results, ROLES, truth, title="circle")
        whole.canvas.draw()
    want = np.asarray(whole.canvas.buffer_rgba()).copy()
    draft = plots.draft_dashboard(results, ROLES, "circle")
    assert sorted(draft.pngs) == sorted(k for k in PANEL_KEYS if not plots.PANELS[k].truth)
    early = np.asarray(draft.frame.figure.canvas.buffer_rgba()).copy()
    for ax, key in zip(draft.frame.figure.axes, draft.frame.keys):
        box = ax.get_window_extent()          # the axes' own area: blank until the truth
        rows = slice(early.shape[0] - int(box.y1) + 2, early.shape[0] - int(box.y0) - 2)
        cell = early[rows, int(box.x0) + 2:int(box.x1) - 2]
        assert ink(cell).any() != plots.PANELS[key].truth, key
    pngs = plots.finish_dashboard(draft, truth)
    got = np.asarray(draft.frame.figure.canvas.buffer_rgba())
    assert np.array_equal(got, want)
    assert list(pngs) == ["dashboard"] + PANEL_KEYS


def test_a_draft_sent_before_the_truth_gives_the_same_files(drawn_here, tmp_path):
    results, truth = make_run()
    worker = PlotWorker.start()
    worker.draft(results, ROLES, "circle")
    there = worker.finish(results, judged(ROLES, truth), tmp_path / "there", title="circle")
    assert [p.name for p in there] == [p.name for p in drawn_here]
    for a, b in zip(drawn_here, there):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_cancel_while_a_large_draft_is_still_being_written():
    """The draft is written from a thread (the worker may still be importing matplotlib);
    a cancel then kills the worker, the write fails and the thread ends."""
    results, _ = make_run(n=400_000)           # ~45 MB pickled: far more than a pipe holds
    worker = PlotWorker.start()
    proc = worker._proc
    worker.draft(results, ROLES, "circle")
    writer = worker._writer
    assert writer is not None
    worker.cancel()
    assert proc.returncode == -signal.SIGKILL
    assert not writer.is_alive() and worker._proc is None
