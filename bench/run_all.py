"""`make bench`: every benchmark, measured in one run on this machine. Not tests: nothing here
asserts a time; it prints ratios measured side by side."""
import accuracy
import closed_loop_order
import endurance
import loop_overhead
import memory
import other_hosts
import sweep
import turnaround
from mecanum_fmu.process import exit_now

if __name__ == "__main__":
    print("== accuracy per cost (bench/accuracy.py)")
    accuracy.main([])
    print("\n== stepping-loop overhead (bench/loop_overhead.py)")
    loop_overhead.main()
    print("\n== peak memory against run length (bench/memory.py)")
    memory.main()
    print("\n== the same run in other FMI hosts (bench/other_hosts.py)")
    other_hosts.main()
    print("\n== closed-loop convergence (bench/closed_loop_order.py)")
    closed_loop_order.main()
    print("\n== sweeps on Dask (bench/sweep.py)")
    sweep.main([])
    print("\n== command-line turnaround: plots and validate (bench/turnaround.py)")
    turnaround.main()
    print("\n== 1,000 runs in one process (bench/endurance.py)")
    exit_now(endurance.main([]))    # no interpreter shutdown with pythonfmu FMUs loaded
