"""SSP 1.0 import: an .ssp archive or a bare .ssd -> the same frozen Scenario the YAML loader
builds, on the scenario's own rules (names, references, experiment checks), so `run` and
`validate` apply the same graph checks to it.

Archives are data: the XML is read with the standard library parser (no external entities are
fetched), FMUs are extracted only from resources/ into a cache folder keyed by the archive's
sha256, and every problem is reported as a ScenarioError with the SSD place.
"""
from __future__ import annotations

import hashlib
import math
import posixpath
import re
import zipfile
from pathlib import Path
from typing import Callable
from xml.etree import ElementTree as ET

from ..errors import Problem, ScenarioError
from ..scenario.document import (Component, Connection, Scenario, Scalar, VarRef, is_finite,
                       is_identifier, parse_experiment, parse_ref, show, usable_name)
from .ssp import ANNOTATION_TYPE, FMU_MIME, NS, SSD_NAME, as_type, local, namespace, q
from ..scenario.graph import port_type
from ..models.library import read_description
from ..archive import ZIP_ERRORS, ArchiveError, checked_members, extract_file, read_member
from ..storage import NotARegularFile, cache_root, open_regular, read_regular

_MAX_SSD_BYTES = 10_000_000          # the SSD and each parameter file
_MAX_SSP_BYTES = 4 << 30             # the .ssp archive itself


def load_ssp(path: str | Path) -> Scenario:
    """Read an .ssp archive or a bare .ssd into a Scenario. Raises ScenarioError listing every
    problem found, each placed in the SSD (e.g. `SystemStructure.ssd: Connection[3]`)."""
    path = Path(path)
    reader = _SsdReader(path)
    root, system = reader.root()
    components = reader.components(system)
    connections = reader.connections(system)
    experiment, outputs = reader.experiment(root)
    if reader.problems:
        raise ScenarioError(reader.problems)
    name = usable_name(root.get("name") or "") or usable_name(path.stem) or "scenario"
    return Scenario(path, name, root.get("description", ""), experiment, tuple(components),
                    tuple(connections), outputs, {})


