"""SSP 1.0 export: a compiled scenario as an .ssp archive (SystemStructure.ssd plus each
distinct FMU once under resources/), byte-identical for the same scenario and FMUs."""
from __future__ import annotations

import re
from pathlib import Path
from xml.etree import ElementTree as ET

from ..scenario.graph import port_type
from ..scenario.document import Scalar
from . import ssp_bake, ssp_vendor
from .ssp import ANNOTATION_TYPE, FMU_MIME, PARAMETER_SET, SSD_NAME, VALUE_TAGS, as_type, q
from ..output import check_output_file, output_file
from ..storage import write_zip

OPTION = "export-ssp -o"      # how messages name the archive's path


def _format(value: Scalar, kind: str | None = None) -> tuple[str, str]:
    """(SSV/SSC type tag, value text) for a start value, typed as the FMU variable it sets
    (kind, when known); repr keeps floats bit-exact."""
    value = as_type(value, kind)
    if isinstance(value, bool):
        return "Boolean", "true" if value else "false"
    if isinstance(value, int):
        return "Integer", str(value)
    if isinstance(value, float):
        return "Real", repr(value)
    return "String", str(value)


def build_ssd(graph, sources: dict[str, str], strings_in_fmu: set[str] = frozenset()) -> bytes:
    """The SystemStructure.ssd text of a compiled graph; sources: instance -> FMU source URI;
    strings_in_fmu: instances whose String parameters are their FMU's own defaults (bundled
    models, baked or at the default): no String parameter connector or binding is written for
    those (OMSimulator cannot import either and reports an error for each)."""
    scenario = graph.scenario
    exp = scenario.experiment
    root = ET.Element(q("ssd", "SystemStructureDescription"),
                      {"version": "1.0", "name": scenario.name})
    if scenario.description:
        root.set("description", scenario.description)
    system = ET.SubElement(root, q("ssd", "System"), {"name": scenario.name})
    elements = ET.SubElement(system, q("ssd", "Elements"))
    for comp in scenario.components:          # declared order: it fixes ties in step order
        inst = graph.instance(comp.name)
        node = ET.SubElement(elements, q("ssd", "Component"), {
            "name": inst.name, "type": FMU_MIME, "source": sources[inst.name]})
        kinds = {var.name: port_type(var) for var in inst.model.modelVariables}
        skip = ({v.name for v in inst.model.modelVariables
                 if v.causality == "parameter" and kinds[v.name] == "String"}
                if inst.name in strings_in_fmu else set())
        _connectors(node, inst, skip)
        _bindings(node, {k: v for k, v in inst.start_values.items() if k not in skip}, kinds)
    connections = ET.SubElement(system, q("ssd", "Connections"))
    for conn in scenario.connections:         # declared order, like the YAML
        ET.SubElement(connections, q("ssd", "Connection"), {
            "startElement": conn.source.instance, "startConnector": conn.source.variable,
            "endElement": conn.target.instance, "endConnector": conn.target.variable})
    if not len(connections):
        system.remove(connections)
    default = ET.SubElement(root, q("ssd", "DefaultExperiment"),
                            {"startTime": repr(exp.start_time), "stopTime": repr(exp.stop_time)})
    annotations = ET.SubElement(default, q("ssd", "Annotations"))
    annotation = ET.SubElement(annotations, q("ssc", "Annotation"), {"type": ANNOTATION_TYPE})
    ours = ET.SubElement(annotation, q("mf", "Experiment"),
                         {"stepSize": repr(exp.step_size), "master": exp.master})
    if scenario.outputs is not None:
        for ref, _place in scenario.outputs:
            ET.SubElement(ours, q("mf", "Output"), {"name": str(ref)})
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _connectors(node, inst, skip: set[str]) -> None:
    connectors = ET.SubElement(node, q("ssd", "Connectors"))
    for var in inst.model.modelVariables:
        if var.causality not in ("input", "output", "parameter") or var.name in skip \
                or getattr(var, "dimensions", None):     # an FMI 3.0 array: SSP 1.0 has none
            continue
        conn = ET.SubElement(connectors, q("ssd", "Connector"),
                             {"name": var.name, "kind": var.causality})
        kind = port_type(var)
        if kind in VALUE_TAGS:
            ET.SubElement(conn, q("ssc", kind))   # units left out: no ssd:Units table


def _bindings(node, start_values: dict, kinds: dict[str, str]) -> None:
    if not start_values:
        return
    bindings = ET.SubElement(node, q("ssd", "ParameterBindings"))
    binding = ET.SubElement(bindings, q("ssd", "ParameterBinding"))
    values = ET.SubElement(binding, q("ssd", "ParameterValues"))
    pset = ET.SubElement(values, q("ssv", "ParameterSet"),
                         {"version": "1.0", "name": PARAMETER_SET})
    params = ET.SubElement(pset, q("ssv", "Parameters"))
    for key in sorted(start_values):
        tag, text = _format(start_values[key], kinds.get(key))
        param = ET.SubElement(params, q("ssv", "Parameter"), {"name": key})
        ET.SubElement(param, q("ssv", tag), {"value": text})


def export_ssp(graph, path: str | Path) -> Path:
    """Write the compiled graph as an SSP 1.0 archive (deterministic bytes). Returns the path.
    A path that cannot be written is bad input (ScenarioError), checked before the work."""
    path = Path(path)
    example = f"{graph.scenario.name}.ssp"
    check_output_file(path, OPTION, example)
    sources: dict[str, str] = {}
    files: dict[str, Path | bytes] = {}  # archive name -> FMU file, or a baked variant's bytes
    by_file: dict[Path, str] = {}
    baked = ssp_bake.variants(graph)     # String parameters as defaults (ssp_bake.py)
    for inst in graph.instances:
        if inst.name in baked:
            files[f"resources/{baked[inst.name].name}"] = baked[inst.name].data
            sources[inst.name] = f"resources/{baked[inst.name].name}"
            continue
        fmu = Path(inst.fmu_path).resolve()
        if fmu not in by_file:
            base = re.sub(r"[^\w.-]", "_", inst.model_name) or "model"
            name, n = f"resources/{base}.fmu", 1
            while name in files:
                n += 1
                name = f"resources/{base}_{n}.fmu"
            files[name] = fmu
            by_file[fmu] = name
        sources[inst.name] = by_file[fmu]
    strings_in_fmu = {i.name for i in graph.instances if ssp_bake.is_bakeable(i)}
    ssd = ssp_vendor.with_vendor_annotations(build_ssd(graph, sources, strings_in_fmu),
                                             graph.scenario.experiment.step_size)
    members = {SSD_NAME: ssd}
    members.update((name, data if isinstance(data, bytes) else data.read_bytes())
                   for name, data in files.items())
    # FMUs are zips already: little to gain from a higher level
    return output_file(path, lambda p: write_zip(p, members, compresslevel=1), OPTION,
                       example)
