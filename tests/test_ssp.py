"""SSP 1.0 export/import: structure, XSD validity, bit-identical round trip, a third-party
SSP, a broken SSP, and the `doctor` command."""
import io
import json
import shutil
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from helpers import CHAIN_CONNECTIONS, child_env, run_child, run_main
from mecanum_fmu.models.library import read_description
from mecanum_fmu.scenario.graph import compile_graph, port_type
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.scenario.document import load_scenario
from mecanum_fmu.interop import ssp, ssp_read, ssp_write

REPO = Path(__file__).resolve().parents[1]
CIRCLE = REPO / "scenarios" / "circle.yaml"
SCHEMA_DIR = None
try:
    import fmpy
    SCHEMA_DIR = Path(fmpy.__file__).parent / "ssp" / "schema"
except ImportError:  # pragma: no cover
    pass
N = ssp.NS


def q(prefix, tag):
    return f"{{{N[prefix]}}}{tag}"


@pytest.fixture(autouse=True)
def cache_home(tmp_path_factory, monkeypatch):
    """Keep the extraction cache out of the user's home."""
    home = tmp_path_factory.getbasetemp() / "xdg_cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(home))
    return home


@pytest.fixture(scope="module")
def circle_graph(fmu_dir):
    return compile_graph(load_scenario(CIRCLE), fmu_dir)


@pytest.fixture(scope="module")
def exported_once(circle_graph, tmp_path_factory):
    """The circle's SSP, exported once for the module (an export is the same bytes each time:
    test_export_is_deterministic)."""
    return ssp_write.export_ssp(circle_graph, tmp_path_factory.mktemp("ssp") / "circle.ssp")


@pytest.fixture
def exported(exported_once, tmp_path):
    """A copy of the circle's SSP in the test's own folder."""
    return Path(shutil.copy(exported_once, tmp_path / "circle.ssp"))


def cli(*args, cwd=None, env_extra=None):
    return run_child(*args, cwd=cwd, env=child_env(**(env_extra or {})))


def ssd_root(path):
    with zipfile.ZipFile(path) as zf:
        return ET.fromstring(zf.read("SystemStructure.ssd"))


# ------------------------------------------------------------------------------------ export

def test_export_structure_and_content(exported, circle_graph, built_fmus):
    graph = circle_graph
    with zipfile.ZipFile(exported) as zf:
        names = zf.namelist()
        assert names[0] == "SystemStructure.ssd"
        used = sorted({i.model_name for i in graph.instances})   # the circle's four models
        assert sorted(names[1:]) == sorted(f"resources/{m}.fmu" for m in used)
        for model in used:                           # each FMU inside, byte for byte
            assert zf.read(f"resources/{model}.fmu") == built_fmus[model].read_bytes()
        assert {i.date_time for i in zf.infolist()} == {(1980, 1, 1, 0, 0, 0)}
    root = ssd_root(exported)
    assert root.tag == q("ssd", "SystemStructureDescription")
    assert root.get("version") == "1.0" and root.get("name") == "circle"
    system = root.find(q("ssd", "System"))
    comps = system.findall(f"{q('ssd', 'Elements')}/{q('ssd', 'Component')}")
    assert [c.get("name") for c in comps] == [c.name for c in graph.scenario.components]
    for comp in comps:
        inst = graph.instance(comp.get("name"))
        assert comp.get("source") == f"resources/{inst.model_name}.fmu"
        assert comp.get("type") == "application/x-fmu-sharedlibrary"
        # connectors: names, kinds and types as in the FMU's own model description
        md = read_description(inst.fmu_path)
        # (bundled models: no String parameters - their values are the FMU's own defaults)
        expected = {v.name: (v.causality, port_type(v)) for v in md.modelVariables
                    if v.causality in ("input", "output", "parameter")
                    and not (v.causality == "parameter" and v.type == "String")}
        got = {}
        for c in comp.find(q("ssd", "Connectors")):
            (typ,) = list(c)
            assert typ.tag.startswith("{%s}" % N["ssc"])
            got[c.get("name")] = (c.get("kind"), typ.tag.split("}")[1])
        assert got == expected
        # every start value is bound, with its type and exact value
        params = {}
        for p in comp.iter(q("ssv", "Parameter")):
            (val,) = list(p)
            params[p.get("name")] = (val.tag.split("}")[1], val.get("value"))
        types = {v.name: v.type for v in md.modelVariables}
        want = {k: (types[k], repr(float(v)) if types[k] == "Real" else str(v))
                for k, v in inst.start_values.items() if types[k] != "String"}
        assert params == want
    assert len(graph.instance("c2w").start_values) == 4        # the shared geometry
    assert "vy_expr" not in params_of(comps, "source")         # cos(t): the FMU's default
    conns = [(c.get("startElement"), c.get("startConnector"), c.get("endElement"),
              c.get("endConnector")) for c in system.iter(q("ssd", "Connection"))]
    assert conns == [(c.source.instance, c.source.variable, c.target.instance,
                      c.target.variable) for c in graph.scenario.connections]
    assert len(conns) == 10
    default = root.find(q("ssd", "DefaultExperiment"))
    assert (float(default.get("startTime")), float(default.get("stopTime"))) == (0.0, 10.0)
    ours = default.find(f".//{q('mf', 'Experiment')}")
    assert ours.get("stepSize") == "0.05" and ours.get("master") == "quadratic"


