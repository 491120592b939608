"""The embedded pair, the fixed-step masters' default estimate (master/pair.py, pair_rows.py):
its pieces and weights against hand-worked values, the hold it rebuilds against the one the
master fed, where it hands over to Richardson and why, and the ends it will not stand
behind. Its accuracy against the truth is tests/test_estimate.py's (auto)."""
import numpy as np
import pytest

from helpers import ROOT, with_experiment
from mecanum_fmu import master, runner
from mecanum_fmu.master import pair_rows, plan, stencils, stepping
from mecanum_fmu.master.estimate import LATE_END, LONE_PIECES, TABLES
from mecanum_fmu.master.breakpoints import pieces
from mecanum_fmu.models import pose_error
from mecanum_fmu.scenario.tables import Breaks

SCENARIOS = ROOT / "scenarios"


def _breaks(kinks=(), jumps=(), others=()):
    return Breaks(*(np.array(x, dtype=float) for x in (kinks, jumps, others)))


def test_pieces_of_kinks_jumps_and_a_breakpoint_inside_a_step():
    # 10 steps of 0.1 s: a kink at 0.3 s (node 3), a jump at 0.6 s (node 6), a jump at 0.85 s
    found = pieces(_breaks(kinks=[0.3], jumps=[0.6, 0.85]), 0.0, 0.1, 10)
    assert found.starts.tolist() == [0, 3, 6, 9]
    # a kink's node ends one piece and starts the next; a jump's node is the next piece's;
    # the one inside step 8 ends a piece on node 8 and starts the next on node 9
    assert found.ends.tolist() == [3, 5, 8, 10]
    assert found.cut.tolist() == [6]            # the step that ends on the jump is cut
    assert set(found.across) == {8}
    assert found.across[8][0] == pytest.approx(0.5) and found.across[8][1]
    assert not found.short


def test_a_table_with_rows_closer_than_two_steps_is_short():
    assert pieces(_breaks(kinks=[0.05, 0.1, 0.15, 0.2]), 0.0, 0.04, 10).short
    assert not pieces(_breaks(kinks=[0.05, 0.1, 0.15, 0.2]), 0.0, 0.01, 40).short
    # a hold table's rows (jumps) as close: constant pieces, whose one value says it all
    assert not pieces(_breaks(jumps=[0.05, 0.1, 0.15, 0.2]), 0.0, 0.04, 10).short


def test_the_cubics_weights_are_the_classical_ones():
    """The mean over one step of the cubic through four values a step apart: the centred
    (-1, 13, 13, -1)/24, the first interval's (9, 19, -5, 1)/24 and Adams-Bashforth's
    extrapolation (-9, 37, -59, 55)/24; with fewer nodes the parabola's and the trapezoid."""
    table = stencils.weight_table(5)

    def three(m, o):      # the weights of m nodes at offset o, as rows: mean, start, end
        return table[(m - 1) * 5 + o][:, :m]
    assert np.allclose(three(4, 1)[0] * 24, [-1, 13, 13, -1])
    assert np.allclose(three(4, 0)[0] * 24, [9, 19, -5, 1])
    assert np.allclose(three(4, 3)[0] * 24, [-9, 37, -59, 55])
    assert np.allclose(three(3, 0)[0] * 12, [5, 8, -1])
    assert np.allclose(three(2, 0)[0], [0.5, 0.5])
    # and the values at the step's ends: the nodes themselves, or the extrapolated one
    assert np.allclose(three(4, 1)[1:], [[0, 1, 0, 0], [0, 0, 1, 0]])
    assert np.allclose(three(2, 1)[2], [-1, 2])


def _held(monkeypatch, path, name, factor=1, corrector=False):
    """(what the pair rebuilt as the pose's held twist, what the master fed it) per step
    (`corrector`: where the master rolls back, what it fed in the corrector's pass)."""
    fed, rebuilt = [], []
    fill = plan._Blend.fill

    def spy(blend):
        fill(blend)
        if not corrector or blend.holds.mode == blend.holds.CORRECT or name != "quadratic":
            fed.append(blend.staging.copy())
    monkeypatch.setattr(plan._Blend, "fill", spy)
    steps = pose_error.PoseBatch.steps

    def keep(model, h, held, error, change):
        rebuilt.append(held.copy())
        return steps(model, h, held, error, change)
    monkeypatch.setattr(pose_error.PoseBatch, "steps", keep)
    graph = runner.prepare(path, master_name=name)
    graph, exp = with_experiment(graph, step_size=graph.scenario.experiment.step_size * factor)
    master.simulate(graph, exp, with_estimate=True)
    return np.concatenate(rebuilt), np.array(fed)


