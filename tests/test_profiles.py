"""Velocity profiles from tables and segments (issue 15, parts 1 and 2).

Reference values: hand-computed interpolation, np.interp, closed-form paths (SPEC.md
section 4 with a piecewise-constant or piecewise-linear twist), and the nested-where()
showcase that the segments replace.
"""
import math
import re
import zipfile

import numpy as np
import pytest

from helpers import ROOT, run_host_or_skip, write_scenario
from mecanum_fmu import master
from mecanum_fmu.models.blocks.profile_table import TableError, parse_table, table_sampler
from mecanum_fmu.runner import prepare, run

SOURCE_TO_POSE = """\
  pose: {fmu: PoseIntegrator}
connections:
  - [source.vx, pose.vx]
  - [source.vy, pose.vy]
  - [source.w,  pose.w]
"""
TABLE = """\
# a comment, then the header in another order with a column we ignore
w, time, vy, buttons, vx
0.0, 0.0, 0.0, 1, 0.0
0.5, 1.0, 0.2, 0, 0.4
0.5, 3.0, 0.2, 0, -0.2
"""


def table_scenario(folder, interpolation, stop=4.0, step=0.25, table="profile.csv"):
    (folder / "tables").mkdir(exist_ok=True)
    (folder / "tables" / table).write_text(TABLE)
    text = (f"name: tab_{interpolation}\n"
            f"experiment: {{start_time: 0.0, stop_time: {stop}, step_size: {step}}}\n"
            "components:\n"
            f"  source: {{fmu: VelocitySource, parameters: {{table: tables/{table}, "
            f"interpolation: {interpolation}}}}}\n" + SOURCE_TO_POSE)
    return write_scenario(folder, f"tab_{interpolation}", text)


# ------------------------------------------------------------------ the table block


def test_parse_table_picks_the_named_columns_in_any_order():
    times, vx, vy, w = parse_table(TABLE)
    assert times == [0.0, 1.0, 3.0]
    assert vx == [0.0, 0.4, -0.2] and vy == [0.0, 0.2, 0.2] and w == [0.0, 0.5, 0.5]


def test_linear_and_hold_sampling_by_hand():
    lin, hold = table_sampler(TABLE, "linear"), table_sampler(TABLE, "hold")
    assert lin(0.5) == pytest.approx((0.2, 0.1, 0.25))           # halfway 0 -> 1 s
    assert lin(2.0) == pytest.approx((0.1, 0.2, 0.5))            # halfway 1 -> 3 s
    assert hold(0.5) == (0.0, 0.0, 0.0) and hold(2.0) == (0.4, 0.2, 0.5)
    assert hold(1.0) == (0.4, 0.2, 0.5)                          # a row holds from its time on
    for sample in (lin, hold):                                   # end values held
        assert sample(-3.0) == (0.0, 0.0, 0.0)
        assert sample(3.0) == sample(99.0) == (-0.2, 0.2, 0.5)


@pytest.mark.parametrize("text, line, words", [
    ("", 0, "empty"),
    ("time,vx,vy\n0,0,0\n", 1, "lacks the column(s) w"),
    ("time,vx,vy,w\n", 1, "header but no rows"),
    ("time,vx,vy,w\n0,0,0,0\n\n1,0,x,0\n", 4, "vy = 'x' is not a number"),
    ("time,vx,vy,w\n0,0,0,0\n0,1,0,0\n", 3, "does not increase"),
    ("time,vx,vy,w\n0,0,0,0\n-1,1,0,0\n", 3, "does not increase"),
    ("time,vx,vy,w\n0,0,nan,0\n", 2, "not a finite number"),
    ("time,vx,vy,w\n0,0,0\n", 2, "has 3 cells"),
])
def test_bad_tables_name_their_line(text, line, words):
    with pytest.raises(TableError, match=re.escape(words)) as info:
        parse_table(text)
    assert info.value.line == line


def test_unknown_interpolation():
    with pytest.raises(TableError, match="use linear or hold"):
        table_sampler(TABLE, "cubic")


# ------------------------------------------------------------------ table sources in a run


def test_the_fmu_gets_the_table_text_not_the_path(fmu_dir, tmp_path):
    graph = prepare(table_scenario(tmp_path, "linear"), fmu_dir=fmu_dir)
    values = graph.instance("source").start_values
    assert values["table"] == TABLE and values["interpolation"] == "linear"


@pytest.mark.parametrize("interpolation", ["linear", "hold"])
def test_table_source_outputs_at_the_communication_points(fmu_dir, tmp_path, interpolation):
    graph = prepare(table_scenario(tmp_path, interpolation, stop=4.0, step=0.25), fmu_dir=fmu_dir)
    res = master.simulate(graph, graph.scenario.experiment)
    t = res.time
    times = np.array([0.0, 1.0, 3.0])
    for name, column in (("vx", [0.0, 0.4, -0.2]), ("vy", [0.0, 0.2, 0.2]), ("w", [0, 0.5, 0.5])):
        if interpolation == "linear":
            expected = np.interp(t, times, column)
        else:
            expected = np.asarray(column)[np.searchsorted(times, t, side="right") - 1]
        np.testing.assert_allclose(res[f"source.{name}"], expected, rtol=0, atol=1e-15)


