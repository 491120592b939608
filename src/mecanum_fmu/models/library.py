"""Find the FMU behind a component and read its model description (fmpy's reader)."""
from __future__ import annotations

import functools
import hashlib
import os
import re
import uuid
import zipfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from xml.etree import ElementTree

import fmpy
from fmpy import read_model_description
from fmpy.model_description import ModelDescription

from ..errors import did_you_mean
from ..archive import ZIP_ERRORS, ArchiveError, checked_members, read_member
from .catalog import MODELS
from .embed import runtime_or_none
from ..storage import FileMemo, cache_root

PACKAGE_DIR = Path(__file__).resolve().parent
MAX_DESCRIPTION_BYTES = 50_000_000      # modelDescription.xml, inflated
# `from mecanum_fmu.models.blocks.X import ...  # inline` (the maths) or
# `from mecanum_fmu.models.slaves.X import ...  # inline` (what slaves share)
_INLINE = re.compile(r"^from mecanum_fmu\.models\.(blocks|slaves)\.(\w+) import [\w, ]+# inline$",
                     re.MULTILINE)
_PYTHONFMU_IMPORT = re.compile(r"^from pythonfmu(?:\.\w+)? import [\w, ]+\n", re.MULTILINE)
# The end of an FMI 3.0 script: the model class that pythonfmu3 finds (slaves/fmi3.py)
_FMI3_MODEL = '''

class {name}(Fmi3Model, {name}, Fmi3Slave):
    """{name} as an FMI 3.0 co-simulation FMU: the slave above on pythonfmu3."""
'''


def default_fmu_dir() -> Path:
    """fmus/ in a source checkout; a per-version cache folder for a plain install."""
    repo = PACKAGE_DIR.parents[2]
    if (repo / "pyproject.toml").is_file():
        return repo / "fmus"
    from mecanum_fmu import __version__
    return cache_root() / __version__ / "fmus"


@dataclass(frozen=True)
class SlaveSource:
    """The self-contained FMU script of a bundled model and the identity derived from it."""
    model_name: str
    module_name: str      # top-level module name inside the FMU
    script: str           # self-contained script text
    tool: str = "pythonfmu"     # or pythonfmu3: an FMI 3.0 FMU

    @property
    def digest(self) -> str:
        """Hash of everything that goes into the FMU: our script and pythonfmu's version."""
        text = self.script + f"\n{self.tool} " + tool_version(self.tool)
        bundled = runtime_or_none()    # the Python runtime the FMU carries (embed.py)
        if bundled is not None:
            text += "\n" + bundled.tag
        return hashlib.sha256(text.encode()).hexdigest()

    @property
    def guid(self) -> str:
        return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "mecanum_fmu:" + self.digest)) + "}"


@functools.cache
def tool_version(tool: str) -> str:
    """The installed version of pythonfmu or pythonfmu3, read once per process (the package
    metadata took 0.7 ms of each FMU's check that it is current, twice per FMU per prepare)."""
    return metadata.version(tool)


def slave_source(model_name: str) -> SlaveSource:
    """The self-contained FMU script for a bundled model, with the block maths inlined (a
    pythonfmu script is loaded as a top-level module from the FMU's resources/)."""
    module = MODELS[model_name].module
    script = _inlined((PACKAGE_DIR / "slaves" / f"{module}.py").read_text(), set())
    return SlaveSource(model_name, f"mecanum_fmu_{module}", script)


def _inlined(text: str, done: set[str]) -> str:
    """text with each `# inline` import replaced by the module's source, itself inlined the
    same way (slaves/sampled.py imports blocks/sensors.py); a module already inlined above is
    not repeated: the whole module is in the script, so every name it defines is there."""
    def inline(match: re.Match) -> str:
        where = f"{match.group(1)}/{match.group(2)}.py"
        if where in done:
            return f"# (mecanum_fmu/models/{where} is inlined above)"
        done.add(where)
        block = _inlined((PACKAGE_DIR / where).read_text(), done)
        return f"# --- inlined from mecanum_fmu/models/{where} ---\n{block}# --- end ---"

    return _INLINE.sub(inline, text)


def fmi3_slave_source(model_name: str) -> SlaveSource:
    """The FMI 3.0 script of a bundled model: its FMI 2.0 script with slaves/fmi3.py in place
    of the pythonfmu imports, and the model class pythonfmu3 finds at the end."""
    script = slave_source(model_name).script
    first = _PYTHONFMU_IMPORT.search(script)
    adapter = (PACKAGE_DIR / "slaves" / "fmi3.py").read_text()
    script = (script[:first.start()]
              + f"# --- inlined from mecanum_fmu/models/slaves/fmi3.py ---\n{adapter}# --- end ---\n"
              + _PYTHONFMU_IMPORT.sub("", script[first.start():]) + _FMI3_MODEL.format(name=model_name))
    return SlaveSource(model_name, f"mecanum_fmu3_{MODELS[model_name].module}", script, "pythonfmu3")


def fmi3_dir(fmu_dir: Path) -> Path:
    """Where `make fmus` puts the FMI 3.0 FMUs: fmus/fmi3/ beside the FMI 2.0 ones."""
    return Path(fmu_dir) / "fmi3"


