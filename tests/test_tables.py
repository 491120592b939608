"""Tables under the input-file rules, logs as they come, and O(log n) lookup (issue 23 item 2,
issue 24 item 2).

Reference values: tables written here with known rows (parsing must give them back), np.interp,
unit factors by hand (1 deg = pi/180 rad, 1 mm = 1e-3 m, 1 ms = 1e-3 s), and counts of the
work done (elements read by the bisection, solver calls), never the code's own outputs.
"""
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import ROOT, child_env, write_scenario
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.models.blocks import profile_table
from mecanum_fmu.models.blocks.profile_table import (MAX_LINE, MAX_REPORTED, TableError,
                                                     parse_table, table_sampler)
from mecanum_fmu.models.commanded import table_twist
from mecanum_fmu.scenario.tables import read_table
from mecanum_fmu.scenario.document import load_scenario

SOURCE = """\
experiment: {{start_time: 0.0, stop_time: 2.0, step_size: 0.1}}
components:
  source: {{fmu: VelocitySource, {spec}}}
  pose: {{fmu: PoseIntegrator}}
connections:
  - [source.vx, pose.vx]
  - [source.vy, pose.vy]
  - [source.w,  pose.w]
"""


def source_scenario(folder, spec, name="tab"):
    return write_scenario(folder, name, SOURCE.format(spec=spec))


def problems_of(path):
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    return [str(p) for p in info.value.problems]


# ------------------------------------------------------------------ the file rules


def test_a_device_is_refused_before_reading(tmp_path):
    messages = problems_of(source_scenario(tmp_path, "parameters: {table: /dev/zero}"))
    assert len(messages) == 1 and "is not a regular file" in messages[0]


def test_a_fifo_is_refused_without_hanging(tmp_path):
    os.mkfifo(tmp_path / "log.csv")
    path = source_scenario(tmp_path, "parameters: {table: log.csv}")
    # in a child: a hang would be a timeout (a failure), not a stuck test run
    proc = subprocess.run([sys.executable, "-m", "mecanum_fmu", "validate", str(path)],
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, **child_env()})
    assert proc.returncode == 2 and "is not a regular file" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_file_over_the_size_limit_is_refused_by_its_size(tmp_path):
    with open(tmp_path / "big.csv", "wb") as f:       # sparse: nothing is written
        f.truncate(3_000_000_000)
    messages = problems_of(source_scenario(tmp_path, "parameters: {table: big.csv}"))
    assert "3000000000 bytes is too large" in messages[0]


def test_a_long_line_is_refused_before_it_is_copied():
    text = "time,vx,vy,w\n0,0,0," + "1" * (MAX_LINE + 10) + "\n"
    with pytest.raises(TableError, match=f"longer than {MAX_LINE} characters") as info:
        parse_table(text)
    assert info.value.line == 2


def test_a_byte_order_mark_is_accepted(tmp_path):
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbftime,vx,vy,w\r\n0,0.5,0,0\r\n1,0.5,0,0\r\n")
    scenario = load_scenario(source_scenario(tmp_path, "parameters: {table: bom.csv}"))
    assert parse_table(scenario.components[0].parameters["table"])[1] == [0.5, 0.5]
    assert parse_table("\ufefftime,vx,vy,w\n0,1,2,3\n") == [[0.0], [1.0], [2.0], [3.0]]


def test_a_file_outside_the_folder_is_read_but_never_quoted(tmp_path):
    secret = "root:x:0:0:SECRET-HEADER"
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "passwd").write_text(f"{secret}\nmore:SECRET-LINE\n")
    (outside / "cells.csv").write_text("time,vx,vy,w\n0,SECRET-CELL,0,0\n")
    (outside / "good.csv").write_text("time,vx,vy,w\n0,0.25,0,0\n")
    inside = tmp_path / "scenario"
    inside.mkdir()
    for table in ("passwd", "cells.csv"):
        messages = problems_of(source_scenario(inside, f"parameters: {{table: ../elsewhere/"
                                                       f"{table}}}"))
        assert messages and not any("SECRET" in m for m in messages), messages
    assert "lacks the column(s) time" in problems_of(source_scenario(
        inside, "parameters: {table: ../elsewhere/passwd}"))[0]
    good = load_scenario(source_scenario(inside, "parameters: {table: ../elsewhere/good.csv}"))
    assert parse_table(good.components[0].parameters["table"])[1] == [0.25]   # allowed
    # the same bad cell inside the folder is quoted (it is the user's own file)
    (inside / "cells.csv").write_text("time,vx,vy,w\n0,SECRET-CELL,0,0\n")
    assert "'SECRET-CELL'" in problems_of(source_scenario(inside,
                                                          "parameters: {table: cells.csv}"))[0]