def test_ground_truth_of_a_table_is_the_closed_form_path(fmu_dir, tmp_path):
    """Linear table with w = 0: vx = 0.4 t on [0, 1], then 0.4 - 0.3 (t - 1) on [1, 3], then
    -0.2; vy = 0.2 t then 0.2. Integrated by hand at t = 4:
    x = 0.2 + (0.4*2 - 0.3*2) + (-0.2) = 0.2,  y = 0.1 + 0.2*3 = 0.7."""
    text = TABLE.replace("0.5, 1.0", "0.0, 1.0").replace("0.5, 3.0", "0.0, 3.0")
    (tmp_path / "tables").mkdir()
    (tmp_path / "tables" / "w0.csv").write_text(text)
    scenario = table_scenario(tmp_path, "linear")
    scenario.write_text(scenario.read_text().replace("profile.csv", "w0.csv"))
    outcome = run(prepare(scenario, fmu_dir=fmu_dir), tmp_path / "out", plots=False,
                  log=lambda line: None)
    assert outcome.truth.end == pytest.approx((0.2, 0.7, 0.0), abs=1e-9)
    # the quadratic (default) and trapezoidal masters integrate piecewise-linear inputs exactly
    # when the kinks fall on steps (they do: h = 0.25); the quadratic one through its limiter
    assert outcome.summary["end_pose"]["x"] == pytest.approx(0.2, abs=1e-12)
    assert outcome.summary["end_pose"]["y"] == pytest.approx(0.7, abs=1e-12)


def test_a_hold_table_with_a_turn_has_the_arc_as_ground_truth(fmu_dir, tmp_path):
    """Hold: (vx, vy, w) = 0 for t < 1, then (0.4, 0.2, 0.5) up to t = 3, then (-0.2, 0.2, 0.5).
    Constant twists are arcs (SPEC.md section 4): integrate them in closed form."""
    outcome = run(prepare(table_scenario(tmp_path, "hold"), fmu_dir=fmu_dir), tmp_path / "o",
                  plots=False, log=lambda line: None)
    pose = np.zeros(3)
    for (vx, vy, w), duration in (((0.4, 0.2, 0.5), 2.0), ((-0.2, 0.2, 0.5), 1.0)):
        th0, th1 = pose[2], pose[2] + w * duration
        # x' = vx cos - vy sin, y' = vx sin + vy cos with theta = th0 + w t
        pose += ((vx * (math.sin(th1) - math.sin(th0)) + vy * (math.cos(th1) - math.cos(th0))) / w,
                 (-vx * (math.cos(th1) - math.cos(th0)) + vy * (math.sin(th1) - math.sin(th0))) / w,
                 w * duration)
    assert outcome.truth.end == pytest.approx(tuple(pose), abs=1e-9)


# ------------------------------------------------------------------ segments