def bundled_fmu_path(model_name: str, fmu_dir: Path) -> Path:
    return Path(fmu_dir) / f"{model_name}.fmu"


def is_current(model_name: str, fmu_path: Path) -> bool:
    """True when fmu_path exists and was built from the current sources (GUID match)."""
    guid = fmu_guid(fmu_path)
    return guid is not None and guid == slave_source(model_name).guid


def fmu_guid(fmu_path: Path) -> str | None:
    """The GUID (FMI 3.0: instantiation token) an FMU's model description declares; None
    when it cannot be read. Read once per file (each prepare asks twice per bundled FMU)."""
    try:
        return _GUIDS(fmu_path)
    except OSError:
        return None


def _read_guid(fmu_path: Path) -> str | None:
    try:
        with zipfile.ZipFile(fmu_path) as zf:
            root = ElementTree.fromstring(read_member(zf, "modelDescription.xml", MAX_DESCRIPTION_BYTES))
    except (ArchiveError, *ZIP_ERRORS, KeyError, ElementTree.ParseError):
        return None
    return root.get("guid") or root.get("instantiationToken")      # FMI 2.0, FMI 3.0


_GUIDS = FileMemo(_read_guid)


def stale_warning(spec: str, fmu_dir: Path) -> str | None:
    """A warning when a bundled FMU was built from other sources than the installed ones."""
    if spec in MODELS and not is_current(spec, bundled_fmu_path(spec, fmu_dir)):
        return (f"the bundled FMU {spec} in {fmu_dir} is out of date (built from other "
                "sources); `run` and `python -m mecanum_fmu fmus` rebuild it")
    name, fmi3 = bundled_spec(spec)
    if fmi3 and name in MODELS and not is_current3(name, bundled_fmu_path(name, fmi3_dir(fmu_dir))):
        return (f"the bundled FMU {spec} in {fmi3_dir(fmu_dir)} is out of date (built from "
                "other sources); `python -m mecanum_fmu fmus` rebuilds it")
    return None


FMI3_PREFIX = "fmi3/"       # `fmu: fmi3/Center2Wheel`: the bundled model's FMI 3.0 FMU


def bundled_spec(spec: str) -> tuple[str, bool]:
    """(the model name a component's `fmu:` may name, whether it asks for FMI 3.0)."""
    if spec.startswith(FMI3_PREFIX):
        return spec[len(FMI3_PREFIX):], True
    return spec, False


def is_current3(model_name: str, fmu_path: Path) -> bool:
    """is_current for the model's FMI 3.0 FMU."""
    return fmu_guid(fmu_path) == fmi3_slave_source(model_name).guid


def resolve_fmu(spec: str, scenario_dir: Path, fmu_dir: Path) -> Path:
    """A bundled model name -> its FMU in fmu_dir (fmi3/<name>: in fmi3_dir); otherwise a path relative to the scenario
    file. Never builds (an out-of-date bundled FMU is still returned: see stale_warning).
    Raises ValueError with a user-facing reason."""
    bundled, fmi3 = bundled_spec(spec)
    if bundled in MODELS:       # Center2Wheel, or fmi3/Center2Wheel: its FMI 3.0 twin
        folder = fmi3_dir(fmu_dir) if fmi3 else fmu_dir
        path = bundled_fmu_path(bundled, folder)
        if not path.is_file():
            raise ValueError(f"the bundled FMU {spec} is not built in {folder}; build it "
                             "with `python -m mecanum_fmu fmus` (make fmus)")
        return path
    if "\0" in spec:
        raise ValueError(f"FMU path {spec!r:.80} contains a NUL character")
    try:
        path = (scenario_dir / spec).resolve() if not Path(spec).is_absolute() else Path(spec)
        exists, is_file, is_dir = path.exists(), path.is_file(), path.is_dir()
    except (OSError, RuntimeError) as err:     # name too long, symlink loop, ...
        raise ValueError(f"FMU {spec!r:.80}: cannot use this path: "
                         f"{getattr(err, 'strerror', None) or err}") from None
    if not exists:
        hint = ""
        if not spec.endswith(".fmu"):
            hint = f"{did_you_mean(spec, MODELS)} (bundled FMUs: {', '.join(MODELS)})"
        raise ValueError(f"FMU {spec!r} not found (looked for {path}){hint}")
    if not is_file:
        raise ValueError(f"FMU {spec!r} is {'a folder' if is_dir else 'a special file'}, "
                         "not an .fmu file")
    return path


def read_description(path: Path) -> ModelDescription:
    """Read and check that the FMU is FMI 2.0 or 3.0 co-simulation. Raises ValueError with the
    reason. Read once per file (storage.FileMemo): every prepare reads each FMU it names, and
    the description is only read afterwards, never changed."""
    try:
        st = os.stat(path)
    except OSError:
        return _read_description(path)          # says why it is no FMU
    return _DESCRIPTIONS(path, st)


