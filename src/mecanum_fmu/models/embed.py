"""The Python runtime each FMU carries, so it runs on a Linux x86_64 machine without Python.

`make fmus` turns pythonfmu's FMU into a self-contained one (and pythonfmu3's FMI 3.0 FMU, with
binaries/x86_64-linux/ for binaries/linux64/ and the loader compiled with -DLOADER_FMI3):

  binaries/linux64/<Model>.so            the loader (models/loader/loader.c, compiled here)
  binaries/linux64/<Model>.pythonfmu.so  pythonfmu's export library, as pythonfmu built it
  binaries/linux64/libpython3.X.so.1.0   the building interpreter's libpython, stripped
  resources/python/stdlib.zip            the standard-library modules the slave imports (.pyc)
  resources/python/lib-dynload/*.so      the extension modules among them (stripped)
  resources/python/MANIFEST              "<size> <sha-256> <path>" of each file above but the
                                         loader: the loader checks them before it opens any
                                         (loader/bundle_check.h), `doctor` too (damage())

The loader uses a Python already in the host process when it has the same major.minor
version, refuses (a clear message in the FMU's log, fmi2Instantiate returns NULL) one of
another version, and otherwise starts the bundled libpython isolated: its standard library
comes from resources/python only, never from PATH, PYTHONHOME, PYTHONPATH or the working folder.

What the slave imports is measured, not guessed: a `python -I -S` subprocess imports pythonfmu's
runtime and every module the slave script names in an import statement anywhere (its block
maths is inlined, so that is all it imports) and lists the standard-library modules that ended
up loaded. Extension modules that need a library
beyond glibc and libz (liblzma, libbz2, libuuid, ...) are left out: the modules that import
them here do so optionally. The pieces (loader, stripped libpython, stdlib per module set) are cached
under cache_root()/runtime, so a rebuild costs little and repeated builds are byte-identical.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..bundle import HOME, MANIFEST
from ..storage import cache_root, zip_bytes
from .link import BINARY_DIR, binary_needs, find_libpython

LOADER_SOURCE = Path(__file__).resolve().parent / "loader" / "loader.c"
BINARY_DIR3 = "binaries/x86_64-linux/"     # FMI 3.0's platform folder
REAL_SUFFIX = ".pythonfmu.so"           # the loader's REAL_SUFFIX
# The libraries an extension module may need and still be bundled: glibc's own, and zlib's
# libz.so.1 (binascii needs it; a "required" package on Debian/Ubuntu, in every base image).
TARGET_LIBS = {"libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2", "librt.so.1",
               "libutil.so.1", "libz.so.1"}
# pythonfmu3 imports ctypes: its _ctypes needs libffi, which an FMI 3.0 FMU carries next to its
# binary (the FMI 3.0 loader loads it before pythonfmu3's library, loader/fmi3_instantiate.h)
SHIPPED_LIBS = {"pythonfmu3": ("libffi.so.8",), "pythonfmu": ()}


class EmbedUnavailable(RuntimeError):
    """This machine cannot build self-contained FMUs (the message says what is missing)."""


@dataclass(frozen=True)
class Runtime:
    """What the FMUs built here carry: this interpreter's libpython and headers."""
    libpython: Path
    soname: str
    include: Path
    version: str            # e.g. 3.11.7

    @property
    def tag(self) -> str:
        """What goes into the FMU's GUID digest: any change makes the FMUs stale."""
        sources = sorted(LOADER_SOURCE.parent.glob("*.[ch]"))     # loader.c and its FMI 3 parts
        loader = _key(*(hashlib.sha256(p.read_bytes()).hexdigest() for p in sources))[:16]
        return f"self-contained Python {self.version} ({self.libpython}), loader {loader}"


@functools.cache
def runtime_or_none() -> Runtime | None:
    """The runtime `make fmus` bundles here, or None: then the FMUs are pythonfmu's own, and
    need the host to bring Python 3.X (why: unavailable_reason())."""
    try:
        return runtime()
    except EmbedUnavailable:
        return None


def unavailable_reason() -> str | None:
    try:
        runtime()
    except EmbedUnavailable as err:
        return str(err)
    return None


