"""`mecanum-fmu run` in-process: the seed scenario against docs/spec.md, Expected results, the
order of accuracy of the masters, reproducibility and command-line overrides."""
import json
import math

import pytest
from scipy.integrate import solve_ivp

from helpers import ROOT, SPEC_END, chain_scenario, read_csv, run_main


def run_cli(tmp_path, capsys, *args, out="out"):
    """Run `mecanum-fmu run ARGS --out tmp_path/out --no-plots`; (exit code, stdout, stderr, out)."""
    out_dir = tmp_path / out
    code, stdout, stderr = run_main(capsys, "run", *args, "--out", out_dir, "--no-plots")
    return code, stdout, stderr, out_dir


def end_point(out_dir):
    header, data = read_csv(out_dir / "results.csv")
    return data[-1, header.index("pose.x")], data[-1, header.index("pose.y")]


@pytest.fixture
def in_repo(monkeypatch):
    monkeypatch.chdir(ROOT)


def test_seed_scenario_matches_the_spec(tmp_path, capsys, in_repo):
    code, out, err, out_dir = run_cli(tmp_path, capsys, "scenarios/circle.yaml")
    assert code == 0, err
    assert "match!" in out and "no match" not in out
    assert "1.839" in out and "-0.544" in out

    header, data = read_csv(out_dir / "results.csv")
    assert header[0] == "time"
    assert data[0, 0] == 0.0
    assert data[-1, 0] == 10.0
    x, y = data[-1, header.index("pose.x")], data[-1, header.index("pose.y")]
    assert abs(x - SPEC_END[0]) < 1e-3 and abs(y - SPEC_END[1]) < 1e-3
    # the whole path lies on the unit circle around (1, 0) (docs/spec.md, The seed scenario:
    # x = 1 - cos t, y = sin t)
    px, py = data[:, header.index("pose.x")], data[:, header.index("pose.y")]
    assert max(abs(math.hypot(a - 1.0, b) - 1.0) for a, b in zip(px, py)) < 1e-3

    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["master"] == "quadratic"
    assert summary["steps"] == 200
    assert isinstance(summary["wall_time_s"], float) and summary["wall_time_s"] >= 0
    assert summary["end_pose"]["x"] == pytest.approx(x, abs=1e-15)
    assert summary["end_pose"]["y"] == pytest.approx(y, abs=1e-15)
    ref = summary["reference_end_pose"]
    assert ref["x"] == pytest.approx(SPEC_END[0], abs=1e-9)
    assert ref["y"] == pytest.approx(SPEC_END[1], abs=1e-9)
    assert summary["error"]["dx"] == pytest.approx(x - SPEC_END[0], abs=1e-9)
    assert summary["error"]["dy"] == pytest.approx(y - SPEC_END[1], abs=1e-9)
    assert summary["error"]["position"] == pytest.approx(
        math.hypot(x - SPEC_END[0], y - SPEC_END[1]), abs=1e-9)
    assert summary["match"] is True
    assert summary["complete"] is True


# --- order of accuracy ------------------------------------------------------------------------

ROTATING = ("0.2*sin(t)", "0.5", "0.4*cos(0.5*t)")


def rotating_reference():
    """End point of the pose equations (docs/spec.md, Pose integration) for vx = 0.2 sin t,
    vy = 0.5, w = 0.4 cos(t/2), from rest at 0."""
    def rhs(t, s):
        vx, vy, w = 0.2 * math.sin(t), 0.5, 0.4 * math.cos(0.5 * t)
        th = s[2]
        return [vx * math.cos(th) - vy * math.sin(th), vx * math.sin(th) + vy * math.cos(th), w]
    sol = solve_ivp(rhs, (0.0, 10.0), [0.0, 0.0, 0.0], method="DOP853", rtol=1e-11, atol=1e-13)
    assert sol.success
    return float(sol.y[0, -1]), float(sol.y[1, -1]), float(sol.y[2, -1])