def _read_description(path: Path) -> ModelDescription:
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{path.name} is not an FMU (an FMU is a zip archive)")
    try:
        with zipfile.ZipFile(path) as zf:
            infos = {i.filename: i for i in checked_members(zf)}
    except ArchiveError as err:
        raise ValueError(f"{path.name} cannot be used safely: {err}; export the FMU "
                         "again") from None
    except ZIP_ERRORS as err:
        raise ValueError(f"{path.name} is a damaged zip archive: {err}") from None
    if "modelDescription.xml" not in infos:
        raise ValueError(f"{path.name} has no modelDescription.xml; it is not an FMU")
    if infos["modelDescription.xml"].file_size > MAX_DESCRIPTION_BYTES:
        raise ValueError(f"{path.name}: modelDescription.xml inflates to "
                         f"{infos['modelDescription.xml'].file_size} bytes (limit "
                         f"{MAX_DESCRIPTION_BYTES}); is this a real FMU?")
    version = _fmi_version(path)        # before fmpy: its FMI 1.0 reader fails on a bare file
    if version is not None and version != "2.0" and not version.startswith("3."):
        raise ValueError(f"{path.name} is an FMI {version[:20]} FMU; this master runs FMI 2.0 "
                         "and 3.0 co-simulation FMUs")
    try:
        md = read_model_description(str(path), validate=False)
    except ValueError:
        raise
    except Exception as err:
        raise ValueError(f"{path.name}: cannot read modelDescription.xml: {err}") from None
    if md.fmiVersion != "2.0" and not md.fmiVersion.startswith("3."):
        raise ValueError(f"{path.name} is an FMI {md.fmiVersion} FMU; this master runs FMI 2.0 "
                         "and 3.0 co-simulation FMUs")
    if md.coSimulation is None:
        raise ValueError(f"{path.name} supports model exchange only; this master needs "
                         "a co-simulation FMU (export it for co-simulation)")
    _check_numbers(path, md)
    return md


_DESCRIPTIONS = FileMemo(_read_description)


def _check_numbers(path: Path, md: ModelDescription) -> None:
    """fmi2ValueReference is an unsigned 32-bit and fmi2Integer a signed 32-bit number:
    ctypes would silently wrap anything outside (2**32 becomes 0)."""
    for var in md.modelVariables:
        if not 0 <= var.valueReference < 2**32:
            raise ValueError(f"{path.name}: variable {var.name!r:.80} has valueReference "
                             f"{str(var.valueReference)[:24]}; FMI 2.0 value references are "
                             "0 to 2**32-1 (fix the modelDescription.xml)")
        if var.type in ("Integer", "Enumeration") and var.start is not None:
            try:
                ok = -2**31 <= int(var.start) < 2**31
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"{path.name}: {var.type} variable {var.name!r:.80} has start "
                                 f"{str(var.start)[:40]!r}; fmi2Integer is -2**31 to 2**31-1")


def loading_problem(path: Path, md: ModelDescription) -> str | None:
    """Why the FMU cannot be loaded here, or None: no binary for this platform, or (a pythonfmu
    FMU) its slave script missing - pythonfmu's fmi2Instantiate then crashes the process.
    Cheap: reads the member list and resources/slavemodule.txt only."""
    ident = md.coSimulation.modelIdentifier
    platform = fmpy.platform_tuple if md.fmiVersion.startswith("3.") else fmpy.platform
    member = f"binaries/{platform}/{ident}{fmpy.sharedLibraryExtension}"
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
    except ZIP_ERRORS as err:
        return f"{path.name} is a damaged zip archive: {err}"
    if member in names:
        return _slave_script_problem(path, names, md)
    platforms = sorted({n.split("/")[1] for n in names
                        if n.startswith("binaries/") and n.count("/") >= 2 and n.split("/")[2]})
    return (f"{path.name} has no binary for this platform ({member}); it has "
            f"{', '.join(platforms) if platforms else 'no binaries at all'}; export the FMU "
            f"for {platform}")


def _fmi_version(path: Path) -> str | None:
    """The fmiVersion attribute of the root element, or None when it cannot be read."""
    try:
        with zipfile.ZipFile(path) as zf, zf.open("modelDescription.xml") as f:
            for _, elem in ElementTree.iterparse(f, events=("start",)):
                return elem.get("fmiVersion")
    except Exception:       # a broken file is reported by the full read below
        return None
    return None


def _slave_script_problem(path: Path, names: set[str], md: ModelDescription) -> str | None:
    if "resources/slavemodule.txt" not in names:
        if (md.generationTool or "").startswith("PythonFMU"):   # its binary would crash
            return (f"{path.name} is a pythonfmu FMU without resources/slavemodule.txt (the name "
                    "of its slave script); export the FMU again")
        return None
    try:
        with zipfile.ZipFile(path) as zf:
            module = read_member(zf, "resources/slavemodule.txt", 1000).decode().strip()
    except (ArchiveError, UnicodeDecodeError) as err:
        return f"{path.name}: resources/slavemodule.txt cannot be read: {err}"
    if f"resources/{module}.py" not in names:
        return (f"{path.name} is a pythonfmu FMU whose slave script resources/{module[:80]}.py "
                "is missing; export the FMU again")
    return None