def params_of(comps, name):
    comp = next(c for c in comps if c.get("name") == name)
    return {p.get("name"): (p[0].tag.split("}")[1], p[0].get("value"))
            for p in comp.iter(q("ssv", "Parameter"))}


TYPED = """\
name: typed
experiment: {start_time: 0.0, stop_time: 2.0, step_size: 0.05, master: jacobi}
components:
  source: {fmu: VelocitySource, parameters: {vx_expr: "2.5", vy_expr: "0", w_expr: "0"}}
  c2w: {fmu: Center2Wheel}
  w2c: {fmu: Wheel2Center}
  pose: {fmu: PoseIntegrator, parameters: {x0: 5, y0: -1}}
""" + CHAIN_CONNECTIONS


def test_values_take_the_fmu_variables_type_and_baked_strings_leave_the_ssd(fmu_dir,
                                                                            tmp_path):
    """x0: 5 (a YAML int) sets a Real: written as ssv:Real 5.0; the String expressions are
    baked into a variant FMU, so the SSD has neither their connectors nor their bindings
    (OMSimulator reports an error for each); imported again, the value is the Real 5.0 and
    the run ends where x0 = 5.0 puts it: x = 5 + 2.5 * 2."""
    from helpers import write_scenario
    from mecanum_fmu import master
    from mecanum_fmu.runner import prepare
    graph = prepare(write_scenario(tmp_path, "typed", TYPED), fmu_dir=fmu_dir)
    path = ssp_write.export_ssp(graph, tmp_path / "typed.ssp")
    comps = list(ssd_root(path).iter(q("ssd", "Component")))
    assert params_of(comps, "pose") == {"x0": ("Real", "5.0"), "y0": ("Real", "-1.0")}
    source = next(c for c in comps if c.get("name") == "source")
    assert source.get("source").startswith("resources/VelocitySource_")       # the variant
    assert not [e for e in source.iter() if e.tag in (q("ssc", "String"), q("ssv", "String"))]
    again = prepare(path, fmu_dir=fmu_dir)
    values = again.instance("pose").start_values
    assert values["x0"] == 5.0 and type(values["x0"]) is float
    results = master.simulate(again, again.scenario.experiment)
    assert results["pose.x"][-1] == pytest.approx(10.0, abs=1e-12)
    assert results["pose.y"][-1] == pytest.approx(-1.0, abs=1e-12)


DEFAULTS = """\
name: defaults
experiment: {start_time: 0.0, stop_time: 2.0, step_size: 0.1, master: gauss-seidel}
components:
  source: {fmu: VelocitySource}
  pose: {fmu: PoseIntegrator}
connections:
  - [source.vx, pose.vx]
  - [source.vy, pose.vy]
  - [source.w, pose.w]
"""