class _SsdReader:
    """Reads one SSD, collecting every problem with its place in the SSD."""

    def __init__(self, path: Path):
        self.label = str(path)
        self.source = _Source(path, self.label)
        self.problems: list[Problem] = []
        self.connectors: dict[str, set[str] | None] = {}
        self.sys_place = ""

    def at(self, place: str) -> str:
        ssd = SSD_NAME if self.source.zip is not None else ""  # a bare .ssd is the file itself
        return f"{ssd}: {place}" if ssd and place else (place or ssd)

    def bad(self, place: str, message: str) -> None:
        self.problems.append(Problem(self.label, self.at(place), message))

    def fail(self, place: str, message: str) -> ScenarioError:
        return self.source.fail(self.at(place), message)

    def root(self):
        text = self.source.open()
        try:
            root = ET.fromstring(text)
        except ET.ParseError as err:
            line, col = err.position
            raise self.fail(f"line {line}, column {col + 1}", f"XML syntax error: {err}") from None
        if root.tag != q("ssd", "SystemStructureDescription"):
            raise self.fail("SystemStructureDescription", f"root element is {local(root.tag)!r} "
                            f"in {namespace(root.tag) or 'no namespace'}; expected "
                            f"ssd:SystemStructureDescription ({NS['ssd']})")
        systems = root.findall(q("ssd", "System"))
        if len(systems) != 1:
            raise self.fail("SystemStructureDescription",
                            f"expected one ssd:System, found {len(systems)}")
        self.sys_place = f"System[@name='{systems[0].get('name', '')}']"
        return root, systems[0]

    def components(self, system) -> list[Component]:
        """Components with their own bindings, then the system-level bindings
        (element.parameter), which win over the element's own."""
        found: list[tuple[Component, dict[str, Scalar]]] = []
        elements = system.find(q("ssd", "Elements"))
        for i, elem in enumerate(list(elements) if elements is not None else []):
            if isinstance(elem.tag, str):
                item = self._component(i, elem)
                if item is not None:
                    found.append(item)
        params_of = {comp.name: params for comp, params in found}
        place = f"{self.sys_place}/ParameterBindings"
        for key, value in _bindings(system, place, self.source, self.bad).items():
            ref = parse_ref(key)
            if ref is not None and ref.instance in params_of:
                params_of[ref.instance][ref.variable] = value
            else:
                self.bad(place, f"parameter {key!r} does not name component.parameter of a "
                                "component of this system")
        if not self.connectors and not self.problems:
            self.bad(f"{self.sys_place}/Elements", "no ssd:Component: a system needs at least "
                                                   "one FMU")
        # graph messages name the SSD place: components carry it
        return [Component(c.name, c.fmu, _typed(Path(c.fmu), params_of[c.name]), self.at(c.place))
                for c, _ in found if c.fmu]

    def _component(self, i: int, elem):
        cname = elem.get("name")
        place = f"Elements/{local(elem.tag)}[{i + 1}]" + (f"[@name='{cname}']" if cname else "")
        if elem.tag == q("ssd", "SignalDictionaryReference"):
            return self.bad(place, "signal dictionaries are not supported; connect the "
                                   "components directly")
        if elem.tag == q("ssd", "System"):
            return self.bad(place, "nested systems are not supported; flatten the system")
        if elem.tag != q("ssd", "Component"):
            return None
        if not cname or not is_identifier(cname):
            return self.bad(place, f"component name {show(cname)} must be an identifier "
                                   "(letters, digits, _)")
        if cname in self.connectors:
            return self.bad(place, f"a second component named '{cname}'; names must be unique")
        if elem.get("type", FMU_MIME) != FMU_MIME:
            return self.bad(place, f"type {elem.get('type')!r} is not supported; only FMUs "
                                   f"({FMU_MIME})")
        fmu = self._fmu(place, elem)
        conns = elem.find(q("ssd", "Connectors"))
        self.connectors[cname] = (None if conns is None else
                                  {c.get("name") for c in conns.findall(q("ssd", "Connector"))})
        params = _bindings(elem, f"{place}/ParameterBindings", self.source, self.bad)
        return Component(cname, str(fmu) if fmu else "", {}, place), params

    def _fmu(self, place: str, elem) -> Path | None:
        uri = elem.get("source")
        member = self.source.member(uri) if uri else None
        where = "archive" if self.source.zip else "folder"
        if not uri:
            self.bad(place, "has no source (the FMU, e.g. resources/Model.fmu)")
        elif member is None:
            self.bad(f"{place}/@source", f"{uri!r} must be a relative path inside the {where}")
        elif elem.get("implementation", "any") == "ModelExchange":
            self.bad(place, "implementation='ModelExchange' is not supported; this master runs "
                            "co-simulation FMUs")
        else:
            try:
                fmu = self.source.fmu_path(member)
            except ArchiveError as err:
                self.bad(f"{place}/@source", f"{uri!r}: {err}; export the SSP again")
                return None
            if fmu is None:
                self.bad(f"{place}/@source", f"{uri!r} not found in the {where}")
            return fmu
        return None

    def connections(self, system) -> list[Connection]:
        out: list[Connection] = []
        conns = system.find(q("ssd", "Connections"))
        for i, conn in enumerate(conns.findall(q("ssd", "Connection")) if conns is not None else []):
            place = f"Connections/Connection[{i + 1}]"
            ends = [self._end(place, side, conn) for side in ("start", "end")]
            if all(ends):
                out.append(Connection(ends[0], ends[1], self.at(place)))
        return out

    def _end(self, place: str, side: str, conn) -> VarRef | None:
        element, connector = conn.get(f"{side}Element"), conn.get(f"{side}Connector")
        if not element:
            self.bad(place, f"no {side}Element: connections to the system's own connectors "
                            "are not supported (the system has no ports)")
        elif element not in self.connectors:
            self.bad(place, f"{side}Element '{element}' is not a component of this system")
        elif not connector:
            self.bad(place, f"no {side}Connector")
        elif self.connectors[element] is not None and connector not in self.connectors[element]:
            self.bad(place, f"component '{element}' has no connector '{connector}' "
                            f"({side}Connector)")
        else:
            return VarRef(element, connector)
        return None

    def experiment(self, root):
        """The experiment (DefaultExperiment plus our annotation), checked by the scenario's
        own rules, and the recorded outputs our annotation names (None: all)."""
        raw, outputs = {}, None
        default = root.find(q("ssd", "DefaultExperiment"))
        if default is not None:
            for attr, key in (("startTime", "start_time"), ("stopTime", "stop_time")):
                if default.get(attr) is not None:
                    raw[key] = self._number(default.get(attr), f"DefaultExperiment/@{attr}")
            for ann in default.iterfind(f"{q('ssd', 'Annotations')}/{q('ssc', 'Annotation')}"):
                ours = ann.find(q("mf", "Experiment")) if ann.get("type") == ANNOTATION_TYPE else None
                if ours is not None:
                    outputs = self._annotation(ours, raw)
        raw = {k: v for k, v in raw.items() if v is not None}
        experiment = parse_experiment(
            raw, lambda place, message: self.bad(f"DefaultExperiment ({place})", message))
        return experiment, outputs

    def _annotation(self, ours, raw: dict):
        aplace = f"DefaultExperiment/Annotations/Annotation[@type='{ANNOTATION_TYPE}']"
        if ours.get("stepSize") is not None:
            raw["step_size"] = self._number(ours.get("stepSize"), f"{aplace}/@stepSize")
        if ours.get("master") is not None:
            raw["master"] = ours.get("master")
        outs = ours.findall(q("mf", "Output"))
        if not outs:
            return None
        outputs = []
        for k, out in enumerate(outs):
            ref = parse_ref(out.get("name"))
            if ref is None:
                self.bad(f"{aplace}/Output[{k + 1}]", "name must be instance.variable")
            else:
                outputs.append((ref, self.at(f"{aplace}/Output[{k + 1}]")))
        return tuple(outputs)

    def _number(self, text: str, place: str) -> float | None:
        try:
            return float(text)
        except ValueError:
            self.bad(place, f"{show(text)} is not a number")
            return None




