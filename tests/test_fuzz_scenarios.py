"""Property-based fuzzing of the scenario checks: mutate the valid circle scenario anywhere
(drop, rename or retype keys at any depth, random values, random connection strings), write
it with yaml.safe_dump and run `runner.prepare` (checks only, no simulation). It must either
succeed or raise ScenarioError with located, short messages - never any other exception."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

REPO = Path(__file__).resolve().parents[1]
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.runner import prepare

CIRCLE = yaml.safe_load((REPO / "scenarios" / "circle.yaml").read_text())

INSTANCES = ["source", "c2w", "w2c", "pose", "sourse", "", "x"]
VARIABLES = ["vx", "vy", "w", "w1", "w2", "w3", "w4", "x", "y", "theta", "alpha", "L",
             "vx_expr", "nope", "", "a.b"]
KEYS = ["name", "description", "experiment", "components", "connections", "outputs",
        "parameters", "start_time", "stop_time", "step_size", "master", "fmu", "from", "to",
        "alpha", "L", "W", "R", "x0", "theta0", "vx_expr", "vy_expr", "w_expr", "source",
        "c2w", "pose"]
WORDS = ["source.vx", "c2w.vx", "pose.theta", "w2c.w", "c2w.alpha", ".", "a.", ".b", "x.y.z",
         "VelocitySource", "Center2Wheel", "Wheel2Center", "PoseIntegrator", "nope.fmu", ".",
         "..", "/", "/dev/null", "fmus", "sin(t)", "1/0", "t**1000", "where(t<1, 1, 2)",
         "__import__('os')", "trapezoidal", "gauss-seidel", "jacobi", "", " ", "\x00",
         "a\x00b.fmu", "0", "1e308", "-1"]

text = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=30)
connection_string = st.builds(lambda a, b: f"{a}.{b}", st.sampled_from(INSTANCES) | text,
                              st.sampled_from(VARIABLES) | text) | text
scalars = (st.none() | st.booleans() | st.integers(-10**20, 10**20)
           | st.sampled_from([10**400, -10**309, 2**63, 0, -0.0, 1e-320])
           | st.floats(allow_nan=True, allow_infinity=True) | text
           | st.builds(lambda c, n: c * n, st.sampled_from(["x", "/", "a.", "9"]),
                       st.integers(200, 5000))
           | st.sampled_from(WORDS) | connection_string)
keys = st.sampled_from(KEYS) | text | st.integers(-5, 5) | st.booleans()
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(keys, inner, max_size=4), max_leaves=10)
connections = st.lists(st.lists(connection_string, min_size=0, max_size=3)
                       | st.fixed_dictionaries({"from": connection_string, "to": connection_string})
                       | values, max_size=6)


def spots(node, out=None):
    """Every (container, key-or-index) in the document, depth first."""
    out = [] if out is None else out
    if isinstance(node, dict):
        for key in list(node):
            out.append((node, key))
            spots(node[key], out)
    elif isinstance(node, list):
        for i in range(len(node)):
            out.append((node, i))
            spots(node[i], out)
    return out


def mutate(data, doc):
    found = spots(doc)
    if not found:
        return data.draw(values)
    parent, key = data.draw(st.sampled_from(found))
    op = data.draw(st.sampled_from(["drop", "rename", "replace", "replace", "add",
                                    "connections", "root"]))
    if op == "root":
        return data.draw(values)
    if op == "connections" and isinstance(doc, dict):
        doc["connections"] = data.draw(connections)
    elif op == "drop":
        del parent[key]
    elif op == "rename" and isinstance(parent, dict):
        new = data.draw(keys)
        parent[new] = parent.pop(key)
    elif op == "add" and isinstance(parent, dict):
        parent[data.draw(keys)] = data.draw(values)
    elif op == "add":
        parent.append(data.draw(values))
    else:
        parent[key] = data.draw(values)
    return doc


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@settings(max_examples=250, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large])
@given(data=st.data())
def test_prepare_succeeds_or_raises_scenario_error(workdir, data):
    doc = copy.deepcopy(CIRCLE)
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        doc = mutate(data, doc)
    path = workdir / "fuzzed.yaml"
    path.write_text(yaml.safe_dump(doc, allow_unicode=True), encoding="utf-8")
    try:
        prepare(path, fmu_dir=REPO / "fmus")
    except ScenarioError as err:
        assert err.problems
        for problem in err.problems:
            assert problem.file == str(path)
            assert problem.message
            assert len(str(problem)) < 2000, str(problem)[:300]