def test_a_baked_variant_and_its_original_each_run_their_own_script_in_one_process(
        fmu_dir, tmp_path):
    """pythonfmu imports a slave script by its module name, once per process: the variant
    has a module name of its own, so the original at its defaults (vx = sin t, docs/spec.md,
    The seed scenario), then the exported SSP's variant (vx = 2.5, nothing in the SSD sets
    it), then the original again each run their own script in this one process."""
    from helpers import write_scenario
    from mecanum_fmu import master
    from mecanum_fmu.runner import prepare
    plain = prepare(write_scenario(tmp_path, "defaults", DEFAULTS), fmu_dir=fmu_dir)
    graph = prepare(write_scenario(tmp_path, "typed", TYPED), fmu_dir=fmu_dir)
    path = ssp_write.export_ssp(graph, tmp_path / "typed.ssp")
    with zipfile.ZipFile(path) as zf:
        variant = next(n for n in zf.namelist() if n.startswith("resources/VelocitySource_"))
        variant = io.BytesIO(zf.read(variant))
    modules = []
    for fmu in (fmu_dir / "VelocitySource.fmu", variant):
        with zipfile.ZipFile(fmu) as zf:
            modules.append(zf.read("resources/slavemodule.txt").decode().strip())
    assert modules[1].startswith(modules[0] + "_") and len(set(modules)) == 2
    for run in ("plain", "variant", "plain"):
        if run == "plain":
            results = master.simulate(plain, plain.scenario.experiment)
            assert np.allclose(results["source.vx"], np.sin(results.time), atol=1e-12, rtol=0)
        else:
            again = prepare(path, fmu_dir=fmu_dir)
            results = master.simulate(again, again.scenario.experiment)
            assert results["pose.x"][-1] == pytest.approx(10.0, abs=1e-12)