def test_every_bad_row_is_reported_capped_with_a_count(tmp_path):
    bad = [3, 5, 6] + list(range(8, 30))              # 25 bad rows (1-based lines)
    rows = ["time,vx,vy,w"] + [f"{n},{'x' if n in bad else '0'},0,0" for n in range(2, 31)]
    (tmp_path / "bad.csv").write_text("\n".join(rows) + "\n")
    messages = problems_of(source_scenario(tmp_path, "parameters: {table: bad.csv}"))
    listed = [m for m in messages if "is not a number" in m]
    assert [m.split(":")[1] for m in listed] == [str(n) for n in bad[:MAX_REPORTED]]
    assert f"{len(bad) - MAX_REPORTED} more bad row(s) not listed" in messages[-1]
    assert len(messages) == MAX_REPORTED + 1


# ------------------------------------------------------------------ O(log n) lookup


class CountingTimes(list):
    """A list that counts the elements read through it (bisect reads through __getitem__)."""
    reads = 0

    def __getitem__(self, i):
        CountingTimes.reads += 1
        return super().__getitem__(i)


def test_a_lookup_reads_log2_n_times(monkeypatch):
    n = 100_000
    text = "time,vx,vy,w\n" + "".join(f"{i * 0.01!r},{i},0,0\n" for i in range(n))
    real = profile_table.parse_table

    def counted(*args, **kwargs):
        times, *rest = real(*args, **kwargs)
        return [CountingTimes(times), *rest]
    monkeypatch.setattr(profile_table, "parse_table", counted)
    sample = table_sampler(text)
    worst = 0
    for t in np.random.default_rng(1).uniform(-5, n * 0.01 + 5, 500):
        CountingTimes.reads = 0
        value = sample(float(t))
        worst = max(worst, CountingTimes.reads)
        assert value[0] == pytest.approx(np.clip(t / 0.01, 0, n - 1), rel=1e-9, abs=1e-9)
    assert worst <= math.ceil(math.log2(n)) + 3       # the bisection plus the row's two ends


def test_the_ground_truth_solves_only_the_rows_inside_the_run(monkeypatch, tmp_path, fmu_dir):
    """A 10^5-row table, a run over 2 s of it: the truth's work follows the rows inside the
    run (20 intervals), not the table's length."""
    import scipy.integrate
    from mecanum_fmu.report.ground_truth import ground_truth
    from mecanum_fmu.runner import prepare
    n = 100_000
    (tmp_path / "long.csv").write_text("time,vx,vy,w\n" + "".join(
        f"{i * 0.1!r},0.2,0.1,0.05\n" for i in range(n)))
    path = source_scenario(tmp_path, "parameters: {table: long.csv}")
    graph = prepare(path, fmu_dir=fmu_dir)
    calls = []
    real = scipy.integrate.solve_ivp
    monkeypatch.setattr(scipy.integrate, "solve_ivp",
                        lambda *a, **k: calls.append(a[1]) or real(*a, **k))
    truth = ground_truth(graph, np.linspace(0.0, 2.0, 21))
    assert 19 <= len(calls) <= 21
    # constant twist: the closed form of docs/spec.md (an arc of radius v / w)
    v, w, t = math.hypot(0.2, 0.1), 0.05, 2.0
    heading = math.atan2(0.1, 0.2)          # world direction of (vx, vy) at theta 0
    x = v / w * (math.sin(heading + w * t) - math.sin(heading))
    y = -v / w * (math.cos(heading + w * t) - math.cos(heading))
    assert (truth.x[-1], truth.y[-1]) == pytest.approx((x, y), abs=1e-9)


