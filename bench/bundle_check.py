"""What the loader's check of a self-contained FMU costs (models/loader/bundle_check.h): every
bundled file's size and SHA-256 against resources/python/MANIFEST, once per load of the FMU.

Times the check itself (a small C program that includes the header, best of 5) for all files
(a host without Python) and for pythonfmu's library alone (a Python host of the same version),
and the plain C host's whole run of the FMU (tests/hosts/plain_host.c: load, start the bundled
Python, instantiate, 10 steps) for the ratio.
Run: .venv/bin/python bench/bundle_check.py
"""
from __future__ import annotations

import subprocess
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEADER = ROOT / "src" / "mecanum_fmu" / "models" / "loader" / "bundle_check.h"
MODEL = "PoseIntegrator"
TIMER = r"""
#include "HEADER"
#include <time.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t);
                          return t.tv_sec * 1e3 + t.tv_nsec / 1e6; }
int main(int argc, char **argv) {
    char why[2048]; double best = 1e9;
    for (int i = 0; i < 5; i++) {
        double a = now();
        if (bundle_check(argv[1], "resources/python/MANIFEST", argc > 2 ? argv[2] : NULL, why,
                         sizeof why)) { printf("damaged: %s\n", why); return 1; }
        double b = now();
        if (b - a < best) best = b - a;
    }
    printf("%.3f\n", best);
    return 0;
}
"""


def _compile(tmp: Path, source: str, name: str) -> Path:
    (tmp / f"{name}.c").write_text(source)
    subprocess.run(["gcc", "-O2", "-Wno-format-truncation", "-o", str(tmp / name),
                    str(tmp / f"{name}.c"), "-ldl"], check=True)
    return tmp / name


def main() -> None:
    from fmpy import read_model_description
    fmu = ROOT / "fmus" / f"{MODEL}.fmu"
    with tempfile.TemporaryDirectory(prefix="mecanum-bench-") as tmp:
        tmp = Path(tmp)
        folder = tmp / "fmu"
        zipfile.ZipFile(fmu).extractall(folder)
        timer = _compile(tmp, TIMER.replace("HEADER", str(HEADER)), "timer")
        real = f"binaries/linux64/{MODEL}.pythonfmu.so"
        all_ms = float(subprocess.run([str(timer), str(folder)], capture_output=True, text=True,
                                      check=True).stdout)
        one_ms = float(subprocess.run([str(timer), str(folder), real], capture_output=True,
                                      text=True, check=True).stdout)
        host = _compile(tmp, (ROOT / "tests" / "hosts" / "plain_host.c").read_text(), "host")
        md = read_model_description(str(folder))
        vrs = {v.name: v.valueReference for v in md.modelVariables}
        t0 = time.perf_counter()
        subprocess.run([str(host), str(folder / "binaries" / "linux64" / f"{MODEL}.so"),
                        md.guid, (folder / "resources").as_uri(), str(vrs["vx"]), "0.5",
                        str(vrs["x"])], check=True, capture_output=True,
                       env={"PATH": "/usr/bin:/bin"})
        run_ms = (time.perf_counter() - t0) * 1e3
    size = sum(int(line.split()[0]) for line in
               zipfile.ZipFile(fmu).read("resources/python/MANIFEST").decode().splitlines())
    print(f"{MODEL}: {size / 1e6:.1f} MB bundled; check of every file {all_ms:.1f} ms, of "
          f"pythonfmu's library alone {one_ms:.2f} ms (best of 5)")
    print(f"plain C host, whole run with the check: {run_ms:.0f} ms; the check is "
          f"{all_ms / run_ms:.2f} of it")


if __name__ == "__main__":
    main()