def summary() -> str:
    """One line for `make fmus`: what the FMUs built here need on a target machine."""
    rt = runtime_or_none()
    if rt is None:
        return (f"FMUs NOT self-contained ({unavailable_reason()}): a host needs Python "
                f"{sys.version_info.major}.{sys.version_info.minor} with its shared libpython")
    return (f"self-contained FMUs: each carries Python {rt.version} (libpython + the stdlib "
            "modules its slave imports); any Linux x86_64 host, with or without Python")


def runtime() -> Runtime:
    """The runtime for this interpreter; raises EmbedUnavailable with the reason."""
    if not (sys.platform.startswith("linux") and os.uname().machine == "x86_64"):
        raise EmbedUnavailable("self-contained FMUs are built on Linux x86_64 only")
    lib = find_libpython()
    if lib is None:
        raise EmbedUnavailable(f"{sys.executable} has no shared libpython to bundle (use a "
                               "Python built with --enable-shared, e.g. pyenv's)")
    include = Path(sysconfig.get_config_var("INCLUDEPY") or "")
    if not (include / "Python.h").is_file():
        raise EmbedUnavailable(f"Python.h not found in {include} (install the Python headers)")
    for tool in ("gcc", "strip"):
        if shutil.which(tool) is None:
            raise EmbedUnavailable(f"{tool} not found (apt-get install gcc binutils)")
    soname = sysconfig.get_config_var("INSTSONAME") or lib.name
    return Runtime(lib.resolve(), soname, include, sys.version.split()[0])


def embed_entries(entries: dict[str, bytes], identifier: str, rt: Runtime,
                  fmi3: bool = False) -> tuple[dict[str, bytes], list[Path]]:
    """pythonfmu's FMU members (name -> bytes), or pythonfmu3's with fmi3, made self-contained
    (see the module doc), and archives holding the runtime members already deflated
    (write_zip's reuse=)."""
    out = dict(entries)
    folder = BINARY_DIR3 if fmi3 else BINARY_DIR
    binary = f"{folder}{identifier}.so"
    out[f"{folder}{identifier}{REAL_SUFFIX}"] = out.pop(binary)
    loader_key = _key(rt.tag, "fmi3") if fmi3 else _key(rt.tag)
    out[binary] = _cached(f"loader-{loader_key}.so",
                          lambda dest: _compile_loader(rt, dest, fmi3))
    python = {folder + rt.soname: _cached(
        f"libpython-{_key(str(rt.libpython), _stat(rt.libpython))}.so",
        lambda dest: _strip(rt.libpython, dest))}
    stdlib = stdlib_members({n: d for n, d in entries.items() if n.startswith("resources/")})
    for name in SHIPPED_LIBS["pythonfmu3" if fmi3 else "pythonfmu"]:
        path = _loaded_library(name)
        python[folder + name] = _cached(f"lib-{_key(str(path), _stat(path))}.so",
                                        lambda dest, p=path: _strip(p, dest))
    out.update(python)
    out.update(stdlib)
    out[MANIFEST] = manifest({n: d for n, d in out.items() if n != binary
                              and (n.startswith(folder) or n.startswith(HOME))})
    return out, [_deflated(python), _deflated(stdlib)]     # the loader is small: deflated anew


def manifest(members: dict[str, bytes]) -> bytes:
    """The MANIFEST of members (FMU name -> bytes): one "<size> <sha-256> <name>" line each."""
    return "".join(f"{len(data)} {hashlib.sha256(data).hexdigest()} {name}\n"
                   for name, data in sorted(members.items())).encode()


def damage(read, names: set[str]) -> str | None:
    """What the loader's check finds in an FMU whose members read(name) returns (names: all
    of them): None when each file of its MANIFEST has its size and hash, else the first that
    differs and how, in the loader's words."""
    lines = read(MANIFEST).decode(errors="replace").splitlines() if MANIFEST in names else []
    if not lines:
        return f"{MANIFEST} is missing or lists no file"
    for number, line in enumerate(lines, 1):
        size, digest, name = (line.split(" ", 2) + ["", ""])[:3]
        if not size.isdigit() or len(digest) != 64 or not name or ".." in name:
            return f'{MANIFEST} line {number} is not "<size> <sha-256> <path>"'
        if name not in names:
            return f"{name} is missing"
        data = read(name)
        if len(data) != int(size):
            return f"{name} has {len(data)} bytes, the build recorded {size}"
        if hashlib.sha256(data).hexdigest() != digest:
            return f"{name} has other contents than the build recorded"
    return None


