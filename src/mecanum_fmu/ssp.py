"""SSP 1.0 (System Structure and Parameterization) export and import.

`export_ssp(graph, path)` writes a compiled scenario as an .ssp archive: SystemStructure.ssd
plus each distinct FMU once under resources/. `load_ssp(path)` reads an .ssp archive or a bare
.ssd back into the same frozen Scenario the YAML loader builds, so `run`/`validate` apply the
same graph checks to it. The master's step size and algorithm travel in a DefaultExperiment
annotation of type org.mecanum-fmu.experiment; other tools ignore it.

Archives are data: the XML is read with the standard library parser (no external entities are
fetched), FMUs are extracted only from resources/ into a cache folder keyed by the archive's
sha256, and every problem is reported as a ScenarioError with the SSD place.
"""
from __future__ import annotations

import hashlib
import math
import os
import posixpath
import re
import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Callable
from xml.etree import ElementTree as ET

from .errors import Problem, ScenarioError
from .scenario import (DEFAULT_EXPERIMENT, MASTERS, Component, Connection, Experiment,
                       Scenario, Scalar, VarRef, check_experiment, show)

SSD_NAME = "SystemStructure.ssd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "mf": "https://github.com/mecanum-fmu/ssp-annotation/1.0",
}
ANNOTATION_TYPE = "org.mecanum-fmu.experiment"
FMU_MIME = "application/x-fmu-sharedlibrary"
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)
_MAX_SSD_BYTES = 10_000_000
_VALUE_TAGS = ("Real", "Integer", "Boolean", "String")
# Every component's inline parameter set carries this one name. SSP applies inline bindings
# always; Ecos applies only the set named at init (`ecos simulate --parameterSet
# initialValues`, `EcosSimulation.init(parameter_set="initialValues")`), so one shared name
# lets a single option apply every component's values there.
PARAMETER_SET = "initialValues"

for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


# --------------------------------------------------------------------------------------------
# export


def _format(value: Scalar) -> tuple[str, str]:
    """(SSV/SSC type tag, value text) for a start value; repr keeps floats bit-exact."""
    if isinstance(value, bool):
        return "Boolean", "true" if value else "false"
    if isinstance(value, int):
        return "Integer", str(value)
    if isinstance(value, float):
        return "Real", repr(value)
    return "String", str(value)


def build_ssd(graph, sources: dict[str, str]) -> bytes:
    """The SystemStructure.ssd text of a compiled graph; sources: instance -> FMU source URI."""
    scenario = graph.scenario
    exp = scenario.experiment
    root = ET.Element(_q("ssd", "SystemStructureDescription"),
                      {"version": "1.0", "name": scenario.name})
    if scenario.description:
        root.set("description", scenario.description)
    system = ET.SubElement(root, _q("ssd", "System"), {"name": scenario.name})
    elements = ET.SubElement(system, _q("ssd", "Elements"))
    for comp in scenario.components:          # declared order: it fixes ties in step order
        inst = graph.instance(comp.name)
        node = ET.SubElement(elements, _q("ssd", "Component"), {
            "name": inst.name, "type": FMU_MIME, "source": sources[inst.name]})
        connectors = ET.SubElement(node, _q("ssd", "Connectors"))
        for var in inst.model.modelVariables:
            if var.causality not in ("input", "output", "parameter"):
                continue
            conn = ET.SubElement(connectors, _q("ssd", "Connector"),
                                 {"name": var.name, "kind": var.causality})
            kind = "Integer" if var.type == "Enumeration" else var.type
            if kind in _VALUE_TAGS:
                ET.SubElement(conn, _q("ssc", kind))   # units left out: no ssd:Units table
        if inst.start_values:
            bindings = ET.SubElement(node, _q("ssd", "ParameterBindings"))
            binding = ET.SubElement(bindings, _q("ssd", "ParameterBinding"))
            values = ET.SubElement(binding, _q("ssd", "ParameterValues"))
            pset = ET.SubElement(values, _q("ssv", "ParameterSet"),
                                 {"version": "1.0", "name": PARAMETER_SET})
            params = ET.SubElement(pset, _q("ssv", "Parameters"))
            for key in sorted(inst.start_values):
                tag, text = _format(inst.start_values[key])
                param = ET.SubElement(params, _q("ssv", "Parameter"), {"name": key})
                ET.SubElement(param, _q("ssv", tag), {"value": text})
    connections = ET.SubElement(system, _q("ssd", "Connections"))
    for conn in scenario.connections:         # declared order, like the YAML
        ET.SubElement(connections, _q("ssd", "Connection"), {
            "startElement": conn.source.instance, "startConnector": conn.source.variable,
            "endElement": conn.target.instance, "endConnector": conn.target.variable})
    if not len(connections):
        system.remove(connections)
    default = ET.SubElement(root, _q("ssd", "DefaultExperiment"),
                            {"startTime": repr(exp.start_time), "stopTime": repr(exp.stop_time)})
    annotations = ET.SubElement(default, _q("ssd", "Annotations"))
    annotation = ET.SubElement(annotations, _q("ssc", "Annotation"), {"type": ANNOTATION_TYPE})
    ours = ET.SubElement(annotation, _q("mf", "Experiment"),
                         {"stepSize": repr(exp.step_size), "master": exp.master})
    if scenario.outputs is not None:
        for ref, _place in scenario.outputs:
            ET.SubElement(ours, _q("mf", "Output"), {"name": str(ref)})
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def export_ssp(graph, path: str | Path) -> Path:
    """Write the compiled graph as an SSP 1.0 archive (deterministic bytes). Returns the path."""
    from . import ssp_bake, ssp_vendor
    path = Path(path)
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
    ssd = ssp_vendor.with_vendor_annotations(build_ssd(graph, sources),
                                             graph.scenario.experiment.step_size)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    with zipfile.ZipFile(tmp, "w") as zf:
        _add(zf, SSD_NAME, ssd)
        for name in sorted(files):
            data = files[name]
            _add(zf, name, data if isinstance(data, bytes) else data.read_bytes())
    os.replace(tmp, path)
    return path


