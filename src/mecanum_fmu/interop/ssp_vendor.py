"""Vendor annotations other tools need in an exported SSD.

OMSimulator (OpenModelica's FMI/SSP engine) takes a system's type only from its own annotation
on the ssd:System: without one its program stops with `[NewSystem] internal error` and
`Unable to add System`. We add the annotation OMSimulator itself writes for a weakly coupled
(fixed-step co-simulation) system - see OMSimulator's SSP documentation and the snapshots in
its test suite:

    <ssd:Annotations>
      <ssc:Annotation type="org.openmodelica">
        <oms:Annotations>
          <oms:SimulationInformation>
            <oms:FixedStepMaster description="oms-ma" stepSize="0.05" .../>

ssd:Annotations is the last child of ssd:System in the SSP 1.0 schema, and an ssc:Annotation may
hold any content, so the SSD stays valid SSP 1.0; other tools skip annotations of types they do
not know.
"""
from __future__ import annotations

from xml.etree import ElementTree as ET

OMS_NS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
OMS_TYPE = "org.openmodelica"
_SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
_SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
# OMSimulator's own defaults for a fixed-step master (it writes them on every export)
_TOLERANCE = "0.0001"

ET.register_namespace("oms", OMS_NS)


def add_openmodelica_annotation(system: ET.Element, step_size: float) -> ET.Element:
    """Append OMSimulator's fixed-step-master annotation to an ssd:System element (kept last,
    as the schema wants) and return the oms:FixedStepMaster element."""
    annotations = system.find(f"{{{_SSD}}}Annotations")
    if annotations is None:
        annotations = ET.SubElement(system, f"{{{_SSD}}}Annotations")
    else:                      # keep it the last child
        system.remove(annotations)
        system.append(annotations)
    annotation = ET.SubElement(annotations, f"{{{_SSC}}}Annotation", {"type": OMS_TYPE})
    oms = ET.SubElement(annotation, f"{{{OMS_NS}}}Annotations")
    info = ET.SubElement(oms, f"{{{OMS_NS}}}SimulationInformation")
    return ET.SubElement(info, f"{{{OMS_NS}}}FixedStepMaster", {
        "description": "oms-ma", "stepSize": repr(float(step_size)),
        "absoluteTolerance": _TOLERANCE, "relativeTolerance": _TOLERANCE})


def with_vendor_annotations(ssd: bytes, step_size: float) -> bytes:
    """The SSD text with the vendor annotations added (deterministic: same input, same bytes)."""
    root = ET.fromstring(ssd)
    system = root.find(f"{{{_SSD}}}System")
    add_openmodelica_annotation(system, step_size)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"
