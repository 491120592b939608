"""Build the four bundled FMUs: pythonfmu's build, then a pass that makes them standard-clean.

pythonfmu's raw output has no InitialUnknowns, no output dependencies, no units, a random GUID,
a timestamp and stored (uncompressed) entries. ``build_fmu`` fixes all of these so that the
FMUs pass ``fmpy validate``, other tools see the true direct-feedthrough structure, and two
builds from the same sources are byte-identical (the GUID is a hash of the sources).
"""
from __future__ import annotations

import hashlib
import importlib
import io
import re
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import pythonfmu
from pythonfmu import FmuBuilder

from . import fmu_link

PACKAGE_DIR = Path(__file__).resolve().parent
REPO_FMU_DIR = PACKAGE_DIR.parent.parent / "fmus"

# modelName -> slave module in mecanum_fmu.slaves. The FMU script gets a unique module name
# (mecanum_fmu_<module>) so that all four load into one process without clashing.
BUNDLED = {
    "VelocitySource": "velocity_source",
    "Center2Wheel": "center2wheel",
    "Wheel2Center": "wheel2center",
    "PoseIntegrator": "pose_integrator",
}

UNIT_BASES = {"m": {"m": "1"}, "m/s": {"m": "1", "s": "-1"},
              "rad": {"rad": "1"}, "rad/s": {"rad": "1", "s": "-1"}}

_INLINE = re.compile(r"^from mecanum_fmu\.blocks\.(\w+) import [\w, ]+# inline$", re.MULTILINE)
_FIXED_DATE = (1980, 1, 1, 0, 0, 0)


@dataclass(frozen=True)
class SlaveSource:
    model_name: str
    module_name: str      # top-level module name inside the FMU
    script: str           # self-contained script text

    @property
    def digest(self) -> str:
        """Hash of everything that goes into the FMU: our script, pythonfmu's version and the
        libpython the binaries are linked to (fmu_link)."""
        link = fmu_link.build_link()
        text = self.script + "\npythonfmu " + pythonfmu.__version__
        if link is not None:
            text += "\nlinked to " + link.tag
        return hashlib.sha256(text.encode()).hexdigest()

    @property
    def guid(self) -> str:
        return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "mecanum_fmu:" + self.digest)) + "}"


def slave_source(model_name: str) -> SlaveSource:
    """The self-contained FMU script for a bundled model, with the block maths inlined."""
    module = BUNDLED[model_name]
    text = (PACKAGE_DIR / "slaves" / f"{module}.py").read_text()

    def inline(match: re.Match) -> str:
        block = (PACKAGE_DIR / "blocks" / f"{match.group(1)}.py").read_text()
        return f"# --- inlined from mecanum_fmu/blocks/{match.group(1)}.py ---\n{block}# --- end ---"

    script = fmu_link.with_prelude(_INLINE.sub(inline, text), fmu_link.build_link())
    return SlaveSource(model_name, f"mecanum_fmu_{module}", script)


def bundled_fmu_path(model_name: str, fmu_dir: Path = REPO_FMU_DIR) -> Path:
    return Path(fmu_dir) / f"{model_name}.fmu"


def is_current(model_name: str, fmu_path: Path) -> bool:
    """True when fmu_path exists and was built from the current sources (GUID match)."""
    try:
        with zipfile.ZipFile(fmu_path) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return False
    return root.get("guid") == slave_source(model_name).guid


def build_fmu(model_name: str, dest_dir: Path = REPO_FMU_DIR) -> Path:
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
    entries = fmu_link.link_entries(entries, fmu_link.build_link())
    entries["modelDescription.xml"] = _fix_model_description(
        entries["modelDescription.xml"], slave_class, source.guid)
    partial = target.with_suffix(".fmu.part")
    partial.write_bytes(zip_entries(entries))
    partial.replace(target)   # atomic: a reader never sees a half-written FMU
    return target


def zip_entries(entries: dict[str, bytes]) -> bytes:
    """An FMU archive of entries (name -> bytes): sorted, fixed dates, deterministic bytes."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=_FIXED_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, entries[name], compresslevel=9)
    return buffer.getvalue()


def build_all(dest_dir: Path = REPO_FMU_DIR, only_stale: bool = False) -> list[Path]:
    paths = []
    for name in BUNDLED:
        path = bundled_fmu_path(name, dest_dir)
        if not (only_stale and is_current(name, path)):
            build_fmu(name, dest_dir)
        paths.append(path)
    return paths


def _slave_class(module_name: str):
    module = importlib.import_module(module_name)
    return next(obj for obj in vars(module).values()
                if isinstance(obj, type) and issubclass(obj, pythonfmu.Fmi2Slave)
                and obj is not pythonfmu.Fmi2Slave)


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
        for name in outputs:
            ET.SubElement(node, "Unknown", index=index[name],
                          dependencies=dependency_list(init_deps[name]))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _package_version() -> str:
    from mecanum_fmu import __version__
    return __version__