def _add(zf: zipfile.ZipFile, name: str, data: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    info.create_system = 3
    zf.writestr(info, data)


# --------------------------------------------------------------------------------------------
# import


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mecanum_fmu" / "ssp"


class _Source:
    """Files of an .ssp archive or of the folder around a bare .ssd."""

    def __init__(self, path: Path, label: str):
        self.path, self.label = path, label
        self.zip: zipfile.ZipFile | None = None
        self.digest: str | None = None

    def fail(self, place: str, message: str) -> ScenarioError:
        return ScenarioError([Problem(self.label, place, message)])

    def open(self) -> bytes:
        path = self.path
        try:
            if not path.exists():
                raise self.fail("file", "not found; check the path")
            if path.is_dir():
                raise self.fail("file", "is a folder; give an .ssp archive or an .ssd file")
            if path.suffix.lower() == ".ssd":
                if path.stat().st_size > _MAX_SSD_BYTES:
                    raise self.fail("file", "is too large for a system structure description")
                return path.read_bytes()
            data = path.read_bytes()
        except OSError as err:
            raise self.fail("file", f"cannot be read: {err.strerror}") from None
        self.digest = hashlib.sha256(data).hexdigest()
        try:
            self.zip = zipfile.ZipFile(path)
            names = self.zip.namelist()
        except zipfile.BadZipFile as err:
            raise self.fail("file", f"is not an SSP archive (an .ssp is a zip archive): {err}") from None
        if SSD_NAME not in names:
            raise self.fail("file", f"has no {SSD_NAME} at its top level (has: "
                                    f"{show(sorted(names)[:6])})")
        info = self.zip.getinfo(SSD_NAME)
        if info.file_size > _MAX_SSD_BYTES:
            raise self.fail(SSD_NAME, "is too large for a system structure description")
        return self.zip.read(SSD_NAME)

    def member(self, uri: str) -> str | None:
        """Archive-relative normalized name of a relative URI, or None when it leaves the root."""
        if re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", uri) or uri.startswith("/"):
            return None
        name = posixpath.normpath(uri.replace("\\", "/"))
        if name.startswith("..") or name == ".":
            return None
        return name

    def read(self, name: str) -> bytes | None:
        if self.zip is not None:
            try:
                return self.zip.read(name)
            except KeyError:
                return None
        file = self.path.parent / name
        return file.read_bytes() if file.is_file() else None

    def fmu_path(self, name: str) -> Path | None:
        """A usable path of the FMU at name: the file itself next to a bare .ssd, or a copy
        extracted once into the cache folder of this archive."""
        if self.zip is None:
            file = (self.path.parent / name).resolve()
            return file if file.is_file() else None
        try:
            info = self.zip.getinfo(name)
        except KeyError:
            return None
        folder = cache_root() / self.digest
        target = folder / name
        if target.is_file() and target.stat().st_size == info.file_size:
            return target
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=".part-")
        try:
            with os.fdopen(fd, "wb") as out, self.zip.open(info) as src:
                shutil.copyfileobj(src, out)
            os.replace(tmp, target)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return target