@pytest.mark.parametrize("name", ["trapezoidal", "quadratic"])
def test_the_rebuilt_hold_is_the_one_the_master_fed(monkeypatch, name):
    rebuilt, fed = _held(monkeypatch, SCENARIOS / "circle.yaml", name)
    assert len(rebuilt) == len(fed) == 200
    assert np.abs(rebuilt - fed).max() < 1e-13


def test_the_rebuilt_hold_at_jumps_is_the_left_values_one(monkeypatch):
    """showcase at 0.04 s (jumps on the grid every 2 s): the step that ends on a jump is
    taken in two pieces, its first on the left value: the pair rebuilds that piece's hold
    (the master fills the blend once per piece: the first of each cut step's two fills)."""
    rebuilt, fed = _held(monkeypatch, SCENARIOS / "modes" / "showcase.yaml", "quadratic", 4)
    graph = runner.prepare(SCENARIOS / "modes" / "showcase.yaml")
    cut = {int(round(b / 0.04)) - 1 for b in graph.breaks.jumps}
    per_step, i = [], 0
    for k in range(len(rebuilt)):
        per_step.append(fed[i])
        i += 2 if k in cut else 1
    assert i == len(fed)
    assert np.abs(rebuilt - np.array(per_step)).max() < 1e-13


def _method(path, name="quadratic", parameters=None, **changes):
    graph = runner.prepare(path, master_name=name, parameters=parameters)
    graph, exp = with_experiment(graph, **changes)
    results = master.simulate(graph, exp, with_estimate=True)
    return master.estimate_error(graph, results), results


def _reference(graph, results, refine=32, names=None):
    """|the run - the same graph stepped by the same master at 1/refine of the step| on the
    run's times, per output (`names`, by default the pose's): a closed loop's coupling error
    (its truth is the path asked for, not the pose the loop makes); the reference's own error
    is refine^p times smaller."""
    exp = graph.scenario.experiment
    fine, fexp = with_experiment(graph, step_size=exp.step_size / refine, estimate="none")
    reference = master.simulate(fine, fexp)
    names = names or [n for n in results.names if n.startswith("pose.")]
    return {name: np.abs(np.asarray(results[name]) - np.asarray(reference[name])[::refine])
            for name in names}


LOOPS = ("track_circle", "track_figure_eight", "recorded_path")
OMNI = SCENARIOS / "chassis" / "omni_field_circle.yaml"


@pytest.mark.parametrize("scenario", LOOPS)
@pytest.mark.parametrize("name", ["quadratic", "trapezoidal", "gauss-seidel"])
def test_a_loop_carries_the_error_around_through_the_fmus_responses(scenario, name):
    """The bundled closed loops: the pose's error comes back through the follower, Center2Wheel
    and Wheel2Center (their Jacobians, models/responses.py); the pair holds, makes no coarser
    run, and its estimate of the pose is within 3x of the error against a run at h/32: its
    max, and its end where the loop has not damped it by three orders below the max (the
    recorded path's x ends at 1e-7 m, after 3e-4 m: the carried estimate reads 0.26x)."""
    path = SCENARIOS / "closed_loop" / f"{scenario}.yaml"
    found, results = _method(path, name)
    assert found["error_estimate_method"].startswith("the embedded pair")
    assert "coarse" not in results.extra
    graph = runner.prepare(path, master_name=name)
    for output, error in _reference(graph, results).items():
        estimate = found["error_estimate"][output]
        for which, true in (("max", error.max()), ("end", error[-1])):
            if true < max(1e-9, 1e-3 * error.max()):   # (theta ends on 0: constant headings)
                continue
            assert true / 3 <= estimate[which] <= 3 * true, (output, which, estimate, true)


