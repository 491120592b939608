"""Bake a scenario's String parameters into variant FMUs, for hosts that ignore String bindings.

OMSimulator drops String parameters (`Failed to import connector "vx_expr" with type "String"`,
`Unknown ParameterBinding-type`) and never sets their start values, so every scenario would run
with the bundled defaults there. `export-ssp` therefore writes, for every bundled component
whose String parameters differ from its FMU's defaults, a variant FMU whose defaults ARE the
scenario's values:

  * modelDescription.xml: the String start values are the scenario's, and a new GUID;
  * the slave script in resources/ ends with a few lines that, after the slave's own
    __init__, set those values through the variables' setters - what fmi2SetString would do -
    so the slave starts with them even when nobody calls fmi2SetString;
  * that script has a module name of its own (`<module>_<12 hex digits>`, in
    resources/slavemodule.txt): one process imports one module per name, so a host that
    loads the variant and the original would otherwise run one script for both.

FMI 3.0 FMUs (pythonfmu3) are baked the same way, in their own model description's terms.
Everything else (binaries, the bundled Python, pythonfmu's runtime) is copied byte for byte. One FMU per distinct set
of values, named `<Model>_<first 12 hex digits of its sha256>.fmu`: deterministic, so two
exports of one scenario are identical and two components with the same values share a file.
The String bindings stay in the SSD (hosts that apply them set the same values).
"""
from __future__ import annotations

import hashlib
import json
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

from ..models.catalog import bundled_model
from ..storage import zip_bytes

_MARK = "# --- start values baked in by `mecanum_fmu export-ssp` (mecanum_fmu/ssp_bake.py) ---"
_PATCH = '''

{mark}
def _mecanum_fmu_bake(values):
    {base}
    for cls in [c for c in list(globals().values()) if isinstance(c, type)
                and issubclass(c, Fmi2Slave) and c.__module__ == __name__]:
        def __init__(self, _init=cls.__init__, **kwargs):
            _init(self, **kwargs)
            for var in self.vars.values():
                if var.name in values:
                    var.setter(values[var.name])
        cls.__init__ = __init__


_mecanum_fmu_bake({values})
del _mecanum_fmu_bake
'''


@dataclass(frozen=True)
class Variant:
    name: str          # file name, e.g. VelocitySource_0123456789ab.fmu
    data: bytes        # the FMU archive


def string_changes(inst) -> dict[str, str]:
    """The String parameters of a graph instance whose value differs from its FMU's default."""
    changes = {}
    for var in inst.model.modelVariables:
        if var.type == "String" and var.causality == "parameter" and var.name in inst.start_values:
            value = str(inst.start_values[var.name])
            if value != (var.start or ""):
                changes[var.name] = value
    return changes


def is_bakeable(inst) -> bool:
    """A bundled pythonfmu model: we know its slave script and how it stores parameters."""
    md = inst.model
    return bundled_model(md) is not None and (md.generationTool or "").startswith("PythonFMU")


def variants(graph) -> dict[str, Variant]:
    """instance name -> the variant FMU it needs (instances at their defaults are left out)."""
    out: dict[str, Variant] = {}
    made: dict[tuple, Variant] = {}
    for inst in graph.instances:
        changes = string_changes(inst) if is_bakeable(inst) else {}
        if not changes:
            continue
        fmu = Path(inst.fmu_path).resolve()
        key = (str(fmu), json.dumps(changes, sort_keys=True))
        if key not in made:
            data = bake(fmu.read_bytes(), changes, reuse=fmu)
            digest = hashlib.sha256(data).hexdigest()[:12]
            made[key] = Variant(f"{inst.model.modelName}_{digest}.fmu", data)
        out[inst.name] = made[key]
    return out


def bake(fmu: bytes, values: dict[str, str], reuse: Path | None = None) -> bytes:
    """The FMU archive `fmu` with `values` (String parameter -> value) as its defaults; reuse:
    the archive's file, whose unchanged members (the bundled Python) are copied deflated."""
    import io
    with zipfile.ZipFile(io.BytesIO(fmu)) as zf:
        entries = {i.filename: zf.read(i) for i in zf.infolist() if not i.filename.endswith("/")}
    values = dict(sorted(values.items()))
    tag = hashlib.sha256(fmu + json.dumps(values).encode()).hexdigest()
    entries["modelDescription.xml"] = _description(entries["modelDescription.xml"], values, tag)
    module = entries["resources/slavemodule.txt"].decode().strip()
    # a module name of its own: pythonfmu imports the slave by name, and a process holds one
    # module per name, so a variant and its original (or two variants) loaded by one host
    # would otherwise all run whichever script was imported first
    own = f"{module}_{tag[:12]}"
    entries["resources/slavemodule.txt"] = entries["resources/slavemodule.txt"].replace(
        module.encode(), own.encode())
    fmi3 = "resources/pythonfmu3/__init__.py" in entries      # an FMI 3.0 FMU (pythonfmu3)
    base = ("from pythonfmu3 import Fmi3Slave as Fmi2Slave" if fmi3 else
            "from pythonfmu import Fmi2Slave")
    entries[f"resources/{own}.py"] = entries.pop(f"resources/{module}.py") + _PATCH.format(
        mark=_MARK, values=repr(values), base=base).encode()
    return zip_bytes(entries, compresslevel=9, reuse=reuse)


def _description(xml: bytes, values: dict[str, str], tag: str) -> bytes:
    root = ET.fromstring(xml)
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "mecanum_fmu-baked:" + tag)) + "}"
    if root.get("fmiVersion", "").startswith("3."):     # <String name=..><Start value=../>
        root.set("instantiationToken", guid)
        for sv in root.find("ModelVariables").iter("String"):
            if sv.get("name") in values:
                start = sv.find("Start")
                start = ET.SubElement(sv, "Start") if start is None else start
                start.set("value", values[sv.get("name")])
    else:
        root.set("guid", guid)
    for sv in root.iter("ScalarVariable"):
        string = sv.find("String")
        if string is not None and sv.get("name") in values:
            string.set("start", values[sv.get("name")])
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"