def load_ssp(path: str | Path) -> Scenario:
    """Read an .ssp archive or a bare .ssd into a Scenario. Raises ScenarioError listing every
    problem found, each placed in the SSD (e.g. `SystemStructure.ssd: Connection[3]`)."""
    path = Path(path)
    label = str(path)
    source = _Source(path, label)
    text = source.open()
    ssd = SSD_NAME if source.zip is not None else ""    # a bare .ssd is the file itself
    problems: list[Problem] = []

    def at(place: str) -> str:
        return f"{ssd}: {place}" if ssd and place else (place or ssd)

    def bad(place: str, message: str) -> None:
        problems.append(Problem(label, at(place), message))

    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        line, col = err.position
        raise source.fail(at(f"line {line}, column {col + 1}"),
                          f"XML syntax error: {err}") from None
    if root.tag != _q("ssd", "SystemStructureDescription"):
        raise source.fail(at("SystemStructureDescription"), f"root element is {_local(root.tag)!r} in "
                               f"{_ns(root.tag) or 'no namespace'}; expected "
                               f"ssd:SystemStructureDescription ({NS['ssd']})")
    name = root.get("name") or path.stem
    if not re.fullmatch(r"[\w.-]+", name):
        name = re.sub(r"[^\w.-]+", "_", name).strip("_") or path.stem
    description = root.get("description", "")

    systems = root.findall(_q("ssd", "System"))
    if len(systems) != 1:
        raise source.fail(at("SystemStructureDescription"), f"expected one ssd:System, found {len(systems)}")
    system = systems[0]
    sys_place = f"System[@name='{system.get('name', '')}']"

    # Components, their connectors and their own parameter bindings.
    components: list[Component] = []
    connectors: dict[str, set[str] | None] = {}
    params_of: dict[str, dict[str, Scalar]] = {}
    elements = system.find(_q("ssd", "Elements"))
    for i, elem in enumerate(list(elements) if elements is not None else []):
        if not isinstance(elem.tag, str):
            continue
        cname = elem.get("name")
        place = f"Elements/{_local(elem.tag)}[{i + 1}]" + (f"[@name='{cname}']" if cname else "")
        if elem.tag == _q("ssd", "SignalDictionaryReference"):
            bad(place, "signal dictionaries are not supported; connect the components directly")
            continue
        if elem.tag == _q("ssd", "System"):
            bad(place, "nested systems are not supported; flatten the system")
            continue
        if elem.tag != _q("ssd", "Component"):
            continue
        if not cname or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", cname):
            bad(place, f"component name {show(cname)} must be an identifier (letters, digits, _)")
            continue
        if cname in connectors:
            bad(place, f"a second component named '{cname}'; names must be unique")
            continue
        kind = elem.get("type", FMU_MIME)
        if kind != FMU_MIME:
            bad(place, f"type {kind!r} is not supported; only FMUs ({FMU_MIME})")
            continue
        uri = elem.get("source")
        fmu: Path | None = None
        member = source.member(uri) if uri else None
        if not uri:
            bad(place, "has no source (the FMU, e.g. resources/Model.fmu)")
        elif member is None:
            bad(f"{place}/@source", f"{uri!r} must be a relative path inside the "
                                    f"{'archive' if source.zip else 'folder'}")
        elif elem.get("implementation", "any") == "ModelExchange":
            bad(place, "implementation='ModelExchange' is not supported; this master runs "
                       "co-simulation FMUs")
        else:
            fmu = source.fmu_path(member)
            if fmu is None:
                bad(f"{place}/@source", f"{uri!r} not found in the "
                                        f"{'archive' if source.zip else 'folder'}")
        conns = elem.find(_q("ssd", "Connectors"))
        connectors[cname] = (None if conns is None else
                             {c.get("name") for c in conns.findall(_q("ssd", "Connector"))})
        params_of[cname] = _bindings(elem, f"{place}/ParameterBindings", source, bad)
        components.append(Component(cname, str(fmu) if fmu else "", {}, place))

    # System-level bindings: names are element.parameter; they win over the element's own.
    for key, value in _bindings(system, f"{sys_place}/ParameterBindings", source, bad).items():
        inst, _, var = key.partition(".")
        if inst in params_of and var:
            params_of[inst][var] = value
        else:
            bad(f"{sys_place}/ParameterBindings", f"parameter {key!r} does not name "
                f"component.parameter of a component of this system")
    components = [Component(c.name, c.fmu, params_of[c.name], c.place) for c in components
                  if c.fmu]
    if not connectors and not problems:
        bad(f"{sys_place}/Elements", "no ssd:Component: a system needs at least one FMU")

    # Connections.
    connections: list[Connection] = []
    conns = system.find(_q("ssd", "Connections"))
    for i, conn in enumerate(conns.findall(_q("ssd", "Connection")) if conns is not None else []):
        place = f"Connections/Connection[{i + 1}]"
        ends = []
        for side in ("start", "end"):
            element, connector = conn.get(f"{side}Element"), conn.get(f"{side}Connector")
            if not element:
                bad(place, f"no {side}Element: connections to the system's own connectors "
                           "are not supported (the system has no ports)")
            elif element not in connectors:
                bad(place, f"{side}Element '{element}' is not a component of this system")
            elif not connector:
                bad(place, f"no {side}Connector")
            elif connectors[element] is not None and connector not in connectors[element]:
                bad(place, f"component '{element}' has no connector '{connector}' "
                           f"({side}Connector)")
            else:
                ends.append(VarRef(element, connector))
        if len(ends) == 2:
            connections.append(Connection(ends[0], ends[1], at(place)))

    experiment, outputs = _experiment(root, bad, at)
    if problems:
        raise ScenarioError(problems)
    # graph messages name the SSD place: components and connections carry it already
    components = [Component(c.name, c.fmu, c.parameters, at(c.place))
                  for c in components]
    return Scenario(path, name, description, experiment, tuple(components),
                    tuple(connections), outputs, {})