@pytest.mark.parametrize("scenario", LOOPS)
def test_a_loop_under_jacobi_carries_the_error_a_row_late_per_fmu(scenario):
    """Under Jacobi each FMU of the chain hands its value on a step late: the pair carries the
    error with those lags (and the late follower's time taken out); the max and the end of x,
    y and theta within 3x of the error against h/32."""
    path = SCENARIOS / "closed_loop" / f"{scenario}.yaml"
    found, results = _method(path, "jacobi")
    assert found["error_estimate_method"].startswith("the embedded pair")
    graph = runner.prepare(path, master_name="jacobi")
    for output, error in _reference(graph, results).items():
        for which, true in (("max", error.max()), ("end", error[-1])):
            if true > 1e-9:
                estimate = found["error_estimate"][output][which]
                assert true / 3 <= estimate <= 3 * true, (output, which, estimate, true)


@pytest.mark.parametrize("name", ["gauss-seidel", "jacobi"])
def test_the_loop_also_covers_the_chain_s_own_outputs(name):
    """The follower's, the wheels' and Wheel2Center's recorded outputs get their carried error
    (S E: each one's sensitivity to the pose's error; under Jacobi plus its lag), within 3x
    of the error against h/32 at its max, not "below round-off" (the ICR, -vy/w with w near 0
    on this path, is left out: its error means little there)."""
    path = SCENARIOS / "closed_loop" / "track_circle.yaml"
    found, results = _method(path, name)
    graph = runner.prepare(path, master_name=name)
    names = ("follower.vx", "follower.w", "c2w.w1", "w2c.vx", "w2c.w")
    for output, error in _reference(graph, results, names=names).items():
        assert error.max() / 3 <= found["error_estimate"][output]["max"] <= 3 * error.max(), (
            output, found["error_estimate"][output], error.max())


TURNING = {"follower.theta_ref_expr": "0.5*t", "pose.theta0": 0.0}


@pytest.mark.parametrize("name", ["quadratic", "gauss-seidel"])
def test_the_icr_gets_a_number_where_w_stays_clear_of_0_and_none_where_it_nears_0(name):
    """Wheel2Center's ICR is -vy/w: on track_circle turning at 0.5 rad/s from a heading on the
    reference its carried error is within 3x of the error against h/32; on the bundled
    track_circle, whose w decays to 0, it is unresolved (1/w^2 magnifies one row's error)."""
    path = SCENARIOS / "closed_loop" / "track_circle.yaml"
    found, results = _method(path, name, parameters=TURNING)
    graph = runner.prepare(path, master_name=name, parameters=TURNING)
    for output, error in _reference(graph, results, names=("w2c.icr_x", "w2c.icr_y")).items():
        for which, true in (("max", error.max()), ("end", error[-1])):
            assert true / 3 <= found["error_estimate"][output][which] <= 3 * true
    found, _ = _method(path, name)
    assert found["error_estimate"]["w2c.icr_x"]["max"].startswith("unresolved (it divides")


def test_under_jacobi_a_late_follower_s_time_is_taken_out():
    """Under Jacobi the follower's row k+1 is f(the pose of t_k, t_k+1): on a heading reference
    of 0.5 t the run's heading ends 0.025 rad (0.5 rad/s x one step) ahead; the pair reads that
    end within 3x (without the time's part it read 1e-9 rad)."""
    path = SCENARIOS / "closed_loop" / "track_circle.yaml"
    found, results = _method(path, "jacobi", parameters=TURNING)
    graph = runner.prepare(path, master_name="jacobi", parameters=TURNING)
    error = _reference(graph, results)["pose.theta"]
    assert error[-1] > 0.02
    assert error[-1] / 3 <= found["error_estimate"]["pose.theta"]["end"] <= 3 * error[-1]


def test_a_loop_the_pair_cannot_carry_through_hands_over_to_richardson_and_says_why():
    """The omni field circle turning at w = 0.5 + 0.1 t^2: FieldToBody reads the pose's
    heading, which carries an error, and has no known response; Richardson's coarser runs are
    stepped on the run's own instances, as where the pair never applied."""
    found, results = _method(OMNI, parameters={"command.w_expr": "0.5 + 0.1*t*t"})
    assert found["error_estimate_method"].startswith("Richardson")
    assert "the embedded pair does not apply" in found["error_estimate_method"]
    assert "pose.theta carries an error into field" in found["error_estimate_method"]
    assert len(results.extra["coarse"]["runs"]) == 2       # stepped on the run's own instances


