"""`make bench`: every benchmark, measured in one run on this machine. Not tests: nothing here
asserts a time; it prints ratios measured side by side."""
import accuracy
import endurance
import loop_overhead
import memory
import other_hosts
from mecanum_fmu.process import exit_now

if __name__ == "__main__":
    print("== accuracy per cost (bench/accuracy.py)")
    accuracy.main()
    print("\n== stepping-loop overhead (bench/loop_overhead.py)")
    loop_overhead.main()
    print("\n== peak memory against run length (bench/memory.py)")
    memory.main()
    print("\n== the same run in other FMI hosts (bench/other_hosts.py)")
    other_hosts.main()
    print("\n== 1,000 runs in one process (bench/endurance.py)")
    exit_now(endurance.main([]))    # no interpreter shutdown with pythonfmu FMUs loaded
