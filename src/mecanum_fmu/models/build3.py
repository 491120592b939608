"""Build the bundled FMUs a second time as FMI 3.0 co-simulation FMUs (pythonfmu3), into
fmus/fmi3/, from the same slave code (library.fmi3_slave_source, slaves/fmi3.py).

As for FMI 2.0 (build.py), pythonfmu3's raw output is made standard-clean and reproducible:
units, output and initial dependencies (by value reference), a hash for the instantiation
token, no timestamp, deflated members; and self-contained (embed.py with the FMI 3.0 loader).
"""
from __future__ import annotations

import importlib.util
import tempfile
import zipfile
from pathlib import Path
from typing import Callable
from xml.etree import ElementTree as ET

from pythonfmu3 import FmuBuilder

from . import embed
from .build import UNIT_BASES, _package_version
from .catalog import MODELS
from .library import bundled_fmu_path, fmi3_dir, fmi3_slave_source, fmu_guid
from ..storage import write_zip

_UNIT_BASES = {**UNIT_BASES, "s": {"s": "1"}}       # and the independent variable's


def build_fmu3(model_name: str, dest_dir: Path) -> Path:
    """Build one bundled model as an FMI 3.0 FMU into dest_dir and return its path."""
    source = fmi3_slave_source(model_name)
    dest_dir = Path(dest_dir)
    dest_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="mecanum_fmu_build3_") as tmp:
        script = Path(tmp) / f"{source.module_name}.py"
        script.write_text(source.script)
        raw = FmuBuilder.build_FMU(script, dest=Path(tmp) / "raw", canGetAndSetFMUState=True,
                                   canSerializeFMUState=True,
                                   canHandleVariableCommunicationStepSize=True)
        slave_class = _model_class(script, source.module_name, model_name)
        with zipfile.ZipFile(raw) as zf:
            entries = {info.filename: zf.read(info) for info in zf.infolist()
                       if not info.filename.endswith("/")
                       and not info.filename.startswith("sources/")}   # pythonfmu3's C++, not
                                                                      # a source-code FMU
    rt, reuse = embed.runtime_or_none(), None
    if rt is not None:
        entries, reuse = embed.embed_entries(entries, model_name, rt, fmi3=True)
    entries["modelDescription.xml"] = _fix_model_description(
        entries["modelDescription.xml"], slave_class, source.guid, rt is None)
    return write_zip(bundled_fmu_path(model_name, dest_dir), entries, compresslevel=9,
                     reuse=reuse)


def build_all3(fmu_dir: Path, only_stale: bool = False,
               report: Callable[[Path, str], None] | None = None) -> list[Path]:
    """Every bundled model as an FMI 3.0 FMU into fmi3_dir(fmu_dir) (only the missing and
    stale ones with only_stale); report(path, "built" | "up to date") after each."""
    dest, paths = fmi3_dir(fmu_dir), []
    for name in MODELS:
        path = bundled_fmu_path(name, dest)
        state = "up to date"
        if not (only_stale and fmu_guid(path) == fmi3_slave_source(name).guid):
            build_fmu3(name, dest)
            state = "built"
        if report is not None:
            report(path, state)
        paths.append(path)
    return paths


def _model_class(script: Path, module_name: str, model_name: str):
    """The model class, from the script run as a module of its own (not put in sys.modules:
    a later in-process load of the FMU, by fmpy, runs the FMU's own copy)."""
    spec = importlib.util.spec_from_file_location(module_name, script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return getattr(module, model_name)


def _fix_model_description(xml: bytes, slave_class, token: str, needs_python: bool) -> bytes:
    root = ET.fromstring(xml)
    root.set("instantiationToken", token)
    root.attrib.pop("generationDateAndTime", None)
    root.set("version", _package_version())
    root.find("CoSimulation").set("needsExecutionTool", str(needs_python).lower())
    variables = root.find("ModelVariables")
    vr = {sv.get("name"): sv.get("valueReference") for sv in variables}
    arrays = getattr(slave_class, "ARRAYS", {})
    units = dict(getattr(slave_class, "UNITS", {}))
    units.update({name: units[elements[0]] for name, (elements, _) in arrays.items()}, time="s")
    _set_units(root, variables, units)
    deps = _with_arrays(getattr(slave_class, "DEPENDENCIES", {}), arrays)
    init_deps = _with_arrays(getattr(slave_class, "INITIAL_DEPENDENCIES", deps), arrays)

    def dependency_list(names) -> str:
        return " ".join(sorted((vr[n] for n in names), key=int))

    structure = root.find("ModelStructure")
    structure.clear()
    outputs = [sv.get("name") for sv in variables if sv.get("causality") == "output"]
    # FMI 3.0: the calculated parameters are initial unknowns too (DCMotor's R_a, k_t, ...)
    initial = [sv.get("name") for sv in variables
               if sv.get("causality") in ("output", "calculatedParameter")]
    for tag, names, table in (("Output", outputs, deps), ("InitialUnknown", initial, init_deps)):
        for name in names:
            ET.SubElement(structure, tag, valueReference=vr[name],
                          dependencies=dependency_list(table[name]))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _set_units(root, variables, units: dict) -> None:
    floats = [sv for sv in variables if sv.tag == "Float64" and sv.get("name") in units]
    for sv in floats:
        sv.set("unit", units[sv.get("name")])
    used = sorted({units[sv.get("name")] for sv in floats})
    if used:
        unit_defs = ET.Element("UnitDefinitions")
        for unit in used:
            ET.SubElement(ET.SubElement(unit_defs, "Unit", name=unit), "BaseUnit",
                          _UNIT_BASES[unit])
        root.insert(list(root).index(root.find("CoSimulation")) + 1, unit_defs)


def _with_arrays(dependencies: dict, arrays: dict) -> dict:
    """An array output depends on what any of its elements depends on."""
    out = dict(dependencies)
    for name, (elements, _) in arrays.items():
        out[name] = tuple(dict.fromkeys(d for e in elements for d in dependencies[e]))
    return out
