"""A component's `dependencies:` (scenario/dependencies.py): what an FMU's model description
leaves undeclared, said in the scenario. Two pythonfmu FMUs (which declare no dependencies)
in a feedback loop are an algebraic loop to FMI; the message says how to break it, and with
the plant's output declared free of its inputs the loop runs as the declared FMUs' does."""
import re

import numpy as np
import pytest

from helpers import rewrite_description, run_main, state_fmus, write_scenario
from mecanum_fmu import master, runner
from mecanum_fmu.errors import ScenarioError


@pytest.fixture(scope="module")
def bare(tmp_path_factory):
    """The test FMUs as built with their dependencies declared (helpers.state_fmus), and the
    lag and the P controller with every dependency taken out, as pythonfmu writes them."""
    folder = tmp_path_factory.mktemp("bare_fmus")
    fmus = state_fmus(folder)
    for stem in ("xtest_lag", "xtest_gain"):
        fmus[f"{stem}_bare"] = rewrite_description(
            fmus[stem], lambda xml: re.sub(r' dependencies="[^"]*"', "", xml),
            folder / f"{stem}_bare.fmu")
    return fmus


def _loop(folder, fmus, plant="xtest_lag_bare", ctrl="xtest_gain_bare", plant_extra="",
          ctrl_extra="", master_name="quadratic"):
    """cos t into a P controller u = 3 (r - x) around the lag x' = -2 x + u."""
    return write_scenario(folder, "loop", f"""\
name: loop
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.1, master: {master_name}}}
components:
  wave: {{fmu: {fmus["xtest_wave"]}}}
  ctrl: {{fmu: {fmus[ctrl]}, parameters: {{kp: 3.0}}{ctrl_extra}}}
  plant: {{fmu: {fmus[plant]}, parameters: {{k: 2.0}}{plant_extra}}}
connections:
  - [wave.u, ctrl.r]
  - [plant.x, ctrl.y]
  - [ctrl.u, plant.u]
outputs: [plant.x]
""")


def test_a_loop_of_fmus_that_declare_no_dependencies_is_refused_with_the_fix(tmp_path, bare,
                                                                          capsys):
    path = _loop(tmp_path, bare)
    code, out, err = run_main(capsys, "run", path, "--no-plots", "--out", tmp_path / "out")
    assert code == 2 and "Traceback" not in err, err
    assert str(path) in err and "connections[" in err and "algebraic loop" in err
    assert "ctrl.u, plant.x declare no dependencies" in err
    assert "`plant: {fmu: ..., dependencies: {x: []}}`" in err
    assert not (tmp_path / "out" / "summary.json").exists()


@pytest.mark.parametrize("master_name", ["quadratic", "trapezoidal", "gauss-seidel", "jacobi"])
def test_an_output_declared_free_of_its_inputs_in_the_scenario_breaks_the_loop(
        tmp_path, bare, master_name):
    # the run is that of the lag that declares it in its model description, to the bit; the
    # estimate is the pair's (the controller found without a state by a probe), within 3x of
    # the closed loop's ODE x' = -5 x + 3 cos t
    from scipy.integrate import solve_ivp
    graph = runner.prepare(_loop(tmp_path, bare, plant_extra=", dependencies: {x: []}",
                                 master_name=master_name))
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    summary = master.estimate_error(graph, results)
    (tmp_path / "declared").mkdir()
    declared = runner.prepare(_loop(tmp_path / "declared", bare, plant="xtest_lag",
                                    master_name=master_name))
    np.testing.assert_array_equal(
        master.simulate(declared, declared.scenario.experiment)["plant.x"], results["plant.x"])
    assert summary["error_estimate_method"].startswith("the embedded pair")
    x = solve_ivp(lambda t, y: [-5 * y[0] + 3 * np.cos(t)], (0.0, 6.0), [0.0],
                  t_eval=results.time, rtol=1e-12, atol=1e-14, method="DOP853").y[0]
    error = np.abs(results["plant.x"] - x)
    for which, value in (("max", error.max()), ("end", error[-1])):
        assert value / 3 <= summary["error_estimate"]["plant.x"][which] <= 3 * value


def test_the_scenarios_dependencies_belong_to_its_instance_alone(tmp_path, bare):
    # two instances of one FMU: the one that says `dependencies:` gets them, the other keeps
    # its model description's (none declared)
    path = write_scenario(tmp_path, "two", f"""\
name: two
experiment: {{start_time: 0.0, stop_time: 1.0, step_size: 0.1}}
components:
  wave: {{fmu: {bare["xtest_wave"]}}}
  one: {{fmu: {bare["xtest_gain_bare"]}, dependencies: {{u: [r]}}}}
  two: {{fmu: {bare["xtest_gain_bare"]}}}
connections: [[wave.u, one.r], [wave.u, two.r]]
""")
    graph = runner.prepare(path)
    deps = {i.name: [u.dependencies for u in i.model.outputs] for i in graph.instances}
    assert [[v.name for v in d] for d in deps["one"]] == [["r"]]
    assert deps["two"] == [None]