def test_scalar_and_array_lookups_agree_with_np_interp():
    rng = np.random.default_rng(7)
    times = np.cumsum(rng.uniform(0.001, 1.0, 300))
    values = rng.normal(size=(3, 300))
    text = "time,vx,vy,w\n" + "".join(",".join(repr(float(v)) for v in row) + "\n"
                                      for row in zip(times, *values))
    twist, _ = table_twist(read_table(text))
    probe = np.concatenate([rng.uniform(-1, times[-1] + 1, 400), times])
    by_hand = np.array([np.interp(probe, times, v) for v in values])
    assert np.array_equal(np.array(twist(probe)), by_hand)
    assert np.array_equal(np.array([twist(float(t)) for t in probe]).T, by_hand)


# ------------------------------------------------------------------ logs as they come


def test_columns_units_and_time_shift_are_applied_on_load(tmp_path):
    (tmp_path / "log.csv").write_text(
        "stamp_ms,fwd_mm_s,left_mm_s,yaw_deg_s,battery\n"
        "5000,100,20,90,12.1\n"
        "5500,200,-40,-45,12.0\n")
    spec = ("table: {file: log.csv, columns: {time: stamp_ms, vx: -left_mm_s, vy: fwd_mm_s, "
            "w: yaw_deg_s}, units: {time: ms, vx: mm/s, vy: mm, w: deg/s}, start: first_row, "
            "offset: 0.25}")
    scenario = load_scenario(source_scenario(tmp_path, spec))
    times, vx, vy, w = parse_table(scenario.components[0].parameters["table"])
    assert times == pytest.approx([0.25, 0.75])            # (5000 - 5000) ms + 0.25 s ...
    assert vx == pytest.approx([-0.02, 0.04])              # minus the left speed, in m/s
    assert vy == pytest.approx([0.1, 0.2])
    assert w == pytest.approx([math.pi / 2, -math.pi / 4])


@pytest.mark.parametrize("spec, words", [
    ("table: {file: log.csv, columns: {vz: a}}", "unknown column (ours: time, vx, vy, w)"),
    ("table: {file: log.csv, units: {w: furlong}}", "'furlong' is not a unit of w"),
    ("table: {file: log.csv, start: last_row}", "the only choice is first_row"),
    ("table: {file: log.csv, offset: .nan}", "expected a finite number of seconds"),
    ("table: {file: log.csv, columns: {vx: nope}}", "lacks the column(s) nope"),
    ("table: {columns: {}}", "needs the table file"),
    ("table: log.csv", "expected a mapping like {file: log.csv"),
    ("table: {file: log.csv}, parameters: {table: log.csv}", "not several"),
])
def test_bad_table_options_are_named(tmp_path, spec, words):
    (tmp_path / "log.csv").write_text("time,vx,vy,w\n0,0,0,0\n")
    messages = problems_of(source_scenario(tmp_path, spec))
    assert any(words in m for m in messages), messages


def test_the_ros_cmd_vel_example_drives_like_the_joystick_table(tmp_path, fmu_dir):
    from mecanum_fmu.runner import prepare, run
    ends = []
    for name in ("cmd_vel", "joystick"):
        outcome = run(prepare(ROOT / "scenarios" / "profiles" / f"{name}.yaml",
                              fmu_dir=fmu_dir), tmp_path / name, plots=False,
                      log=lambda line: None)
        assert outcome.out_dir == tmp_path / name
        ends.append(_end(tmp_path / name))
    # the same recorded profile; the ns stamps are rounded to 256 ns by a float
    assert ends[0] == pytest.approx(ends[1], abs=1e-5)


def _end(folder):
    rows = np.genfromtxt(folder / "results.csv", delimiter=",", names=True)
    return rows["posex"][-1], rows["posey"][-1], rows["posetheta"][-1]


# ------------------------------------------------------------------ a strategy for tables