@pytest.mark.parametrize("name", ["quadratic", "trapezoidal", "gauss-seidel", "jacobi"])
def test_a_loop_whose_fed_back_heading_is_exact_keeps_the_pair(name):
    """omni_field_circle: the heading comes back to FieldToBody, and w is constant: theta
    carries no error, the loop carries none around, and the pair holds (no coarser run)."""
    found, results = _method(OMNI, name)
    assert found["error_estimate_method"].startswith("the embedded pair")
    assert "coarse" not in results.extra
    assert found["error_estimate"]["pose.theta"]["max"] == "below round-off"
    assert all(isinstance(found["error_estimate"][f"pose.{k}"]["max"], float) for k in "xy")


@pytest.mark.parametrize("name", ["trapezoidal", "quadratic"])
def test_the_rebuilt_hold_in_a_loop_is_the_one_the_master_fed(monkeypatch, name):
    """The twist that closes omni_field_circle's loop into the pose: extrapolated by the
    trapezoidal master, the corrector's parabola through the predicted end value by the
    quadratic one (its predictor's fills are left out)."""
    rebuilt, fed = _held(monkeypatch, OMNI, name, corrector=True)
    assert len(rebuilt) == len(fed) == 200
    assert np.abs(rebuilt - fed).max() < 1e-13


def test_an_fmu_with_a_state_held_exactly_keeps_the_pair():
    """The bicycle integrates its own pose from constant commands: held exactly, no error
    (the truth agrees: 1e-13), and no coarser run is made."""
    found, results = _method(SCENARIOS / "chassis" / "bicycle_circle.yaml")
    assert found["error_estimate_method"].startswith("the embedded pair")
    assert "coarse" not in results.extra
    assert all(v == {"max": "below round-off", "end": "below round-off"}
               for v in found["error_estimate"].values())


@pytest.mark.parametrize("name", ["gauss-seidel", "jacobi"])
def test_inputs_that_never_move_are_exact_without_a_pass_over_the_rows(monkeypatch, name):
    """The bicycle's commands and twist hold one value over the whole run: every hold is
    exact, the pair works out no stencil (PairRows._still), and says what a full pass over
    the rows says (the same words with _still turned off)."""
    made = []
    polynomials = pair_rows.PairRows._polynomials
    monkeypatch.setattr(pair_rows.PairRows, "_polynomials",
                        lambda self, *a, **k: (made.append(1), polynomials(self, *a, **k))[1])
    path = SCENARIOS / "chassis" / "bicycle_circle.yaml"
    still, _ = _method(path, name, step_size=0.2)
    assert not made
    monkeypatch.setattr(pair_rows.PairRows, "_still", lambda self: False)
    full, _ = _method(path, name, step_size=0.2)
    assert made
    assert {k: v for k, v in full.items() if k != "error_estimate_cost"} == \
        {k: v for k, v in still.items() if k != "error_estimate_cost"}
    assert all(v == {"max": "below round-off", "end": "below round-off"}
               for v in still["error_estimate"].values())


@pytest.mark.parametrize("name", ["quadratic", "trapezoidal", "gauss-seidel", "jacobi"])
def test_a_table_stepped_coarser_than_its_rows_is_read_off_the_table(name):
    """joystick at 0.04 s (20 Hz rows: kinks inside most steps): the run's rows do not tell
    the twist between them, the table does (master/pair_known.py); no coarser run is made.
    Its accuracy: tests/test_estimate.py."""
    found, results = _method(SCENARIOS / "profiles" / "joystick.yaml", name, step_size=0.04)
    assert found["error_estimate_method"].startswith("the embedded pair")
    assert found["error_estimate_method"].endswith(TABLES)
    assert "coarse" not in results.extra
    assert all(isinstance(v["max"], float) for v in found["error_estimate"].values()
               if v["max"] != "below round-off")


def test_a_table_whose_inputs_are_not_a_linear_map_of_it_hands_over():
    """The same with the wheels limited to 3 rad/s (Center2Wheel's w_max scales them down
    together): the pose's twist is no fixed linear map of the table, and Richardson
    estimates, saying why."""
    found, _ = _method(SCENARIOS / "profiles" / "joystick.yaml", parameters={"w_max": 3.0},
                       step_size=0.04)
    assert found["error_estimate_method"].startswith("Richardson")
    assert "not a fixed linear map of the tables" in found["error_estimate_method"]