@pytest.mark.parametrize("entry,place,words", [
    ("{y: []}", "components.plant.dependencies.y", "'y' is not an output of this FMU"),
    ("{x: [v]}", "components.plant.dependencies.x", "'v' is not an input of this FMU"),
    ("{x: u}", "components.plant.dependencies.x", "a list of the FMU's input names"),
    ("[x]", "components.plant.dependencies", "expected a mapping of output"),
])
def test_a_wrong_dependencies_entry_names_its_place(tmp_path, bare, capsys, entry, place,
                                                    words):
    path = _loop(tmp_path, bare, plant_extra=f", dependencies: {entry}")
    code, _, err = run_main(capsys, "validate", path)
    assert code == 2 and place in err and words in err and "Traceback" not in err, err


def test_a_dependency_the_fmu_declares_is_not_overridden(tmp_path, bare, capsys):
    path = _loop(tmp_path, bare, plant="xtest_lag", ctrl="xtest_gain",
                 plant_extra=", dependencies: {x: [u]}")
    code, _, err = run_main(capsys, "validate", path)
    assert code == 2 and "components.plant.dependencies.x" in err, err
    assert "declares its dependencies (none)" in err and "remove this entry" in err


def test_export_ssp_says_the_scenarios_dependencies_are_not_in_the_fmus(tmp_path, bare,
                                                                        capsys):
    path = _loop(tmp_path, bare, plant_extra=", dependencies: {x: []}")
    code, out, err = run_main(capsys, "export-ssp", path, "-o", tmp_path / "loop.ssp")
    assert code == 0 and (tmp_path / "loop.ssp").is_file(), err
    assert "note: the dependencies: of plant are the scenario's" in err


def test_a_dependencies_claim_that_the_probe_contradicts_is_said(tmp_path, bare):
    # the other choice the loop's message offers, the controller's u declared free of its
    # inputs: u = 3 (r - y) moves with them within the step and keeps no trace a step later;
    # the run is the user's, the pair does not apply and says why
    graph = runner.prepare(_loop(tmp_path, bare, ctrl_extra=", dependencies: {u: []}"))
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    method = master.estimate_error(graph, results)["error_estimate_method"]
    assert "ctrl.u: the scenario's dependencies: says it depends on no input, but probed at " \
           "t = 0 s it moves with ctrl's inputs within the step" in method
    # the plant's {x: []} holds: the lag keeps a trace
    right = runner.prepare(_loop(tmp_path, bare, plant_extra=", dependencies: {x: []}"))
    again = master.simulate(right, right.scenario.experiment, with_estimate=True)
    assert "dependencies: says" not in master.estimate_error(right, again)[
        "error_estimate_method"]


def test_an_fmi3_output_gets_its_dependencies_from_the_scenario_too(tmp_path, bare):
    # pythonfmu3's lag (its dependencies taken out, as pythonfmu3 writes them) around the
    # pythonfmu controller: refused as a loop, then run with {x: []} and the pair applies
    from helpers import state_fmu3
    lag3 = rewrite_description(state_fmu3(tmp_path), lambda xml: re.sub(
        r' dependencies="[^"]*"', "", xml), tmp_path / "X3Bare.fmu")
    fmus = dict(bare, lag3=lag3)
    with pytest.raises(ScenarioError, match="plant: {fmu: ..., dependencies: {x: \\[\\]}}"):
        runner.prepare(_loop(tmp_path, fmus, plant="lag3"))
    graph = runner.prepare(_loop(tmp_path, fmus, plant="lag3",
                                 plant_extra=", dependencies: {x: []}"))
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    assert master.estimate_error(graph, results)["error_estimate_method"].startswith(
        "the embedded pair")


def test_info_says_a_scenario_may_declare_what_the_fmu_does_not(bare, capsys):
    code, out, _ = run_main(capsys, "info", bare["xtest_gain_bare"])
    assert code == 0 and "u  depends on: (not declared: all inputs)" in out
    assert "a scenario may declare what the FMU does not: `dependencies:" in out
    code, out, _ = run_main(capsys, "info", bare["xtest_gain"])
    assert code == 0 and "u  depends on: r, y" in out and "dependencies:" not in out


def _lag_alone(folder, fmu, master_name, extra="", parameters="k: 2.0", outputs="[it.x]"):
    """cos t into the lag x' = -2 x + u (the FMU `fmu`, its component `extra`)."""
    return write_scenario(folder, "alone", f"""\
name: alone
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.1, master: {master_name}}}
components:
  wave: {{fmu: {fmu["xtest_wave"]}}}
  it: {{fmu: {fmu["it"]}, parameters: {{{parameters}}}{extra}}}
connections: [[wave.u, it.u]]
outputs: {outputs}
""")