@pytest.mark.parametrize("profile", ["circle", "rotating"])
@pytest.mark.parametrize("master, steps, ratio", [
    ("gauss-seidel", (0.02, 0.01), (1.7, 2.3)),     # zero-order hold: first order
    ("trapezoidal", (0.1, 0.05), (3.4, 4.6)),       # mean of t_k and t_k+1: second order
    ("quadratic", (0.1, 0.05), None),               # see quadratic_ratio
])
def test_end_point_error_converges_at_the_master_order(tmp_path, capsys, in_repo, profile,
                                                       master, steps, ratio):
    if profile == "circle":
        scenario, reference = ROOT / "scenarios" / "circle.yaml", SPEC_END
    else:
        scenario = chain_scenario(tmp_path, "rotating", master="trapezoidal",
                                  stop_time=10.0, profile=ROTATING)
        reference = rotating_reference()[:2]
    errors = []
    for h in steps:
        code, _, err, out_dir = run_cli(tmp_path, capsys, scenario, "--master", master,
                                        "--step-size", h, out=f"h{h}")
        assert code == 0, err
        summary = json.loads((out_dir / "summary.json").read_text())
        assert summary["master"] == master and summary["steps"] == round(10.0 / h)
        x, y = end_point(out_dir)
        errors.append(math.hypot(x - reference[0], y - reference[1]))
    assert errors[1] < errors[0]
    ratio = ratio or quadratic_ratio(profile)
    assert ratio[0] < errors[0] / errors[1] < ratio[1], errors


def quadratic_ratio(profile: str) -> tuple[float, float]:
    """The parabola's mean over the step is exact to O(h^4) per step (third order over the run)
    while the twist's frame does not turn (w = 0, the circle); with w != 0 the exact
    integrator's turn within the step meets the twist's change over it: O(h^3) per step, the
    run second order (docs/masters.md)."""
    return (7.0, 12.0) if profile == "circle" else (3.4, 4.6)


def test_rotating_profile_turns(tmp_path):
    """The w != 0 reference really leaves theta = 0 (else it would not test the rotation)."""
    theta = rotating_reference()[2]
    assert theta == pytest.approx(0.8 * math.sin(5.0), abs=1e-9)   # integral of w, exactly


# --- reproducibility and overrides ------------------------------------------------------------

def test_two_runs_write_byte_identical_results(tmp_path, capsys, in_repo):
    first = run_cli(tmp_path, capsys, "scenarios/circle.yaml", out="a")
    second = run_cli(tmp_path, capsys, "scenarios/circle.yaml", out="b")
    assert first[0] == second[0] == 0
    a = (first[3] / "results.csv").read_bytes()
    b = (second[3] / "results.csv").read_bytes()
    assert len(a) > 1000 and a == b


def test_stop_time_override_ends_the_run_at_5(tmp_path, capsys, in_repo):
    code, _, err, out_dir = run_cli(tmp_path, capsys, "scenarios/circle.yaml", "--stop-time", 5)
    assert code == 0, err
    header, data = read_csv(out_dir / "results.csv")
    assert data[-1, 0] == 5.0
    assert len(data) == 101                  # 0, 0.05, ..., 5
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["stop_time"] == 5.0 and summary["end_time"] == 5.0 and summary["steps"] == 100
    # and the end point is the circle's at t = 5 (docs/spec.md, The seed scenario)
    x, y = end_point(out_dir)
    assert x == pytest.approx(1 - math.cos(5.0), abs=1e-3)
    assert y == pytest.approx(math.sin(5.0), abs=1e-3)


def test_zero_step_size_is_bad_input(tmp_path, capsys, in_repo):
    code, out, err, out_dir = run_cli(tmp_path, capsys, "scenarios/circle.yaml",
                                      "--step-size", 0)
    assert code == 2
    assert "step_size" in err
    assert not (out_dir / "results.csv").exists()