def test_a_loop_on_a_table_that_jumps_at_every_step_hands_over():
    """recorded_path at 0.1 s: the follower's feed-forward jumps at every row, every step;
    between two jumps the pose's twist moves with the loop, and one value per piece cannot
    tell how (the pair read "below round-off" where the error is 6e-3 m)."""
    found, _ = _method(SCENARIOS / "closed_loop" / "recorded_path.yaml", "gauss-seidel",
                       step_size=0.1)
    assert found["error_estimate_method"].startswith("Richardson")
    assert LONE_PIECES in found["error_estimate_method"]
    assert found["error_estimate"]["pose.x"]["max"] != "below round-off"


def test_jacobis_end_is_read_after_the_run_and_unresolved_without(monkeypatch):
    """quiet_then_busy under jacobi at 0.1 s: w = 2 sin 5(t - 8) turns half a radian a step,
    and theta's end rests on two steps of true inputs past the run's last rows. After the
    run each FMU is set its sources' newest values (no doStep) and the late outputs read:
    their true values at the last node, so the end is a number within 3x of the error
    against the run at h/32. Where that read fails, the cubic and the parabola extrapolate
    past the rows, disagree (the cubic alone said 0.0011 against 0.028), and no number is
    given."""
    path = SCENARIOS / "profiles" / "quiet_then_busy.yaml"
    found, results = _method(path, "jacobi", step_size=0.1)
    graph, _ = with_experiment(runner.prepare(path, master_name="jacobi"), step_size=0.1)
    true_end = _reference(graph, results, names=["pose.theta"])["pose.theta"][-1]
    assert true_end > 0.01
    assert 1 / 3 <= found["error_estimate"]["pose.theta"]["end"] / true_end <= 3
    monkeypatch.setattr(master, "settled_end", lambda *args: None)      # a call refused
    found, _ = _method(path, "jacobi", step_size=0.1)
    assert found["error_estimate"]["pose.theta"]["end"] == LATE_END
    found, _ = _method(path, "jacobi")
    assert isinstance(found["error_estimate"]["pose.theta"]["end"], float)


@pytest.mark.parametrize("status", [2, 4], ids=["discard", "fatal"])
def test_a_refused_read_of_jacobis_end_leaves_it_extrapolated(monkeypatch, status):
    """An FMU that refuses the read after the run (Discard; Fatal, after which FMI allows
    nothing more of it): the end is the extrapolated one, and the next run in the process
    runs and reads it (a fatal instance is not reused)."""
    from mecanum_fmu.master.instance import FmuCallError
    path = SCENARIOS / "profiles" / "quiet_then_busy.yaml"
    graph, exp = with_experiment(runner.prepare(path, master_name="jacobi"), step_size=0.1)

    def refused(target, links, by_name):
        raise FmuCallError(target, "fmi2SetReal", status)
    with monkeypatch.context() as patch:
        patch.setattr(stepping, "_settle_one", refused)
        results = master.simulate(graph, exp, with_estimate=True)
    assert master.estimate_error(graph, results)["error_estimate"]["pose.theta"]["end"] == \
        LATE_END
    again = master.simulate(graph, exp, with_estimate=True)
    assert isinstance(master.estimate_error(graph, again)["error_estimate"]["pose.theta"][
        "end"], float)
    assert np.array_equal(np.asarray(again["pose.theta"]), np.asarray(results["pose.theta"]))


def test_reading_jacobis_end_after_the_run_changes_no_row():
    """The late outputs' end is read after the last row (quiet_then_busy at 0.2 s: it is):
    the run's rows are those of the run without an estimate, bit for bit."""
    path = SCENARIOS / "profiles" / "quiet_then_busy.yaml"
    graph, exp = with_experiment(runner.prepare(path, master_name="jacobi"), step_size=0.2)
    with_end = master.simulate(graph, exp, with_estimate=True)
    assert isinstance(master.estimate_error(graph, with_end)["error_estimate"]["pose.theta"][
        "end"], float)
    plain = master.simulate(*with_experiment(graph, estimate="none"))
    assert with_end.names == plain.names
    for name in plain.names:
        assert np.array_equal(np.asarray(with_end[name]), np.asarray(plain[name])), name


def test_the_pair_costs_no_doStep(monkeypatch):
    """The run with the pair steps each FMU as often as the run without an estimate."""
    graph = runner.prepare(SCENARIOS / "circle.yaml")
    calls = []
    one_pass = stepping.one_pass

    def count(program, t, h):
        calls.append(t)
        one_pass(program, t, h)
    monkeypatch.setattr(stepping, "one_pass", count)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    assert results.extra["pair"]["found"]["failed"] is None
    with_pair = len(calls)
    calls.clear()
    master.simulate(*with_experiment(graph, estimate="none"))
    assert with_pair == len(calls) == 200


