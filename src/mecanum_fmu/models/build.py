"""Build the bundled FMUs: pythonfmu's build, then a pass that makes them standard-clean.

pythonfmu's raw output has no InitialUnknowns, no output dependencies, no units, a random GUID,
a timestamp and stored (uncompressed) entries. ``build_fmu`` fixes all of these so that the
FMUs pass ``fmpy validate``, other tools see the true direct-feedthrough structure, and two
builds from the same sources are byte-identical (the GUID is a hash of the sources).
"""
from __future__ import annotations

import importlib
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Callable
from xml.etree import ElementTree as ET

import pythonfmu
from pythonfmu import FmuBuilder

from .catalog import MODELS
from .library import bundled_fmu_path, is_current, slave_source
from ..output import make_folder
from ..storage import write_zip
from . import embed

UNIT_BASES = {"m": {"m": "1"}, "m/s": {"m": "1", "s": "-1"},
              "rad": {"rad": "1"}, "rad/s": {"rad": "1", "s": "-1"},
              "1/s": {"s": "-1"}, "s": {"s": "1"},
              # the drive train (docs/robot.md)
              "1": {}, "kg": {"kg": "1"}, "kg.m2": {"kg": "1", "m": "2"},
              "m/s2": {"m": "1", "s": "-2"}, "A": {"A": "1"},
              "V": {"kg": "1", "m": "2", "s": "-3", "A": "-1"},
              "N.m": {"kg": "1", "m": "2", "s": "-2"}, "J": {"kg": "1", "m": "2", "s": "-2"},
              "H": {"kg": "1", "m": "2", "s": "-2", "A": "-2"},
              "ohm": {"kg": "1", "m": "2", "s": "-3", "A": "-2"},
              "V.s/rad": {"kg": "1", "m": "2", "s": "-2", "A": "-1", "rad": "-1"},
              "V/rad": {"kg": "1", "m": "2", "s": "-3", "A": "-1", "rad": "-1"},
              "N.m/A": {"kg": "1", "m": "2", "s": "-2", "A": "-1"},
              "N.m.s/rad": {"kg": "1", "m": "2", "s": "-1", "rad": "-1"}}


def build_fmu(model_name: str, dest_dir: Path) -> Path:
    """Build one bundled FMU into dest_dir and return its path."""
    source = slave_source(model_name)
    dest_dir = Path(dest_dir)
    dest_dir.mkdir(parents=True, exist_ok=True)
    target = bundled_fmu_path(model_name, dest_dir)
    with tempfile.TemporaryDirectory(prefix="mecanum_fmu_build_") as tmp:
        script = Path(tmp) / f"{source.module_name}.py"
        script.write_text(source.script)
        raw = FmuBuilder.build_FMU(script, dest=Path(tmp) / "raw.fmu",
                                   canGetAndSetFMUstate=True, canSerializeFMUstate=True)
        slave_class = _slave_class(source.module_name)
        _forget_module(source.module_name, tmp)
        with zipfile.ZipFile(raw) as zf:
            entries = {info.filename: zf.read(info) for info in zf.infolist()
                       if not info.filename.endswith("/")}
    rt, reuse = embed.runtime_or_none(), None
    if rt is not None:
        entries, reuse = embed.embed_entries(entries, model_name, rt)
    entries["modelDescription.xml"] = _fix_model_description(
        entries["modelDescription.xml"], slave_class, source.guid)
    return write_zip(target, entries, compresslevel=9, reuse=reuse)




def build_all(dest_dir: Path, only_stale: bool = False,
              report: Callable[[Path, str], None] | None = None) -> list[Path]:
    """Build every bundled FMU (only the missing and stale ones with only_stale) into
    dest_dir; report(path, "built" | "up to date") after each. The one build loop."""
    make_folder(Path(dest_dir), "fmus --dest")      # a file there, read-only: bad input
    paths = []
    for name in MODELS:
        path = bundled_fmu_path(name, dest_dir)
        state = "up to date"
        if not (only_stale and is_current(name, path)):
            build_fmu(name, dest_dir)
            state = "built"
        if report is not None:
            report(path, state)
        paths.append(path)
    return paths


def _slave_class(module_name: str):
    """The model's slave class: of the Fmi2Slave subclasses in the script, the most derived
    (an inlined base such as FeedthroughSlave is not the model), as pythonfmu picks it."""
    module = importlib.import_module(module_name)
    return max((obj for obj in vars(module).values()
                if isinstance(obj, type) and issubclass(obj, pythonfmu.Fmi2Slave)
                and obj is not pythonfmu.Fmi2Slave), key=lambda cls: len(cls.__mro__))


def _forget_module(module_name: str, folder: str) -> None:
    # pythonfmu imports the script into this process; drop it so a later in-process load of
    # the FMU (by fmpy) runs the FMU's own copy, and leave sys.path as it was.
    sys.modules.pop(module_name, None)
    while folder in sys.path:
        sys.path.remove(folder)


def _fix_model_description(xml: bytes, slave_class, guid: str) -> bytes:
    root = ET.fromstring(xml)
    root.set("guid", guid)
    root.attrib.pop("generationDateAndTime", None)
    root.set("version", _package_version())

    variables = root.find("ModelVariables")
    index = {sv.get("name"): str(i) for i, sv in enumerate(variables, start=1)}
    units = getattr(slave_class, "UNITS", {})
    for sv in variables:
        real = sv.find("Real")
        if real is not None and sv.get("name") in units:
            real.set("unit", units[sv.get("name")])
    used_units = sorted({units[sv.get("name")] for sv in variables
                         if sv.find("Real") is not None and sv.get("name") in units})
    if used_units:
        unit_defs = ET.Element("UnitDefinitions")
        for unit in used_units:
            ET.SubElement(ET.SubElement(unit_defs, "Unit", name=unit), "BaseUnit",
                          UNIT_BASES[unit])
        position = list(root).index(root.find("CoSimulation")) + 1
        root.insert(position, unit_defs)

    def dependency_list(names) -> str:
        return " ".join(sorted((index[n] for n in names), key=int))

    structure = root.find("ModelStructure")
    structure.clear()
    outputs = [sv.get("name") for sv in variables if sv.get("causality") == "output"]
    deps = getattr(slave_class, "DEPENDENCIES", {})
    init_deps = getattr(slave_class, "INITIAL_DEPENDENCIES", deps)
    if outputs:
        node = ET.SubElement(structure, "Outputs")
        for name in outputs:
            ET.SubElement(node, "Unknown", index=index[name],
                          dependencies=dependency_list(deps[name]))
        node = ET.SubElement(structure, "InitialUnknowns")
        # outputs and calculated parameters (a DCMotor's R_a, k_t, ...), in index order
        for name in [sv.get("name") for sv in variables
                     if sv.get("causality") in ("output", "calculatedParameter")]:
            ET.SubElement(node, "Unknown", index=index[name],
                          dependencies=dependency_list(init_deps[name]))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _package_version() -> str:
    from mecanum_fmu import __version__
    return __version__