def test_segments_become_a_hold_table_ending_at_rest(fmu_dir, tmp_path):
    text = ("name: segs\nexperiment: {start_time: 0.0, stop_time: 6.0, step_size: 0.5}\n"
            "components:\n  source: {fmu: VelocitySource, segments: "
            "[{duration: 1}, {duration: 2, vy: 0.3}, {duration: 2, vx: -0.3}]}\n" + SOURCE_TO_POSE)
    graph = prepare(write_scenario(tmp_path, "segs", text), fmu_dir=fmu_dir)
    values = graph.instance("source").start_values
    assert values["interpolation"] == "hold"
    assert list(parse_table(values["table"])) == [[0.0, 1.0, 3.0, 5.0], [0.0, 0.0, -0.3, 0.0],
                                                  [0.0, 0.3, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]
    res = master.simulate(graph, graph.scenario.experiment)
    t = res.time
    np.testing.assert_array_equal(res["source.vy"], np.where((t >= 1) & (t < 3), 0.3, 0.0))
    np.testing.assert_array_equal(res["source.vx"], np.where((t >= 3) & (t < 5), -0.3, 0.0))
    assert (res.final("pose.x"), res.final("pose.y")) == pytest.approx((-0.6, 0.6), abs=1e-12)


WHERE_SOURCE = (
    '  source: {fmu: VelocitySource, parameters: {'
    'vx_expr: "where(t < 1, 0, where(t < 3, 0, where(t < 5, -0.3, where(t < 7, 0, where(t < 9, '
    '0.3, where(t < 11, -0.3, where(t < 13, 0, where(t < 15, 0, 0))))))))", '
    'vy_expr: "where(t < 1, 0, where(t < 3, 0.3, where(t < 5, 0, where(t < 7, -0.3, where(t < 9, '
    '0, where(t < 11, 0.3, where(t < 13, 0, where(t < 15, 0, 0))))))))", '
    'w_expr: "where(t < 1, 0, where(t < 3, 0, where(t < 5, 0, where(t < 7, 0, where(t < 9, 0, '
    'where(t < 11, 0, where(t < 13, 0.8, where(t < 15, -0.8, 0))))))))"}}\n')


def showcase_jump_bound(h):
    """How far the segments' results may be from the nested-where version's (docs/closed-loop.md,
    "Segments against where()"). Both sample the same piecewise-constant twist at the
    communication points; a sample can only differ where a segment start and the where()
    threshold differ by rounding and a step lands between them. One such sample moves the
    trapezoidal hold of the two steps that use it by h/2 |jump| each: at most h |dv| in
    position per translation jump and h |dw| in heading per turn jump, which turns the rest of
    the path (up to |v| T_rest each)."""
    jumps_v = [(0, .3), (-.3, -.3), (.3, -.3), (.3, .3), (-.6, .3), (.3, -.3)]   # at 1..11 s
    jumps_w = [(0.8, 16 - 11), (1.6, 16 - 13), (0.8, 16 - 15)]                    # at 11, 13, 15 s
    speed = math.hypot(0.3, 0.3)
    return h * sum(math.hypot(*j) for j in jumps_v) + sum(h * dw * speed * rest
                                                           for dw, rest in jumps_w)


def test_showcase_segments_agree_with_the_nested_where_version(fmu_dir, tmp_path):
    path = ROOT / "scenarios" / "modes" / "showcase.yaml"
    text = path.read_text()
    start = text.index("  source:\n")
    end = text.index("  c2w:")
    where = write_scenario(tmp_path, "showcase_where", text[:start] + WHERE_SOURCE + text[end:])
    runs = {}
    for key, scenario in (("segments", path), ("where", where)):
        graph = prepare(scenario, fmu_dir=fmu_dir)
        runs[key] = master.simulate(graph, graph.scenario.experiment)
    h = runs["where"].step_size
    seg, ref = runs["segments"], runs["where"]
    gap = np.max(np.hypot(seg["pose.x"] - ref["pose.x"], seg["pose.y"] - ref["pose.y"]))
    assert gap <= showcase_jump_bound(h)
    # here every segment start is the where() threshold exactly, so the samples are the same
    for name in ("source.vx", "source.vy", "source.w", "pose.x", "pose.y", "pose.theta"):
        np.testing.assert_array_equal(seg[name], ref[name])


# ------------------------------------------------------------------ recorded-style example


def test_recorded_joystick_table_against_its_expressions(fmu_dir):
    """scenarios/profiles/joystick.csv samples the formulas of joystick_expressions.yaml at
    20 Hz with 4 decimals. Per channel the table is off by at most dt^2/8 |v''| (linear
    interpolation) + 5e-5 (rounding); over T = 12 s that bounds the position by
    T sqrt(2) e_v + |v|max T (T e_w) (the heading error turns the path)."""
    folder = ROOT / "scenarios" / "profiles"
    ends = {}
    for name in ("joystick", "joystick_expressions"):
        graph = prepare(folder / f"{name}.yaml", fmu_dir=fmu_dir)
        res = master.simulate(graph, graph.scenario.experiment)
        ends[name] = [res.final(f"pose.{k}") for k in ("x", "y", "theta")]
    dt, T = 0.05, 12.0
    e_v = dt ** 2 / 8 * max(0.25 * 0.6 ** 2, 0.35 * 0.4 ** 2) + 5e-5
    e_w = dt ** 2 / 8 * 0.3 * 0.25 ** 2 + 5e-5
    v_max = math.hypot(0.25, 0.7)
    a, b = ends["joystick"], ends["joystick_expressions"]
    assert abs(a[2] - b[2]) <= T * e_w
    assert math.dist(a[:2], b[:2]) <= T * math.sqrt(2) * e_v + v_max * T * (T * e_w)
    assert math.dist(a[:2], b[:2]) > 0      # they are different inputs


# ------------------------------------------------------------------ the table in another host


def test_the_table_travels_in_the_ssp_and_runs_in_libcosim(fmu_dir, tmp_path):
    from mecanum_fmu.interop.cross_check import TOLERANCE, compared_outputs, difference, ours_jacobi
    from mecanum_fmu.interop.ssp_write import export_ssp
    scenario = table_scenario(tmp_path, "linear", stop=4.0, step=0.05)
    graph = prepare(scenario, fmu_dir=fmu_dir)
    ssp = export_ssp(graph, tmp_path / "table.ssp")
    (tmp_path / "tables" / "profile.csv").unlink()       # nothing to look up at run time
    with zipfile.ZipFile(ssp) as zf:
        assert not [n for n in zf.namelist() if n.endswith(".csv")]
    names = compared_outputs(graph)
    ours = ours_jacobi(graph, names)
    other = run_host_or_skip("libcosim", ssp, start=0.0, stop=4.0, step=0.05, variables=names)
    assert difference(other.values, ours.values, names) <= TOLERANCE
    # and the table was used: the source's end values are the table's last row, not the
    # default expressions (sin 4, cos 4, 0)
    assert (other.values["source.vx"], other.values["source.vy"], other.values["source.w"]) == \
        pytest.approx((-0.2, 0.2, 0.5), abs=1e-15)