class _Source:
    """Files of an .ssp archive or of the folder around a bare .ssd."""

    def __init__(self, path: Path, label: str):
        self.path, self.label = path, label
        self.zip: zipfile.ZipFile | None = None
        self.digest: str | None = None
        self._file = None         # the open archive file (kept open for the zip reader)

    def fail(self, place: str, message: str) -> ScenarioError:
        return ScenarioError([Problem(self.label, place, message)])

    def open(self) -> bytes:
        """The SSD's bytes; for an archive, after checking every member's name and declared
        size (archive.checked_members)."""
        path = self.path
        try:
            if path.suffix.lower() == ".ssd":
                return read_regular(path, _MAX_SSD_BYTES, "a system structure description")
            file = open_regular(path, _MAX_SSP_BYTES, "an .ssp archive")
        except FileNotFoundError:
            raise self.fail("file", "not found; check the path") from None
        except IsADirectoryError:
            raise self.fail("file", "is a folder; give an .ssp archive or an .ssd file") from None
        except NotARegularFile as err:
            raise self.fail("file", str(err)) from None
        except OSError as err:
            raise self.fail("file", f"cannot be read: {err.strerror or err}") from None
        self._file = file
        digest = hashlib.sha256()
        while chunk := file.read(1 << 20):
            digest.update(chunk)
        self.digest = digest.hexdigest()
        try:
            self.zip = zipfile.ZipFile(file)
            names = {i.filename for i in checked_members(self.zip)}
        except ArchiveError as err:
            raise self.fail("file", f"cannot be used safely: {err}") from None
        except ZIP_ERRORS as err:
            raise self.fail("file", f"is not an SSP archive (an .ssp is a zip archive): "
                                    f"{err}") from None
        if SSD_NAME not in names:
            raise self.fail("file", f"has no {SSD_NAME} at its top level (has: "
                                    f"{show(sorted(names)[:6])})")
        try:
            return read_member(self.zip, SSD_NAME, _MAX_SSD_BYTES)
        except ArchiveError as err:
            raise self.fail(SSD_NAME, f"{err}; is this the right file?") from None

    def member(self, uri: str) -> str | None:
        """Archive-relative normalized name of a relative URI, or None when it leaves the root."""
        if re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", uri) or uri.startswith("/"):
            return None
        name = posixpath.normpath(uri.replace("\\", "/"))
        if name.startswith("..") or name == ".":
            return None
        return name

    def read(self, name: str) -> bytes | None:
        """A parameter file's bytes (at most _MAX_SSD_BYTES); None when absent. Raises
        ArchiveError (too large, damaged) or NotARegularFile."""
        if self.zip is not None:
            try:
                return read_member(self.zip, name, _MAX_SSD_BYTES)
            except KeyError:
                return None
        file = self.path.parent / name
        try:
            return read_regular(file, _MAX_SSD_BYTES, "a parameter file")
        except OSError:
            return None

    def fmu_path(self, name: str) -> Path | None:
        """A usable path of the FMU at name: the file itself next to a bare .ssd, or a copy
        extracted once into the cache folder of this archive (written under a partial name
        and renamed; never more than archive.MAX_MEMBER_BYTES). Raises ArchiveError."""
        if self.zip is None:
            file = (self.path.parent / name).resolve()
            return file if file.is_file() else None
        try:
            info = self.zip.getinfo(name)
        except KeyError:
            return None
        if info.is_dir():
            return None
        target = cache_root() / "ssp" / self.digest / name
        try:
            if target.is_file() and target.stat().st_size == info.file_size:
                return target
            return extract_file(self.zip, info, target)
        except OSError as err:
            raise ArchiveError(f"cannot be copied into the cache ({target.parent}): "
                               f"{err.strerror or err}") from None