@pytest.mark.parametrize("name", ["quadratic", "gauss-seidel"])
def test_a_short_last_step_is_weighed_on_its_own_nodes(name):
    """The circle to 9.97 s at 0.05 s: its last step is 0.02 s; the estimate stays within 3x
    of the closed form's error (x = 1 - cos t, y = sin t), at the end too."""
    found, results = _method(SCENARIOS / "circle.yaml", name, stop_time=9.97)
    assert results.time[-1] == 9.97 and results.time[-2] == pytest.approx(9.95)
    assert found["error_estimate_method"].startswith("the embedded pair")
    t = results.time
    for axis, truth in (("x", 1 - np.cos(t)), ("y", np.sin(t))):
        error = np.abs(results[f"pose.{axis}"] - truth)
        e = found["error_estimate"][f"pose.{axis}"]
        for which, true in (("max", error.max()), ("end", error[-1])):
            assert true / 3 <= e[which] <= 3 * true, (axis, which, e, true)


def test_a_short_last_step_under_jacobi():
    found, results = _method(SCENARIOS / "circle.yaml", "jacobi", stop_time=9.97)
    t = results.time
    error = np.abs(results["pose.y"] - np.sin(t))
    e = found["error_estimate"]["pose.y"]
    assert error.max() / 3 <= e["max"] <= 3 * error.max()
    assert error[-1] / 3 <= e["end"] <= 3 * error[-1]


def test_the_pairs_window_stays_a_few_rows_long(monkeypatch):
    """Memory stays flat: over a 20,000-step run (five chunks of rows) the pair keeps no more
    than a chunk and the few rows its stencils reach back to, and its estimate is the one it
    makes of the same run at once (the estimate of a run does not depend on its chunks)."""
    from mecanum_fmu.master import pair_rows, recorder
    longest = []
    call = pair_rows.PairRows.__call__

    def watch(rows_tap, rows, first):
        call(rows_tap, rows, first)
        longest.append(len(rows_tap.window))
    monkeypatch.setattr(pair_rows.PairRows, "__call__", watch)
    found, results = _method(SCENARIOS / "circle.yaml", "gauss-seidel", step_size=5e-4)
    assert len(longest) == 5 and max(longest) <= recorder.CHUNK_ROWS + 10
    monkeypatch.setattr(recorder, "CHUNK_ROWS", 30_000)      # all rows in one chunk
    whole, _ = _method(SCENARIOS / "circle.yaml", "gauss-seidel", step_size=5e-4)
    for name in ("pose.x", "pose.y"):
        for which in ("max", "end"):
            assert found["error_estimate"][name][which] == pytest.approx(
                whole["error_estimate"][name][which], rel=1e-9)


def test_a_run_made_without_its_estimate_is_made_again_once(monkeypatch):
    """The turning omni field circle simulated without with_estimate: estimate_error makes the
    run again for the pair, which fails on it (the heading carries an error into FieldToBody);
    the coarser runs that run made on its own instances are used, none is made afresh, and the
    estimate is the one of a run made with it."""
    from mecanum_fmu.master import estimate
    made = []
    monkeypatch.setattr(estimate, "coarse_run", lambda *a, **k: made.append(a) or "made")
    turning = {"command.w_expr": "0.5 + 0.1*t*t"}
    graph = runner.prepare(OMNI, parameters=turning)
    found = master.estimate_error(graph, master.simulate(graph, graph.scenario.experiment))
    assert made == [] and found["error_estimate_method"].startswith("Richardson")
    with_it, _ = _method(OMNI, parameters=turning)
    found.pop("error_estimate_cost"), with_it.pop("error_estimate_cost")
    assert found == with_it


@pytest.mark.parametrize("n", [1, 2, 5, 200, 4097])
def test_the_loop_s_recurrence_by_doubling_is_the_step_by_step_one(n):
    """pair_loop._recurrence (log2 n NumPy rounds) against e_k+1 = p_k e_k + q_k stepped one
    step at a time."""
    from mecanum_fmu.master.pair_loop import _recurrence
    rng = np.random.default_rng(n)
    p = np.eye(3) + 0.02 * rng.standard_normal((n, 3, 3))
    q, e = rng.standard_normal((n, 3)), rng.standard_normal(3)
    start, expected = e.copy(), []
    for k in range(n):
        e = p[k] @ e + q[k]
        expected.append(e)
    assert np.allclose(_recurrence(p, q, start), expected, rtol=1e-10, atol=1e-10)


