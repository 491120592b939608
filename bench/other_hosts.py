"""The same run in our master and in other FMI hosts: the seed circle, Jacobi coupling,
h = 0.001 (10,000 steps), from the SSP that `export-ssp` writes. Best of 3 interleaved rounds.

setup = load the SSP, unpack, instantiate, initialize; steps = the stepping loop only.
ecos-cli is Ecos' command-line program (a non-Python host, LD_PRELOAD=libpython): one number
for the whole program, its CSV of every variable at every step included.
Hosts that are not installed are listed with what to install.
Run: make bench   (or: .venv/bin/python bench/other_hosts.py)
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

from mecanum_fmu import master
from mecanum_fmu.process import exit_now
from mecanum_fmu.interop.cross_check import compared_outputs, difference, ours_jacobi
from mecanum_fmu.interop.other_hosts import HOSTS, HostUnavailable, run_host
from mecanum_fmu.runner import prepare
from mecanum_fmu.interop.ssp_write import export_ssp

ROOT = Path(__file__).resolve().parents[1]
H, STOP, ROUNDS = 0.001, 10.0, 3


def main() -> None:
    graph = prepare(ROOT / "scenarios" / "circle.yaml", master_name="jacobi", step_size=H,
                    stop_time=STOP)
    names = compared_outputs(graph)
    exact = (1.0 - math.cos(STOP), math.sin(STOP))     # docs/spec.md: x = 1 - cos t, y = sin t
    best: dict[str, object] = {}
    missing: dict[str, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        ssp = export_ssp(graph, Path(tmp) / "circle.ssp")
        for _ in range(ROUNDS):
            runs = [ours_jacobi(graph, names)]
            for host in HOSTS:
                if host in missing:
                    continue
                try:
                    runs.append(run_host(host, ssp, start=0.0, stop=STOP, step=H,
                                         variables=names))
                except HostUnavailable as err:
                    missing[host] = str(err)
            for run in runs:
                kept = best.get(run.host)
                if kept is None or run.simulate_s < kept.simulate_s:
                    best[run.host] = run
        # the same circle to the seed's accuracy: our default master at its default step
        t0 = time.perf_counter()
        trap_graph = prepare(ROOT / "scenarios" / "circle.yaml")
        trap = master.simulate(trap_graph, trap_graph.scenario.experiment)
        trap_total = time.perf_counter() - t0

    steps = int(round(STOP / H))
    ours = best["mecanum_fmu jacobi"]
    print(f"seed circle, jacobi coupling, h = {H:g}, {steps} steps, 4 FMUs, "
          f"best of {ROUNDS} interleaved rounds")
    print(f"  {'host':<26} {'setup s':>8} {'steps s':>8} {'us/step':>8} {'x ours':>8} "
          f"{'|e| vs exact':>13} {'diff vs ours':>13}")
    for run in best.values():
        setup = "-" if run.setup_s is None else f"{run.setup_s:.3f}"
        err = math.hypot(run.values["pose.x"] - exact[0], run.values["pose.y"] - exact[1])
        print(f"  {run.host + ' ' + run.version:<26} {setup:>8} {run.simulate_s:>8.3f} "
              f"{1e6 * run.simulate_s / steps:>8.1f} {run.simulate_s / ours.simulate_s:>7.2f}x "
              f"{err:>13.3e} {difference(run.values, ours.values, names):>13.1e}")
    for host, why in missing.items():
        print(f"  {host:<26} not run: {why}")
    err = math.hypot(trap.final("pose.x") - exact[0], trap.final("pose.y") - exact[1])
    jacobi_err = math.hypot(ours.values["pose.x"] - exact[0], ours.values["pose.y"] - exact[1])
    need = H * err / jacobi_err        # Jacobi's error is first order: proportional to h
    print(f"  ours, {trap.master} h = {trap.step_size:g} ({trap.steps} steps): |e| = {err:.3e} in "
          f"{trap.wall_time:.4f} s stepping ({trap_total:.3f} s with setup); a Jacobi master "
          f"needs h = {need:.1e} ({STOP / need:,.0f} steps) for that error")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
    exit_now(0)      # no interpreter shutdown with pythonfmu FMUs loaded