def _advised(path):
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    t = results.time        # x' = -2 x + cos t, x(0) = 0
    error = np.abs(results["it.x"] - (2 * np.cos(t) + np.sin(t) - 2 * np.exp(-2 * t)) / 5)
    return master.estimate_error(graph, results).get("error_estimate_advice", []), error.max()


def test_a_state_the_fmu_does_not_declare_gets_advice_that_pays(tmp_path, bare, capsys):
    # the lag as pythonfmu writes it: its input held at its end value, first order; the
    # probes find x without a direct part, and the advice's dependencies: hold it at its
    # step mean: an error 28x smaller at 0.1 s against the closed form, and no advice
    fmus = dict(bare, it=bare["xtest_lag_bare"])
    said, before = _advised(_lag_alone(tmp_path, fmus, "quadratic"))
    assert len(said) == 1 and "`it: {fmu: ..., dependencies: {x: []}}`" in said[0], said
    code, out, _ = run_main(capsys, "run", _lag_alone(tmp_path, fmus, "quadratic"),
                            "--no-plots", "--out", tmp_path / "out")
    assert code == 0 and "\nadvice: 'it' declares no output dependencies" in out
    said, after = _advised(_lag_alone(tmp_path, fmus, "quadratic", ", dependencies: {x: []}"))
    assert said == [] and after < before / 10, (before, after)


def test_no_advice_under_a_master_that_holds_the_newest_value(tmp_path, bare):
    # gauss-seidel holds a state's inputs at their newest value, declared or not
    said, _ = _advised(_lag_alone(tmp_path, dict(bare, it=bare["xtest_lag_bare"]),
                                  "gauss-seidel"))
    assert said == []


def test_the_advice_names_the_inputs_an_output_reads_directly(tmp_path, bare):
    # y = x + u as pythonfmu writes it: the probes measure y's direct part in u and none in
    # x's; declared so, u is held at its step mean while it steps and set to its end value
    # for y (plan.holds_through): the error falls by far more than at the lag alone
    fmus = dict(bare, it=rewrite_description(bare["xtest_through"], lambda xml: re.sub(
        r' dependencies="[^"]*"', "", xml), tmp_path / "through_bare.fmu"))
    said, before = _advised(_lag_alone(tmp_path, fmus, "quadratic"))
    assert len(said) == 1 and "`it: {fmu: ..., dependencies: {x: [], y: [u]}}`" in said[0], \
        said
    said, after = _advised(_lag_alone(tmp_path, fmus, "quadratic",
                                      ", dependencies: {x: [], y: [u]}"))
    assert said == [] and after < before / 10, (before, after)


def test_no_advice_where_an_output_is_worked_out_in_dostep_alone(tmp_path, bare):
    # y = x + u assigned in do_step (lazy = 1, pythonfmu's usual way): y does not follow u set
    # after the step, so declared y: [u] it would read u's step mean, a first-order error of
    # about h/2 u' (5.1e-2 at 0.1 s against 2.2e-2 as it is); the advice says why and names
    # the way out (a getter) instead of a dependencies: that trades y for x
    fmus = dict(bare, it=rewrite_description(bare["xtest_through"], lambda xml: re.sub(
        r' dependencies="[^"]*"', "", xml), tmp_path / "through_bare.fmu"))
    said, _ = _advised(_lag_alone(tmp_path, fmus, "quadratic", parameters="k: 2.0, lazy: 1",
                                  outputs="[it.x, it.y]"))
    assert len(said) == 1 and "its y is worked out in its doStep alone" in said[0], said
    assert "none is advised" in said[0] and "`getter=`" in said[0], said
    # y recorded by nothing and read by nothing: the declaration is a gain for x alone
    said, _ = _advised(_lag_alone(tmp_path, fmus, "quadratic", parameters="k: 2.0, lazy: 1"))
    assert len(said) == 1 and "`it: {fmu: ..., dependencies: {x: [], y: [u]}}`" in said[0], \
        said


def test_a_probe_before_the_run_that_fails_keeps_the_t0_row(tmp_path, bare, capsys):
    # the lag that declares no dependencies and whose fmi2GetFMUstate returns Fatal: the
    # probe at t0 stops the run with one message, and results.csv holds the t0 row
    nostate = rewrite_description(bare["xtest_nostate"], lambda xml: re.sub(
        r' dependencies="[^"]*"', "", xml), tmp_path / "nostate_bare.fmu")
    path = _lag_alone(tmp_path, dict(bare, it=nostate), "quadratic")
    out = tmp_path / "out"
    code, _, err = run_main(capsys, "run", path, "--no-plots", "--out", out)
    assert code == 1 and "Traceback" not in err, err
    assert "component 'it'" in err and "fmi2GetFMUstate returned Fatal" in err, err
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].split(",")[0] == "0.0", rows