def _deflated(members: dict[str, bytes]) -> Path:
    """A cached archive of members, deflated once at level 6 (1% larger than 9 for
    libpython, 1.82 vs 1.81 MB, in a quarter of the time)."""
    key = _key("deflate 6", *(n + hashlib.sha256(d).hexdigest() for n, d in sorted(members.items())))
    _cached(f"deflated-{key}.zip", lambda dest: dest.write_bytes(zip_bytes(members, 6)))
    return cache_root() / "runtime" / f"deflated-{key}.zip"


def stdlib_members(resources: dict[str, bytes]) -> dict[str, bytes]:
    """resources/python/... members for the slave among resources (FMU name -> bytes)."""
    module = resources["resources/slavemodule.txt"].decode().strip()
    package = "pythonfmu3" if "resources/pythonfmu3/__init__.py" in resources else "pythonfmu"
    names = sorted(_import_names(resources[f"resources/{module}.py"]) | {package})
    runtime_files = {n: d for n, d in resources.items() if n.startswith(f"resources/{package}/")}
    # what gets imported depends only on the names the script imports (its maths is inlined)
    # and pythonfmu's runtime: slaves that import the same names share one probe
    key = _key(sys.version, *names, *SHIPPED_LIBS[package], *(n + hashlib.sha256(d).hexdigest()
                                      for n, d in sorted(runtime_files.items())))
    cached = cache_root() / "runtime" / f"modules-{key}.json"
    if cached.is_file():
        files = json.loads(cached.read_text())
    else:
        files = _imported_stdlib(runtime_files, names, SHIPPED_LIBS[package])
        _atomic_write(cached, json.dumps(files).encode())
    zip_key = _key(sys.version, json.dumps(files, sort_keys=True))     # one zip per module set
    members = {HOME + "stdlib.zip": _cached(f"stdlib-{zip_key}.zip",
                                            lambda dest: _write_stdlib_zip(files, dest))}
    dynload = Path(sysconfig.get_config_var("DESTSHARED") or "")
    for name in files["extensions"]:
        members[f"{HOME}lib-dynload/{name}"] = _cached(
            f"ext-{_key(name, _stat(dynload / name))}.so",
            lambda dest, n=name: _strip(dynload / n, dest))
    return members