def test_ssp_import_types_an_integer_binding_for_a_real_as_real(exported, tmp_path):
    """An SSP from another tool with <ssv:Integer value="5"/> for the Real x0 imports as 5.0."""
    with zipfile.ZipFile(exported) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    ssd = members["SystemStructure.ssd"].decode()
    ours = '<ssd:Component name="pose"'
    assert ours in ssd
    at = ssd.index(ours)
    end = ssd.index("</ssd:Component>", at)
    block = ssd[at:end]
    bound = block.replace("</ssv:Parameters>", '<ssv:Parameter name="x0"><ssv:Integer '
                          'value="5"/></ssv:Parameter></ssv:Parameters>')
    if "<ssd:ParameterBindings>" not in block:
        bound = block.replace("</ssd:Connectors>", "</ssd:Connectors><ssd:ParameterBindings>"
                              "<ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet "
                              'version="1.0" name="initialValues"><ssv:Parameters>'
                              '<ssv:Parameter name="x0"><ssv:Integer value="5"/></ssv:Parameter>'
                              "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
                              "</ssd:ParameterBinding></ssd:ParameterBindings>")
    members["SystemStructure.ssd"] = (ssd[:at] + bound + ssd[end:]).encode()
    with zipfile.ZipFile(tmp_path / "int.ssp", "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    comp = next(c for c in ssp_read.load_ssp(tmp_path / "int.ssp").components if c.name == "pose")
    assert comp.parameters["x0"] == 5.0 and type(comp.parameters["x0"]) is float


def test_export_is_deterministic(circle_graph, tmp_path):
    a = ssp_write.export_ssp(circle_graph, tmp_path / "a.ssp").read_bytes()
    b = ssp_write.export_ssp(circle_graph, tmp_path / "b.ssp").read_bytes()
    assert a == b


@pytest.mark.skipif(SCHEMA_DIR is None or not (SCHEMA_DIR / "SystemStructureDescription.xsd")
                    .is_file(), reason="fmpy's SSP schema not installed")
def test_export_validates_against_ssp_1_0_xsd(exported):
    etree = pytest.importorskip("lxml.etree")
    schema = etree.XMLSchema(file=str(SCHEMA_DIR / "SystemStructureDescription.xsd"))
    with zipfile.ZipFile(exported) as zf:
        doc = etree.fromstring(zf.read("SystemStructure.ssd"))
    assert schema.validate(doc), schema.error_log


def test_fmpy_reads_the_export(exported):
    read_ssd = pytest.importorskip("fmpy.ssp.ssd").read_ssd
    desc = read_ssd(str(exported))
    assert [e.name for e in desc.system.elements] == ["source", "c2w", "w2c", "pose"]
    assert len(desc.system.connections) == 10


def test_cli_export(tmp_path, fmu_dir):
    out = tmp_path / "sub" / "circle.ssp"
    proc = cli("export-ssp", CIRCLE, "-o", out, "--fmu-dir", fmu_dir)
    assert proc.returncode == 0, proc.stderr
    assert out.is_file() and "4 components, 10 connections" in proc.stdout


# ------------------------------------------------------------------------------------ import

def test_load_ssp_gives_the_same_scenario(exported, circle_graph, fmu_dir, cache_home):
    scenario = ssp_read.load_ssp(exported)
    orig = circle_graph.scenario
    assert scenario.name == orig.name and scenario.experiment == orig.experiment
    assert [(c.source, c.target) for c in scenario.connections] == \
        [(c.source, c.target) for c in orig.connections]
    graph = compile_graph(scenario, fmu_dir)
    for inst in graph.instances:
        want = circle_graph.instance(inst.name)
        strings = {v.name: v.start for v in inst.model.modelVariables if v.type == "String"}
        # String values travel in the FMU (its defaults, baked when they differ), not the SSD
        assert inst.start_values == {k: v for k, v in want.start_values.items()
                                     if k not in strings}
        assert all(strings[k] == v for k, v in want.start_values.items() if k in strings)
        assert [type(v) for v in inst.start_values.values()] == \
            [type(want.start_values[k]) for k in inst.start_values]
        assert inst.model.guid == want.model.guid
    assert [i.name for i in graph.instances] == [i.name for i in circle_graph.instances]
    assert [l.place for l in graph.links] and \
        [(str(l.source.ref), str(l.target.ref)) for l in graph.links] == \
        [(str(l.source.ref), str(l.target.ref)) for l in circle_graph.links]
    # the FMUs are extracted once, into a cache folder keyed by the archive's sha256
    import hashlib
    digest = hashlib.sha256(exported.read_bytes()).hexdigest()
    paths = {c.fmu for c in scenario.components}
    assert all(Path(p).parent == cache_home / "mecanum_fmu" / "ssp" / digest / "resources"
               for p in paths)
    mtimes = {p: Path(p).stat().st_mtime_ns for p in paths}
    again = ssp_read.load_ssp(exported)
    assert {c.fmu for c in again.components} == paths
    assert {p: Path(p).stat().st_mtime_ns for p in paths} == mtimes


def test_round_trip_is_bit_identical(exported, tmp_path, fmu_dir, capsys):
    """`run` of the YAML and of its SSP, in this process (cli.main; the extraction cache is
    cache_home's): the same results.csv, end pose and step count."""
    for master in ("trapezoidal", "jacobi"):
        a, b = tmp_path / f"yaml-{master}", tmp_path / f"ssp-{master}"
        code_a, _, err_a = run_main(capsys, "run", CIRCLE, "--out", a, "--no-plots", "-q",
                                    "--master", master, "--fmu-dir", fmu_dir)
        code_b, _, err_b = run_main(capsys, "run", exported, "--out", b, "--no-plots", "-q",
                                    "--master", master)
        assert code_a == 0, err_a
        assert code_b == 0, err_b
        assert (a / "results.csv").read_bytes() == (b / "results.csv").read_bytes()
        sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
        assert sa["end_pose"] == sb["end_pose"] and sa["steps"] == sb["steps"]
    code, out, _ = run_main(capsys, "validate", exported)
    assert code == 0 and "ok - 4 components, 10 connections" in out


THIRD_PARTY = """<?xml version="1.0" encoding="UTF-8"?>
<!-- as another tool would write it: its own prefixes, its own order, no mecanum annotation -->
<SystemStructureDescription xmlns="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:c="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:v="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    version="1.0" name="third party car">
  <System name="Root">
    <Elements>
      <Component name="integrator" source="resources/pose.fmu">
        <Connectors>
          <Connector name="y" kind="output"><c:Real/></Connector>
          <Connector name="x" kind="output"><c:Real/></Connector>
          <Connector name="w" kind="input"><c:Real/></Connector>
          <Connector name="vy" kind="input"><c:Real/></Connector>
          <Connector name="vx" kind="input"><c:Real/></Connector>
        </Connectors>
      </Component>
      <Component name="fwd" source="./resources/kin/Fwd.fmu" type="application/x-fmu-sharedlibrary"/>
      <Component name="inv" source="resources/kin/Inv.fmu">
        <ParameterBindings>
          <ParameterBinding source="resources/geometry.ssv"/>
        </ParameterBindings>
      </Component>
      <Component name="cmd" source="resources/cmd.fmu">
        <ParameterBindings>
          <ParameterBinding>
            <ParameterValues>
              <v:ParameterSet version="1.0" name="command">
                <v:Parameters>
                  <v:Parameter name="vy_expr"><v:String value="0.5"/></v:Parameter>
                  <v:Parameter name="vx_expr"><v:String value="0.2"/></v:Parameter>
                  <v:Parameter name="w_expr"><v:String value="0"/></v:Parameter>
                </v:Parameters>
              </v:ParameterSet>
            </ParameterValues>
          </ParameterBinding>
        </ParameterBindings>
      </Component>
    </Elements>
    <Connections>
      <Connection startElement="fwd" startConnector="w" endElement="integrator" endConnector="w"/>
      <Connection startElement="inv" startConnector="w4" endElement="fwd" endConnector="w4"/>
      <Connection startElement="cmd" startConnector="vy" endElement="inv" endConnector="vy"/>
      <Connection startElement="fwd" startConnector="vx" endElement="integrator" endConnector="vx"/>
      <Connection startElement="inv" startConnector="w1" endElement="fwd" endConnector="w1"/>
      <Connection startElement="cmd" startConnector="w" endElement="inv" endConnector="w"/>
      <Connection startElement="inv" startConnector="w3" endElement="fwd" endConnector="w3"/>
      <Connection startElement="fwd" startConnector="vy" endElement="integrator" endConnector="vy"/>
      <Connection startElement="inv" startConnector="w2" endElement="fwd" endConnector="w2"/>
      <Connection startElement="cmd" startConnector="vx" endElement="inv" endConnector="vx"/>
    </Connections>
  </System>
  <DefaultExperiment startTime="0" stopTime="4"/>
</SystemStructureDescription>
"""

GEOMETRY_SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    version="1.0" name="geometry">
  <ssv:Parameters>
    <ssv:Parameter name="R"><ssv:Real value="0.05"/></ssv:Parameter>
    <ssv:Parameter name="L"><ssv:Real value="0.2"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>
"""
# inv (Center2Wheel) gets R = 0.05, L = 0.2 while fwd (Wheel2Center) keeps the defaults
# R = 0.06, L = 0.16: with w = 0 the wheel speeds scale by 0.06/0.05 and the rotation part
# cancels, so the commanded (0.2, 0.5) m/s comes out as (0.24, 0.6) m/s: after 4 s (0.96, 2.4).
THIRD_PARTY_FILES = {"resources/pose.fmu": "PoseIntegrator",
                     "resources/kin/Fwd.fmu": "Wheel2Center",
                     "resources/kin/Inv.fmu": "Center2Wheel",
                     "resources/cmd.fmu": "VelocitySource"}


def write_third_party(dest: Path, built_fmus, ssd_text=THIRD_PARTY, bare=False) -> Path:
    if bare:
        folder = dest / "third_party"
        for name, model in THIRD_PARTY_FILES.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(built_fmus[model], folder / name)
        (folder / "resources" / "geometry.ssv").write_text(GEOMETRY_SSV)
        (folder / "car.ssd").write_text(ssd_text)
        return folder / "car.ssd"
    path = dest / "third_party.ssp"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, model in sorted(THIRD_PARTY_FILES.items(), reverse=True):
            zf.write(built_fmus[model], name)
        zf.writestr("resources/geometry.ssv", GEOMETRY_SSV)
        zf.writestr("SystemStructure.ssd", ssd_text)
    return path


@pytest.mark.parametrize("bare", [False, True], ids=["ssp", "bare-ssd"])
def test_third_party_ssp_runs_under_our_master(bare, tmp_path, built_fmus, capsys):
    path = write_third_party(tmp_path, built_fmus, bare=bare)
    scenario = ssp_read.load_ssp(path)
    assert scenario.name == "third_party_car"
    assert scenario.experiment.stop_time == 4.0
    assert scenario.experiment.master == "quadratic"          # defaults: no annotation
    params = {c.name: c.parameters for c in scenario.components}
    assert params["cmd"] == {"vy_expr": "0.5", "vx_expr": "0.2", "w_expr": "0"}
    assert params["inv"] == {"R": 0.05, "L": 0.2}
    out = tmp_path / "out"
    code, _, err = run_main(capsys, "run", path, "--out", out, "--no-plots")   # cache_home's
    assert code == 0, err
    end = json.loads((out / "summary.json").read_text())["end_pose"]
    assert end["x"] == pytest.approx(0.96, abs=1e-9)
    assert end["y"] == pytest.approx(2.4, abs=1e-9)
    assert end["theta"] == pytest.approx(0.0, abs=1e-12)


def test_broken_ssp_unknown_connector_exits_2(tmp_path, built_fmus, cache_home):
    env = {"XDG_CACHE_HOME": str(cache_home)}
    # connector not among the component's declared connectors: found by the SSP reader
    text = THIRD_PARTY.replace('startConnector="vy" endElement="inv" endConnector="vy"',
                               'startConnector="vy" endElement="inv" endConnector="vz"')
    path = write_third_party(tmp_path, built_fmus, text)
    out = tmp_path / "out"
    proc = cli("run", path, "--out", out, "--no-plots", env_extra=env)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "SystemStructure.ssd: Connections/Connection[3]" in proc.stderr
    assert "'vz'" in proc.stderr and str(path) in proc.stderr
    assert not out.exists()
    # no Connectors declared: the graph check names the same SSD place
    text = THIRD_PARTY.replace('startConnector="w4" endElement="fwd" endConnector="w4"',
                               'startConnector="w4" endElement="fwd" endConnector="w5"')
    path = write_third_party(tmp_path / "b", built_fmus, text, bare=True)
    proc = cli("validate", path, env_extra=env)
    assert proc.returncode == 2, proc.stderr
    assert "car.ssd: Connections/Connection[2]: " in proc.stderr
    assert "instance 'fwd' has no variable 'w5'" in proc.stderr


@pytest.mark.parametrize("edit, place, message", [
    (('source="resources/cmd.fmu"', 'source="resources/nothere.fmu"'),
     "Component[4][@name='cmd']/@source", "not found in the archive"),
    (('source="resources/cmd.fmu"', 'source="../../etc/passwd"'),
     "Component[4][@name='cmd']/@source", "relative path inside"),
    (('<v:String value="0.5"/>', '<v:Real value="fast"/>'),
     "Parameter[1][@name='vy_expr']", "not a valid Real"),
    (('stopTime="4"', 'stopTime="-1"'), "DefaultExperiment", "must be after start_time"),
    (('</System>', '</System'), "line", "XML syntax error"),
])
def test_broken_ssp_places(edit, place, message, tmp_path, built_fmus):
    text = THIRD_PARTY.replace(*edit)
    assert text != THIRD_PARTY
    path = write_third_party(tmp_path, built_fmus, text)
    with pytest.raises(ScenarioError) as info:
        ssp_read.load_ssp(path)
    report = str(info.value)
    assert "SystemStructure.ssd: " in report and place in report and message in report, report


def test_not_an_ssp(tmp_path):
    bad = tmp_path / "x.ssp"
    bad.write_text("hello")
    with pytest.raises(ScenarioError, match="not an SSP archive"):
        ssp_read.load_ssp(bad)
    with zipfile.ZipFile(tmp_path / "y.ssp", "w") as zf:
        zf.writestr("other.txt", "x")
    with pytest.raises(ScenarioError, match="has no SystemStructure.ssd"):
        ssp_read.load_ssp(tmp_path / "y.ssp")


# ------------------------------------------------------------------------------------ doctor

def test_doctor_reports_what_each_fmu_needs(fmu_dir, built_fmus):
    """Per FMU: self-contained, the glibc floor of its binaries, and the win64 story."""
    import re
    from elftools.elf.elffile import ELFFile
    proc = cli("doctor", "--fmu-dir", fmu_dir)
    assert proc.returncode == 0, proc.stderr
    for model, fmu in built_fmus.items():
        line = next(l for l in proc.stdout.splitlines() if l.strip().startswith(f"{model}:"))
        assert "linux64: self-contained" in line, line
        assert "win64: pythonfmu's own DLL, NOT self-contained" in line and "python3.dll" in line
        # the floor, independently: the newest GLIBC_ version named in any binary's
        # version-needed table (.gnu.version_r), read here with pyelftools directly
        floor = (0,)
        with zipfile.ZipFile(fmu) as zf:
            for name in zf.namelist():
                if name.endswith(".so") or ".so." in name:
                    import io
                    elf = ELFFile(io.BytesIO(zf.read(name)))
                    section = elf.get_section_by_name(".gnu.version_r")
                    for _, auxes in section.iter_versions() if section else ():
                        for aux in auxes:
                            if re.fullmatch(r"GLIBC_[\d.]+", aux.name):
                                floor = max(floor, tuple(map(int, aux.name[6:].split("."))))
        assert f"glibc >= {'.'.join(map(str, floor))} " in line, (floor, line)
    assert "LD_PRELOAD=" not in proc.stdout      # no preload line: nothing to preload