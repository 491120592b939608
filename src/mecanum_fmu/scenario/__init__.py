"""The scenario layer, in the order its data flows: a scenario file (YAML, document.py; an SSP
archive, interop/ssp_read.py) -> Scenario -> its tables (profiles.py, recorded.py, bags.py,
tables.py) -> the checked, ordered Graph (graph.py, with plausibility.py's warnings); and the
API's argument checks over them (arguments.py).

The loader's public names are handed on here, so `mecanum_fmu.scenario.load_scenario_dict`
and the rest stay where the README names them."""
from .document import (Component, Connection, Experiment, Scalar, Scenario, VarRef,  # noqa: F401
                       load_scenario, load_scenario_dict, read_scenario)
