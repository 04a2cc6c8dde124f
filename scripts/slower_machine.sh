#!/usr/bin/env bash
# Run a command as if on a machine SLOWDOWN times slower (default 3: the slower 2-core kind our
# figures are stated for), by capping the CPU time its process tree may take: a cgroup whose
# quota is (cores / SLOWDOWN) of the machine, refilled every PERIOD_US (10 ms, short next to the
# graph's 16.7 ms frame period, so that a throttled node stalls for milliseconds, not for the
# 100 ms of the kernel's default period).
#
#   scripts/slower_machine.sh scripts/test.sh              the suite on "the slower kind"
#   HOGS=2 scripts/slower_machine.sh scripts/test.sh       ... with two CPU-bound processes
#                                                          inside the same cap, beside it
#
# What it does not emulate: one thread alone may use the whole cap (2/3 of a core for a
# slowdown of 3 on 2 cores), where a slower core runs it at a third, so serial stretches run up to
# twice as fast as they would there; where both cores are busy (the suite's four workers) the cap
# and the slower machine agree. Needs root and the cpu controller of cgroup v1 or v2; elsewhere it
# says so and exits 2 (docs/measurements.md, "the slower kind, emulated").
set -euo pipefail
SLOWDOWN="${SLOWDOWN:-3}"
HOGS="${HOGS:-0}"
PERIOD_US=10000
# The slower machine would be ours alone: a high scheduling weight lets the capped group take
# its whole quota even while other work loads this machine (the cap stays the upper bound).
WEIGHT_V1=262144
WEIGHT_V2=10000
if [ "$#" -eq 0 ]; then
  echo "usage: [SLOWDOWN=3] [HOGS=0] scripts/slower_machine.sh COMMAND [ARGS...]" >&2
  exit 2
fi
cores="$(nproc)"
quota="$(python3 -c "
import math, sys
s = float(sys.argv[1])
assert s > 0 and math.isfinite(s)
print(int(round($cores * $PERIOD_US / s)))" "$SLOWDOWN" 2>/dev/null)" || {
  echo "scripts/slower_machine.sh: SLOWDOWN must be a number > 0, not '$SLOWDOWN'" >&2; exit 2; }
if [ "$quota" -lt 1000 ]; then
  echo "scripts/slower_machine.sh: SLOWDOWN $SLOWDOWN leaves under 1 ms a period; use at most $((cores * 10))" >&2
  exit 2
fi
name="saw_ros_slower_$$"
if [ -w /sys/fs/cgroup/cpu ] && [ -e /sys/fs/cgroup/cpu/cpu.cfs_quota_us ]; then
  parent=/sys/fs/cgroup/cpu
  group="$parent/$name"
  mkdir "$group"
  echo "$PERIOD_US" > "$group/cpu.cfs_period_us"
  echo "$quota" > "$group/cpu.cfs_quota_us"
  echo "$WEIGHT_V1" > "$group/cpu.shares"
elif [ -w /sys/fs/cgroup ] && grep -qw cpu /sys/fs/cgroup/cgroup.controllers 2>/dev/null; then
  parent=/sys/fs/cgroup
  group="$parent/$name"
  echo +cpu > /sys/fs/cgroup/cgroup.subtree_control 2>/dev/null || true
  mkdir "$group"
  echo "$quota $PERIOD_US" > "$group/cpu.max"
  echo "$WEIGHT_V2" > "$group/cpu.weight"
else
  echo "scripts/slower_machine.sh: no writable cgroup cpu controller here (needs root); cannot cap the CPU" >&2
  exit 2
fi
hog_pids=()
cleanup() {
  for pid in "${hog_pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  # A cgroup with a process in it cannot be removed: this shell leaves it first.
  echo $$ > "$parent/cgroup.procs" 2>/dev/null || true
  rmdir "$group" 2>/dev/null || true
}
trap cleanup EXIT
echo "scripts/slower_machine.sh: $cores cores capped to $quota us of CPU every $PERIOD_US us" \
     "(a machine $SLOWDOWN times slower), $HOGS CPU hog(s) inside the cap" >&2
# Everything started from here on (the command, the hogs, their children) is inside the cap.
echo $$ > "$group/cgroup.procs"
for _ in $(seq 1 "$HOGS"); do
  python3 -c 'while True: pass' &
  hog_pids+=("$!")
done
code=0
"$@" || code=$?
exit "$code"