def test_the_sensors_outputs_are_unresolved_and_the_true_pose_keeps_the_pair(fmu_dir):
    """belief_open_circle: the encoders, the gyro and the odometry sample at their own period
    and nothing else reads them, so the pair estimates the rest (the true pose against the
    seed circle's closed form, x = 1 - cos t, y = sin t) and leaves theirs unresolved."""
    import math
    graph = runner.prepare(SCENARIOS / "robot" / "belief_open_circle.yaml", fmu_dir=fmu_dir)
    exp = graph.scenario.experiment
    results = master.simulate(graph, exp, with_estimate=True)
    found = master.estimate_error(graph, results)
    assert found["error_estimate_method"].startswith("the embedded pair")
    for name in ("odom.x", "odom.theta", "enc1.w_meas", "gyro.w_meas"):
        assert found["error_estimate"][name]["max"].startswith(
            "unresolved (Encoder, Gyro, Odometry sample at their own period")
    t = exp.stop_time
    for name, truth in (("pose.x", 1 - math.cos(t)), ("pose.y", math.sin(t))):
        true = abs(results.final(name) - truth)
        assert true > 1e-9                                       # the step shows
        assert true / 3 <= found["error_estimate"][name]["end"] <= 3 * true


def test_a_loop_closed_through_the_sensors_hands_over(fmu_dir):
    """belief_track_circle: the follower reads the odometry's belief, so the pose (which has
    an error model) is made from the samples: the pair says so, and no estimate is made."""
    graph = runner.prepare(SCENARIOS / "robot" / "belief_track_circle.yaml", fmu_dir=fmu_dir)
    graph, exp = with_experiment(graph, stop_time=0.2)
    results = master.simulate(graph, exp, with_estimate=True)
    assert "pose reads what Encoder, Odometry sample at their own period" in \
        results.extra["pair"]["found"]
    assert master.estimate_error(graph, results)["error_estimate"] is None


def test_a_loop_closed_through_ideal_sensors_is_second_order_and_the_method_says_how_to_see_it(
        fmu_dir):
    """With no estimate, the method tells the user to halve the step (the samples stay where
    they are). With ideal encoders (no quantisation, no noise: a smooth model) halving it
    twice shows what docs/masters.md ("Samples") says: the follower steps on the sample of
    each step's start, and after each sample the holds move by the jump, so the true end
    point moves about a quarter as far the second time, a second-order error (it was half as
    far, first order, while the follower took each sample a step early)."""
    base = runner.prepare(SCENARIOS / "robot" / "belief_track_circle.yaml", fmu_dir=fmu_dir,
                          parameters={"cpr": 0, "sigma": 0.0})
    ends, method = [], None
    for factor in (1, 2, 4):
        graph, exp = with_experiment(base, stop_time=3.0,
                                     step_size=base.scenario.experiment.step_size / factor)
        results = master.simulate(graph, exp, keep_rows=2)
        ends.append(np.array([results.final("pose.x"), results.final("pose.y")]))
        method = method or master.estimate_error(graph, results)["error_estimate_method"]
    assert "a run at half the step keeps them" in method and "The step's share" in method
    first, second = np.linalg.norm(ends[0] - ends[1]), np.linalg.norm(ends[1] - ends[2])
    assert second > 0 and 3.0 < first / second < 5.0


def test_the_pairs_seconds_count_its_set_up(monkeypatch):
    """error_estimate_cost counts the pair's set-up before the run (its plan, the probes'
    prober, the t0 kept for Richardson) with its work after: a set-up made 50 ms slower
    shows in its seconds."""
    import time
    graph = runner.prepare(ROOT / "scenarios" / "circle.yaml")
    taps = master.pair_tap

    def slow_tap(*args):
        time.sleep(0.05)
        return taps(*args)
    monkeypatch.setattr(master, "pair_tap", slow_tap)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    assert results.extra["pair"]["found"]["seconds"] >= 0.05
    found = master.estimate_error(graph, results)
    assert found["error_estimate_cost"] >= 0.05 / results.wall_time - 1e-3
