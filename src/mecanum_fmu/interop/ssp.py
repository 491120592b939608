"""The SSP 1.0 (System Structure and Parameterization) vocabulary shared by ssp_write (export)
and ssp_read (import): namespaces, member names, and our own annotation.

The master's step size and algorithm travel in a DefaultExperiment annotation of type
org.mecanum-fmu.experiment; other tools ignore it.
"""
from __future__ import annotations

from xml.etree import ElementTree as ET

SSD_NAME = "SystemStructure.ssd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "mf": "https://github.com/mecanum-fmu/ssp-annotation/1.0",
}
ANNOTATION_TYPE = "org.mecanum-fmu.experiment"
FMU_MIME = "application/x-fmu-sharedlibrary"
VALUE_TAGS = ("Real", "Integer", "Boolean", "String")
# Every component's inline parameter set carries this one name. SSP applies inline bindings
# always; Ecos applies only the set named at init (`ecos simulate --parameterSet
# initialValues`, `EcosSimulation.init(parameter_set="initialValues")`), so one shared name
# lets a single option apply every component's values there.
PARAMETER_SET = "initialValues"

for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)


def as_type(value, kind: str | None):
    """A start value as the type of the FMU variable it sets (kind: port_type of that
    variable), whatever literal it was written with: `x0: 5` for a Real is 5.0, an integral
    Real for an Integer is an int. Anything else (a wrong type) is returned as it is, for the
    graph's checks to report."""
    if kind == "Real" and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if kind == "Integer" and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def q(prefix: str, tag: str) -> str:
    """The qualified tag name {namespace}tag."""
    return f"{{{NS[prefix]}}}{tag}"


def local(tag) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else str(tag)


def namespace(tag) -> str:
    return tag[1:].split("}", 1)[0] if isinstance(tag, str) and tag.startswith("{") else ""