def _local(tag) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else str(tag)


def _ns(tag) -> str:
    return tag[1:].split("}", 1)[0] if isinstance(tag, str) and tag.startswith("{") else ""


def _bindings(owner, place: str, source: _Source, bad: Callable) -> dict[str, Scalar]:
    out: dict[str, Scalar] = {}
    node = owner.find(_q("ssd", "ParameterBindings"))
    if node is None:
        return out
    for i, binding in enumerate(node.findall(_q("ssd", "ParameterBinding"))):
        bplace = f"{place}/ParameterBinding[{i + 1}]"
        if binding.find(_q("ssd", "ParameterMapping")) is not None:
            bad(bplace, "ParameterMapping is not supported; give the parameters their FMU names")
            continue
        kind = binding.get("type", "application/x-ssp-parameter-set")
        if kind != "application/x-ssp-parameter-set":
            bad(bplace, f"type {kind!r} is not supported (only application/x-ssp-parameter-set)")
            continue
        prefix = binding.get("prefix", "")
        uri = binding.get("source")
        inline = binding.find(_q("ssd", "ParameterValues"))
        if uri:
            if binding.get("sourceBase", "SSD") != "SSD":
                bad(bplace, "sourceBase='component' is not supported; use a path from the SSD")
                continue
            member = source.member(uri)
            data = source.read(member) if member else None
            if data is None:
                bad(f"{bplace}/@source", f"{uri!r} not found "
                    f"{'in the archive' if source.zip else 'next to the SSD'}")
                continue
            try:
                pset = ET.fromstring(data)
            except ET.ParseError as err:
                bad(f"{bplace}/@source", f"{uri}: XML syntax error: {err}")
                continue
            pplace = f"{bplace} ({uri})"
        elif inline is not None:
            sets = [c for c in inline if isinstance(c.tag, str)]
            if len(sets) != 1 or sets[0].tag != _q("ssv", "ParameterSet"):
                bad(f"{bplace}/ParameterValues", "expected one ssv:ParameterSet")
                continue
            pset, pplace = sets[0], f"{bplace}/ParameterValues"
        else:
            continue
        if pset.tag != _q("ssv", "ParameterSet"):
            bad(pplace, f"expected an ssv:ParameterSet ({NS['ssv']}), got {_local(pset.tag)!r}")
            continue
        params = pset.find(_q("ssv", "Parameters"))
        for j, param in enumerate(params.findall(_q("ssv", "Parameter"))
                                  if params is not None else []):
            name = param.get("name")
            ppl = f"{pplace}/Parameter[{j + 1}]" + (f"[@name='{name}']" if name else "")
            if not name:
                bad(ppl, "has no name")
                continue
            if prefix:
                if not name.startswith(prefix):
                    continue
                name = name[len(prefix):]
            value = _value(param, ppl, bad)
            if value is not None:
                out[name] = value
    return out