def _typed(fmu: Path, params: dict[str, Scalar]) -> dict[str, Scalar]:
    """The values as the types of the FMU variables they set (ssp.as_type: an ssv:Integer 5
    for a Real is 5.0); an FMU that cannot be read is left to the graph's checks."""
    try:
        kinds = {v.name: port_type(v) for v in read_description(fmu).modelVariables}
    except ValueError:
        return params
    return {name: as_type(value, kinds.get(name)) for name, value in params.items()}


def _bindings(owner, place: str, source: _Source, bad: Callable) -> dict[str, Scalar]:
    """The values of an element's (or the system's) parameter bindings, inline or from a
    parameter file; every unsupported form is reported at its place."""
    out: dict[str, Scalar] = {}
    node = owner.find(q("ssd", "ParameterBindings"))
    for i, binding in enumerate(node.findall(q("ssd", "ParameterBinding"))
                                if node is not None else []):
        bplace = f"{place}/ParameterBinding[{i + 1}]"
        if binding.find(q("ssd", "ParameterMapping")) is not None:
            bad(bplace, "ParameterMapping is not supported; give the parameters their FMU names")
            continue
        kind = binding.get("type", "application/x-ssp-parameter-set")
        if kind != "application/x-ssp-parameter-set":
            bad(bplace, f"type {kind!r} is not supported (only application/x-ssp-parameter-set)")
            continue
        found = _parameter_set(binding, bplace, source, bad)
        if found is not None:
            out.update(_parameters(*found, binding.get("prefix", ""), bad))
    return out


def _parameter_set(binding, bplace: str, source: _Source, bad: Callable):
    """(ssv:ParameterSet element, its place) of a binding, or None (reported when wrong)."""
    uri = binding.get("source")
    inline = binding.find(q("ssd", "ParameterValues"))
    if uri:
        if binding.get("sourceBase", "SSD") != "SSD":
            return bad(bplace, "sourceBase='component' is not supported; use a path from the SSD")
        member = source.member(uri)
        try:
            data = source.read(member) if member else None
        except (ArchiveError, NotARegularFile) as err:
            return bad(f"{bplace}/@source", f"{uri}: {err}")
        if data is None:
            return bad(f"{bplace}/@source", f"{uri!r} not found "
                       f"{'in the archive' if source.zip else 'next to the SSD'}")
        try:
            pset, pplace = ET.fromstring(data), f"{bplace} ({uri})"
        except ET.ParseError as err:
            return bad(f"{bplace}/@source", f"{uri}: XML syntax error: {err}")
    elif inline is not None:
        sets = [c for c in inline if isinstance(c.tag, str)]
        if len(sets) != 1 or sets[0].tag != q("ssv", "ParameterSet"):
            return bad(f"{bplace}/ParameterValues", "expected one ssv:ParameterSet")
        pset, pplace = sets[0], f"{bplace}/ParameterValues"
    else:
        return None
    if pset.tag != q("ssv", "ParameterSet"):
        return bad(pplace, f"expected an ssv:ParameterSet ({NS['ssv']}), got {local(pset.tag)!r}")
    return pset, pplace


def _parameters(pset, pplace: str, prefix: str, bad: Callable) -> dict[str, Scalar]:
    out: dict[str, Scalar] = {}
    params = pset.find(q("ssv", "Parameters"))
    for j, param in enumerate(params.findall(q("ssv", "Parameter")) if params is not None else []):
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
        if not isinstance(child.tag, str) or namespace(child.tag) != NS["ssv"]:
            continue
        tag, text = local(child.tag), child.get("value")
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
                value = int(text.strip())
                if not is_finite(value):    # the scenario's rule for numbers
                    bad(place, f"ssv:Integer value {show(text)} is too large")
                    return None
                return value
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
