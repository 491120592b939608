"""The graph's breakpoints (master/breakpoints.py): the one reader the adaptive master's stops
and the error estimate's coarser grids share. The expected times are read off the tables and
the scenario text by hand."""
import numpy as np

from helpers import ROOT
from mecanum_fmu import runner
from mecanum_fmu.master.breakpoints import graph_breaks, pieces
from mecanum_fmu.scenario.tables import Breaks, compared_times, read_table

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


def test_the_pairs_pieces_keep_the_strongest_break_on_a_node():
    """breakpoints.pieces on 10 steps of 0.5 s, worked out by hand: a kink on node 2 (1 s)
    ends the first piece there; a kink at 2.2 s and a jump at 2.4 s inside step 4 (2 to
    2.5 s): that step's fraction is the jump's (0.8), and the piece after starts at node 5;
    a kink and a jump both on node 7 (3.5 s): the jump wins, the piece before ends at node
    6 and node 7 is a cut; a jump at the stop time (node 10) leaves a piece that holds no
    step, which is not `lone`."""
    breaks = Breaks(np.array([1.0, 2.2, 3.5]), np.array([2.4, 3.5, 5.0]), np.array([]))
    found = pieces(breaks, 0.0, 0.5, 10)
    assert found.starts.tolist() == [0, 2, 5, 7, 10]
    assert found.ends.tolist() == [2, 4, 6, 9, 10]
    assert found.cut.tolist() == [7, 10]
    assert list(found.across) == [4] and found.across[4][1] is True
    assert abs(found.across[4][0] - 0.8) < 1e-12
    assert not found.lone and not found.short


def test_rows_closer_than_the_step_make_short_and_lone_pieces():
    """Kinks on every node from node 3 on (a linear table's rows at the step): each piece
    from node 3 holds one step; a kink on nodes 3 and 4 with a jump on node 4 leaves the
    piece [3, 3] without a step (lone), and it ends on a kink (short)."""
    breaks = Breaks(np.array([0.3, 0.4, 0.5]), np.array([0.4]), np.array([]))
    found = pieces(breaks, 0.0, 0.1, 6)
    assert found.starts.tolist() == [0, 3, 4, 5]
    assert found.ends.tolist() == [3, 3, 5, 6]
    assert found.lone and found.short
    assert pieces(Breaks(np.array([]), np.array([]), np.array([])), 0.0, 0.1, 6
                  ).starts.tolist() == [0]