def _value(param, place: str, bad: Callable) -> Scalar | None:
    for child in param:
        if not isinstance(child.tag, str) or _ns(child.tag) != NS["ssv"]:
            continue
        tag, text = _local(child.tag), child.get("value")
        if tag == "Annotations":
            continue
        if text is None:
            bad(place, f"ssv:{tag} has no value attribute")
            return None
        try:
            if tag == "Real":
                value = float(text.strip())
                if not math.isfinite(value):
                    raise ValueError
                return value
            if tag == "Integer":
                return int(text.strip())
            if tag == "Boolean":
                if text.strip() in ("true", "1"):
                    return True
                if text.strip() in ("false", "0"):
                    return False
                raise ValueError
            if tag == "String":
                return text
        except ValueError:
            bad(place, f"ssv:{tag} value {show(text)} is not a valid {tag}")
            return None
        bad(place, f"ssv:{tag} parameters are not supported (use Real, Integer, Boolean, String)")
        return None
    bad(place, "has no ssv:Real/Integer/Boolean/String value")
    return None


def _experiment(root, bad: Callable, at: Callable):
    values = dict(DEFAULT_EXPERIMENT)
    outputs = None
    default = root.find(_q("ssd", "DefaultExperiment"))
    ok = True
    if default is not None:
        for attr, key in (("startTime", "start_time"), ("stopTime", "stop_time")):
            text = default.get(attr)
            if text is None:
                continue
            try:
                values[key] = float(text)
            except ValueError:
                bad(f"DefaultExperiment/@{attr}", f"{show(text)} is not a number of seconds")
                ok = False
        for ann in default.iterfind(f"{_q('ssd', 'Annotations')}/{_q('ssc', 'Annotation')}"):
            if ann.get("type") != ANNOTATION_TYPE:
                continue
            ours = ann.find(_q("mf", "Experiment"))
            if ours is None:
                continue
            aplace = f"DefaultExperiment/Annotations/Annotation[@type='{ANNOTATION_TYPE}']"
            if ours.get("stepSize") is not None:
                try:
                    values["step_size"] = float(ours.get("stepSize"))
                except ValueError:
                    bad(f"{aplace}/@stepSize", f"{show(ours.get('stepSize'))} is not a number")
                    ok = False
            master = ours.get("master")
            if master is not None:
                if master in MASTERS:
                    values["master"] = master
                else:
                    bad(f"{aplace}/@master", f"unknown master {show(master)} "
                                             f"(choose one of {', '.join(MASTERS)})")
            outs = ours.findall(_q("mf", "Output"))
            if outs:
                outputs = []
                for k, out in enumerate(outs):
                    inst, _, var = (out.get("name") or "").partition(".")
                    if inst and var:
                        outputs.append((VarRef(inst, var), at(f"{aplace}/Output[{k + 1}]")))
                    else:
                        bad(f"{aplace}/Output[{k + 1}]", "name must be instance.variable")
                outputs = tuple(outputs)
    experiment = Experiment(**values)
    if ok:
        for place, message in check_experiment(experiment):
            bad(f"DefaultExperiment ({place})", message)
    return experiment, outputs
