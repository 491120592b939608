"""The graph's breakpoints (master/breakpoints.py): the one reader the adaptive master's stops
and the error estimate's coarser grids share. The expected times are read off the tables and
the scenario text by hand."""
import numpy as np

from helpers import ROOT
from mecanum_fmu import runner
from mecanum_fmu.master.breakpoints import graph_breaks
from mecanum_fmu.scenario.tables import compared_times, read_table

TABLE = "time,vx,vy,w\n0,0,0,0\n1,1,0,0\n2,2,0,0\n3,2,0,0\n4,0,0.5,0\n"


def test_a_linear_table_breaks_where_a_slope_changes():
    # slopes per row interval: vx 1, 1, 0, -2; vy 0, 0, 0, 0.5: corners at 2 and 3, not at 1
    kinks, jumps = read_table(TABLE).breaks("linear")
    assert kinks.tolist() == [2.0, 3.0] and jumps.size == 0


def test_a_hold_table_breaks_where_a_value_changes():
    # held values: (0,0) (1,0) (2,0) (2,0) (0,0.5): jumps at 1, 2 and 4, not at 3
    kinks, jumps = read_table(TABLE).breaks("hold")
    assert jumps.tolist() == [1.0, 2.0, 4.0] and kinks.size == 0


def test_an_expression_breaks_where_it_compares_t_with_a_number():
    assert compared_times("where(t < 8, 0, 0.4*sin(6*(t - 8)))") == [8.0]
    assert sorted(compared_times("where(2 <= t, 1, 0) + where(t > 5.5, 1, 0)")) == [2.0, 5.5]
    assert compared_times("sin(t) + where(1 < 2, 1, 0)") == []     # no t in the comparison


def test_segments_break_at_their_ends():
    # showcase.yaml: 1 s still, six motions of 2 s and two spins, 1 s still; every end
    # changes the twist but the last (16 s, the stop time, still): 1, 3, 5, ..., 15
    breaks = graph_breaks(runner.prepare(ROOT / "scenarios" / "modes" / "showcase.yaml"))
    assert breaks.jumps.tolist() == [float(t) for t in range(1, 16, 2)]
    assert breaks.kinks.size == 0 and breaks.others.size == 0
    assert np.array_equal(breaks.times(), breaks.jumps)


def test_quiet_then_busy_breaks_where_its_expressions_switch():
    breaks = graph_breaks(runner.prepare(ROOT / "scenarios" / "profiles" / "quiet_then_busy.yaml"))
    assert breaks.others.tolist() == [8.0] and breaks.times().tolist() == [8.0]
