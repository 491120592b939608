#!/usr/bin/env bash
# `make test` on a machine that is not idle (issue 29: a compiler elsewhere left cc*.s in /tmp
# and three tests that listed the machine-wide TMPDIR failed). Beside the tests it runs
#   - a writer that keeps making and removing cc*.s-like files directly in the machine's TMPDIR
#     (20 files at a time, a new one every 0.05 s), as a compiler elsewhere does, and
#   - HOGS CPU-heavy jobs (busy loops; default 1).
# Not a test and not timed against a budget: it prints the exit code of `make test`, its wall
# time, the load average before and after, and how many files the writer made. It removes
# what it wrote and stops what it started, by process id.
#   bash bench/under_load.sh            # HOGS=2 bash bench/under_load.sh for one hog per core
set -uo pipefail
cd "$(dirname "$0")/.."
TMP="${TMPDIR:-/tmp}"
HOGS="${HOGS:-1}"
COUNT="$(mktemp "$TMP/under_load_count.XXXXXX")"

writer() {
    local made=() n=0
    trap 'rm -f "${made[@]}"; echo "$n" > "$COUNT"; exit 0' TERM
    while true; do
        made+=("$(mktemp "$TMP/ccXXXXXX.s")")
        n=$((n + 1))
        if [ "${#made[@]}" -gt 20 ]; then
            rm -f "${made[0]}"
            made=("${made[@]:1}")
        fi
        sleep 0.05
    done
}

writer & pids=("$!")
for _ in $(seq "$HOGS"); do
    python3 -c "while True: pass" & pids+=("$!")
done
stop() { kill "${pids[@]}" 2>/dev/null; wait "${pids[@]}" 2>/dev/null; }
trap stop EXIT

echo "under load: a writer into $TMP and $HOGS busy loop(s) beside make test"
echo "before: $(uptime)"
start=$(date +%s)
make test
code=$?
end=$(date +%s)
echo "after:  $(uptime)"
stop
trap - EXIT
echo "make test exit code $code in $((end - start)) s; the writer made $(cat "$COUNT") files in $TMP"
rm -f "$COUNT"
exit "$code"
