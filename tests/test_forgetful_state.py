"""An FMU whose saved state misses some of what it holds (tests/fmu_sources/forgetful: a
pythonfmu switch that keeps its opening in an attribute it does not register): Richardson's
coarser runs start from every FMU's state set back to t0 (master/coarse.py), and a number
made from them would be made up. The coarser runs agree to round-off where the run differs
from them, which no order of the step explains: the estimate says so instead."""
from pathlib import Path

import numpy as np
import pytest

from helpers import FMU_SOURCES, write_scenario
from mecanum_fmu import master, runner
from mecanum_fmu.master.richardson import NOT_THE_STEP


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    from pythonfmu import FmuBuilder
    dest = tmp_path_factory.mktemp("forgetful")
    return {script.stem: Path(FmuBuilder.build_FMU(script, dest=dest,
                                                   canGetAndSetFMUstate=True))
            for script in (FMU_SOURCES / "forgetful" / "xtest_switch.py",
                           FMU_SOURCES / "with_state" / "xtest_lag.py")}


@pytest.mark.parametrize("master_name", ["quadratic", "gauss-seidel"])
def test_coarser_runs_from_a_state_that_forgets_are_not_taken_for_the_steps_error(
        tmp_path, fmus, master_name):
    # the switch opens at 1 s; set back to t0 after the run, it stays open, so both coarser
    # runs feed the lag 0 throughout and agree to the bit. Before, Richardson read their
    # difference from the run as the step's error: 0.83 where the lag's x is 0.43 at most
    path = write_scenario(tmp_path, "switch", f"""\
name: switch
experiment: {{start_time: 0.0, stop_time: 3.0, step_size: 0.1, master: {master_name},
             estimate: richardson}}
components:
  switch: {{fmu: {fmus["xtest_switch"]}}}
  lag: {{fmu: {fmus["xtest_lag"]}, parameters: {{k: 2.0}}}}
connections:
  - [switch.u, lag.u]
outputs: [lag.x]
""")
    graph = runner.prepare(path)
    results = master.simulate(graph, graph.scenario.experiment, with_estimate=True)
    assert np.ptp(results["lag.x"]) > 0.3       # the run itself saw the switch open
    estimate = master.estimate_error(graph, results)["error_estimate"]["lag.x"]
    assert estimate == {"max": NOT_THE_STEP, "end": NOT_THE_STEP}, estimate
