"""What the master adds on top of the FMI calls: its stepping loop vs a bare loop of the same
calls (batched get/set + doStep per FMU, no bookkeeping), seed circle at h = 0.001, one run.

Two bare loops: through fmpy's Python wrappers (getReal/setReal/doStep), and calling the C
functions through ctypes with preallocated arrays (the floor for any Python master).
Run: make bench   (or: .venv/bin/python bench/loop_overhead.py)
"""
from __future__ import annotations

import ctypes
import dataclasses
import time
from pathlib import Path

import numpy as np
from fmpy.fmi2 import FMU2Slave

from mecanum_fmu import master
from mecanum_fmu.process import exit_now
from mecanum_fmu.runner import prepare

ROOT = Path(__file__).resolve().parents[1]
H, STOP = 0.001, 10.0


def _instances(graph):
    fmus = []
    for inst in graph.instances:   # source, c2w, w2c, pose (dependency order)
        md = inst.model
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=master.RUNTIME.extracted(inst.fmu_path),
                        modelIdentifier=md.coSimulation.modelIdentifier,
                        instanceName=f"bare_{inst.name}")
        fmu.instantiate()
        for name, value in inst.start_values.items():
            var = next(v for v in md.modelVariables if v.name == name)
            (fmu.setString if var.type == "String" else fmu.setReal)([var.valueReference], [value])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        vrs = {v.name: v.valueReference for v in md.modelVariables}
        ins = [vrs[v.name] for v in md.modelVariables if v.causality == "input"]
        outs = [vrs[v.name] for v in md.modelVariables
                if v.causality == "output" and v.type == "Real"]
        # the master records every output, Boolean ones (Wheel2Center.has_icr) included
        flags = [vrs[v.name] for v in md.modelVariables
                 if v.causality == "output" and v.type == "Boolean"]
        fmus.append((fmu, ins, outs, flags))
    return fmus


def _release(fmus):
    for fmu, *_ in fmus:
        fmu.terminate()
        fmu._functions["fmi2FreeInstance"](fmu.component)   # never unload pythonfmu's library


def bare_fmpy(graph, n: int) -> float:
    fmus = _instances(graph)
    tick = time.perf_counter()
    for k in range(n):
        t = k * H
        values = None
        for fmu, ins, outs, flags in fmus:
            if values is not None:
                fmu.setReal(ins, values[:len(ins)])   # vx, vy, w come first
            fmu.doStep(t, H)
            values = fmu.getReal(outs)
            if flags:
                fmu.getBoolean(flags)
    wall = time.perf_counter() - tick
    _release(fmus)
    return wall


def bare_ctypes(graph, n: int) -> float:
    fmus = _instances(graph)
    plan = []
    for fmu, ins, outs, flags in fmus:
        f = fmu._functions
        plan.append((fmu.component, f["fmi2SetReal"], f["fmi2DoStep"], f["fmi2GetReal"],
                     (ctypes.c_uint * len(ins))(*ins), len(ins),
                     (ctypes.c_uint * len(outs))(*outs), len(outs),
                     (ctypes.c_double * len(outs))(),
                     f["fmi2GetBoolean"], (ctypes.c_uint * len(flags))(*flags), len(flags),
                     (ctypes.c_int * max(len(flags), 1))()))
    tick = time.perf_counter()
    for k in range(n):
        t = k * H
        prev = None
        for (comp, set_real, do_step, get_real, in_vr, n_in, out_vr, n_out, out_val,
             get_bool, flag_vr, n_flags, flag_val) in plan:
            if prev is not None:
                set_real(comp, in_vr, n_in, prev)
            do_step(comp, t, H, 1)
            get_real(comp, out_vr, n_out, out_val)
            if n_flags:
                get_bool(comp, flag_vr, n_flags, flag_val)
            prev = out_val
    wall = time.perf_counter() - tick
    _release(fmus)
    return wall


def ours(graph, name: str) -> float:
    exp = dataclasses.replace(graph.scenario.experiment, master=name, step_size=H, stop_time=STOP)
    return master.simulate(graph, exp).wall_time


def finite_check(graph, n: int) -> float:
    """The stepping loop's once-per-step check for NaN/inf (master.stepping.step_all) alone:
    the same dot product on a Real buffer of this graph's size, n times."""
    from mecanum_fmu.master.plan import Buffers
    real = Buffers(graph, freeze=False).real
    real_dot, zeros = real.dot, np.zeros_like(real)
    tick = time.perf_counter()
    for _ in range(n):
        if real_dot(zeros) != 0.0:
            raise AssertionError("the buffer is finite")
    return time.perf_counter() - tick


def main() -> dict:
    graph = prepare(ROOT / "scenarios" / "circle.yaml")
    n = int(round(STOP / H))
    results = {}
    for _ in range(3):     # interleaved rounds, best of 3: the machine is shared
        for label, fn in (("bare loop, fmpy wrappers", lambda: bare_fmpy(graph, n)),
                          ("bare loop, ctypes", lambda: bare_ctypes(graph, n)),
                          ("master gauss-seidel", lambda: ours(graph, "gauss-seidel")),
                          ("master trapezoidal", lambda: ours(graph, "trapezoidal")),
                          ("master quadratic", lambda: ours(graph, "quadratic")),
                          ("  of which NaN/inf check", lambda: finite_check(graph, n))):
            wall = fn()
            results[label] = min(wall, results.get(label, wall))
    base = results["bare loop, ctypes"]
    print(f"seed circle, h = {H}, {n} steps, 4 FMUs, best of 3 interleaved rounds")
    for label, wall in results.items():
        print(f"  {label:<26} {wall:7.3f} s  {1e6 * wall / n:6.1f} us/step  "
              f"{wall / base:5.2f}x the ctypes bare loop")
    return results


if __name__ == "__main__":
    main()
    exit_now(0)      # no interpreter shutdown with pythonfmu FMUs loaded