def _import_names(script: bytes) -> set[str]:
    """Every absolute module name the script imports, anywhere in it (functions included)."""
    names = set()
    for node in ast.walk(ast.parse(script)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


# Run by `python -I -S`: import pythonfmu's runtime and the slave's names, print what loaded.
_PROBE = r"""
import importlib, json, sys
sys.path.insert(0, sys.argv[1])
for name in sys.argv[2:]:
    try:
        importlib.import_module(name)
    except Exception:
        pass
print(json.dumps({n: getattr(m, "__file__", None) for n, m in sys.modules.items()}))
"""


def _imported_stdlib(runtime_files: dict[str, bytes], names: list[str],
                     shipped: tuple[str, ...]) -> dict:
    """{"sources": [stdlib-relative .py paths], "extensions": [lib-dynload file names]}."""
    with tempfile.TemporaryDirectory(prefix="mecanum_fmu_probe_") as tmp:
        for name, data in runtime_files.items():
            path = Path(tmp, name)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        proc = subprocess.run([sys.executable, "-I", "-S", "-c", _PROBE, str(Path(tmp, "resources")),
                               *names], capture_output=True, text=True, cwd=tmp, timeout=120)
    if proc.returncode != 0:
        raise EmbedUnavailable(f"cannot list the modules a slave imports: {proc.stderr[-1000:]}")
    return _classify(json.loads(proc.stdout), shipped)


def _classify(loaded: dict[str, str | None], shipped: tuple[str, ...] = ()) -> dict:
    stdlib = Path(sysconfig.get_path("stdlib")).resolve()
    dynload = Path(sysconfig.get_config_var("DESTSHARED") or stdlib / "lib-dynload").resolve()
    sources, extensions = set(), set()
    for file in filter(None, loaded.values()):
        path = Path(file).resolve()
        if path.parent == dynload:
            if _bundleable(path, shipped):
                extensions.add(path.name)
        elif path.is_relative_to(stdlib) and path.suffix == ".py" \
                and "site-packages" not in path.parts:
            sources.add(path.relative_to(stdlib).as_posix())
    return {"sources": sorted(sources), "extensions": sorted(extensions)}


@functools.cache
def _bundleable(extension: Path, shipped: tuple[str, ...] = ()) -> bool:
    """An extension module that needs no library a target machine may lack (or the FMU ships)."""
    needs = binary_needs(extension.read_bytes())
    return needs is not None and set(needs.needed) <= TARGET_LIBS | set(shipped)


def _loaded_library(soname: str) -> Path:
    """The file of a shared library this process has loaded (libffi: ctypes is imported)."""
    import ctypes  # noqa: F401  (loads libffi)
    for line in Path("/proc/self/maps").read_text().splitlines():
        path = line.split()[-1]
        if Path(path).name == soname or Path(path).name.startswith(soname + "."):
            return Path(path).resolve()
    raise EmbedUnavailable(f"{soname} not found in this process (install libffi)")


# Run by `python -I -S` with PYTHONHASHSEED=0: compile each source to an unchecked hash-based
# .pyc under the output folder. marshal's output depends on the refcounts in the process that
# runs it, so a fresh process that does only this makes the same bytes every time.
_COMPILE = r"""
import importlib.util, marshal, os, sys
stdlib, out = sys.argv[1], sys.argv[2]
for rel in sys.argv[3:]:
    with open(os.path.join(stdlib, rel), "rb") as f:
        source = f.read()
    code = compile(source, rel, "exec", dont_inherit=True, optimize=0)
    pyc = os.path.join(out, rel[:-3] + ".pyc")
    os.makedirs(os.path.dirname(pyc), exist_ok=True)
    with open(pyc, "wb") as f:
        f.write(importlib.util.MAGIC_NUMBER + (1).to_bytes(4, "little")
                + importlib.util.source_hash(source) + marshal.dumps(code))
"""


def _write_stdlib_zip(files: dict, dest: Path) -> None:
    """The sources as unchecked hash-based .pyc files (no source needed, nothing to check),
    stored: zipimport inflates with zlib, an extension module not there yet at start-up."""
    with tempfile.TemporaryDirectory(prefix="mecanum_fmu_pyc_") as tmp:
        env = {"PYTHONHASHSEED": "0", "PATH": os.environ.get("PATH", "")}
        subprocess.run([sys.executable, "-I", "-S", "-c", _COMPILE, sysconfig.get_path("stdlib"),
                        tmp, *files["sources"]], check=True, capture_output=True, env=env,
                       timeout=300)
        members = {rel[:-3] + ".pyc": Path(tmp, rel[:-3] + ".pyc").read_bytes()
                   for rel in files["sources"]}
    dest.write_bytes(zip_bytes(members, stored=True))


def _compile_loader(rt: Runtime, dest: Path, fmi3: bool = False) -> None:
    cmd = ["gcc", "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall",
           "-Wno-format-truncation", f"-I{rt.include}", f'-DBUNDLED_LIBPYTHON="{rt.soname}"',
           *(["-DLOADER_FMI3"] if fmi3 else []),
           str(LOADER_SOURCE), "-o", str(dest), "-lpthread", "-s"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise EmbedUnavailable(f"compiling the FMU loader failed: {proc.stderr[-2000:]}")


def _strip(source: Path, dest: Path) -> None:
    subprocess.run(["strip", "--strip-all", "-o", str(dest), str(source)], check=True,
                   capture_output=True)


def _cached(name: str, make) -> bytes:
    """The bytes of cache_root()/runtime/name, made by make(path) first when missing."""
    path = cache_root() / "runtime" / name
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="mecanum_fmu_embed_") as tmp:
            make(Path(tmp) / "out")
            _atomic_write(path, (Path(tmp) / "out").read_bytes())
    return path.read_bytes()


def _atomic_write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f"{path.name}.{os.getpid()}.part")
    partial.write_bytes(data)
    os.replace(partial, path)


def _stat(path: Path) -> str:
    info = path.stat()
    return f"{info.st_size}:{info.st_mtime_ns}"


def _key(*parts: str) -> str:
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()[:20]
