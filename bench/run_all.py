"""`make bench`: every benchmark, measured in one run on this machine. Not tests: nothing here
asserts a time; it prints ratios measured side by side."""
import accuracy
import loop_overhead

if __name__ == "__main__":
    print("== accuracy per cost (bench/accuracy.py)")
    accuracy.main()
    print("\n== stepping-loop overhead (bench/loop_overhead.py)")
    loop_overhead.main()