NUMBER = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@st.composite
def tables(draw):
    """(CSV text, rows as (time, vx, vy, w)): random column order, extra columns, comments,
    blank lines, CRLF line ends, a BOM, spaces around cells."""
    n = draw(st.integers(1, 25))
    steps = draw(st.lists(st.floats(1e-3, 100.0), min_size=n, max_size=n))
    start = draw(st.floats(-1e3, 1e3))
    times = list(np.cumsum([start] + steps[1:]))
    rows = [(float(t), *draw(st.tuples(NUMBER, NUMBER, NUMBER))) for t in times]
    names = draw(st.permutations(["time", "vx", "vy", "w"] + draw(st.lists(
        st.sampled_from(["buttons", "battery_v", "seq"]), max_size=2, unique=True))))
    end = draw(st.sampled_from(["\n", "\r\n"]))
    spaced = draw(st.booleans())
    lines = ["# recorded" if draw(st.booleans()) else "", ",".join(
        n.upper() if draw(st.booleans()) else n for n in names)]
    for row in rows:
        cells = dict(zip(("time", "vx", "vy", "w"), row))
        line = ",".join(repr(cells.get(n, 7.0)) for n in names)
        lines.append(line.replace(",", " , ") if spaced else line)
        if draw(st.booleans()):
            lines.append(draw(st.sampled_from(["", "# a note", "   "])))
    text = ("\ufeff" if draw(st.booleans()) else "") + end.join(lines) + end
    return text, rows


SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(tables())
def test_a_random_table_gives_its_rows_back(case):
    text, rows = case
    assert list(zip(*parse_table(text))) == rows
    sample, hold = table_sampler(text), table_sampler(text, "hold")
    for row in rows:
        assert sample(row[0]) == pytest.approx(row[1:]) and hold(row[0]) == row[1:]
    times = [r[0] for r in rows]
    twist, breaks = table_twist(read_table(text))      # the ground truth's reader (NumPy)
    assert breaks.tolist() == times
    assert np.array(twist(np.array(times))).T.tolist() == [list(r[1:]) for r in rows]
    mid = [(a + b) / 2 for a, b in zip(times, times[1:])]
    for k, column in enumerate(zip(*[r[1:] for r in rows])):
        assert [sample(t)[k] for t in mid] == pytest.approx(
            np.interp(mid, times, column).tolist(), rel=1e-9, abs=1e-6)


@SETTINGS
@given(tables(), st.data())
def test_a_damaged_row_is_found_on_its_line(case, data):
    text, rows = case
    lines = text.split("\n")
    clean = [line.lstrip("\ufeff").strip() for line in lines]
    data_lines = [i for i, line in enumerate(clean) if line and not line.startswith("#")
                  and "time" not in line.lower()]
    hit = sorted(data.draw(st.sets(st.sampled_from(data_lines), min_size=1)))
    how = data.draw(st.sampled_from(["word", "nan", "short"]))
    for i in hit:
        cells = lines[i].split(",")
        lines[i] = {"word": ",".join("oops" for _ in cells),
                    "nan": ",".join("nan" for _ in cells), "short": "1e9"}[how]
    with pytest.raises(TableError) as info:
        parse_table("\n".join(lines))
    assert info.value.count == len(hit)
    assert [line for line, _ in info.value.problems] == [i + 1 for i in hit][:MAX_REPORTED]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from([0.0, -0.0, 0.5, 1.0, 1.0 + 2e-16, 2.5, 1e300, -3.0]),
                max_size=12))
def test_distinct_times_are_numpys_unique(times):
    from mecanum_fmu.scenario.tables import distinct
    np.testing.assert_array_equal(distinct(np.array(times)), np.unique(np.array(times)))
    assert distinct(np.array(times)).dtype == np.float64


def test_a_run_with_its_estimate_leaves_numpy_ma_unimported():
    """np.unique imports numpy.ma on its first call (15-30 ms once per process), which landed in
    the first run's error estimate (summary.json's error_estimate_cost): the run's breakpoints
    take distinct() instead. The seed segments' showcase has jumps and kinks."""
    code = ("import sys\nfrom mecanum_fmu import master, runner\n"
            f"g = runner.prepare({str(ROOT / 'scenarios' / 'modes' / 'showcase.yaml')!r})\n"
            "r = master.simulate(g, g.scenario.experiment, with_estimate=True)\n"
            "found = master.estimate_error(g, r)\n"
            "assert found['error_estimate_method'].startswith('the embedded pair'), found\n"
            "print('numpy.ma' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=child_env(), timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"
