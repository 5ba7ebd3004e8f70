#!/usr/bin/env bash
# Set up (.venv, dependencies, project packages), lint (ruff) and run the whole test suite.
#
# Two pytest runs side by side at any time.  The ROS tests (marker `ros`, given by folder: every
# test under a ros/ folder or tests/e2e/; they mostly wait on processes and DDS) are two shards
# of files (`--shard`, tests/conftest.py; each test claims a ROS_DOMAIN_ID of its own, so
# shards do not meet): shard 1 runs from the start, beside the
# pure tests (CPU-bound, no DDS); shard 2 runs once the pure tests are done.  The outputs of the
# background runs follow shard 1's; the exit code is the first failure's.  Arguments go to every
# run (a run that selects no test passes).
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh || exit $?
# the lint gate first (ruff.toml): a finding fails the run before any test starts
.venv/bin/ruff check --quiet . || { echo "ruff check found the problems above (ruff.toml); fix them first"; exit 1; }
# the ROS shards' weights: shard 1 runs beside the pure tests from the start, shard 2 after them
SHARDS=3,2
work=$(mktemp -d "${TMPDIR:-/tmp}/swarm-tests.XXXXXX")
trap 'rm -rf "$work"' EXIT

rest() {        # the pure tests, then ROS shard 2; each one's pid (for a stop) and exit code in $work
  .venv/bin/python -m pytest -q -p no:cacheprovider -m "not ros" "$@" >"$work/pure.log" 2>&1 &
  echo $! >"$work/pid"
  wait $!
  echo $? >"$work/pure.rc"
  [ -e "$work/stop" ] && return
  .venv/bin/python -m pytest -q -p no:cacheprovider -m ros --shard 2/2:$SHARDS "$@" >"$work/ros2.log" 2>&1 &
  echo $! >"$work/pid"
  wait $!
  echo $? >"$work/ros2.rc"
}
rest "$@" &
bg=$!
trap 'touch "$work/stop"; kill -INT "$(cat "$work/pid" 2>/dev/null)" 2>/dev/null; wait $bg; rm -rf "$work"; exit 130' INT TERM
.venv/bin/python -m pytest -q -p no:cacheprovider -m ros --shard 1/2:$SHARDS "$@"
ros1_rc=$?
wait $bg
echo "---- the ROS tests, shard 2"
cat "$work/ros2.log" 2>/dev/null
echo "---- the pure tests (not marked ros)"
cat "$work/pure.log"
codes="$ros1_rc $(cat "$work/ros2.rc" 2>/dev/null || echo 1) $(cat "$work/pure.rc" 2>/dev/null || echo 1)"
for rc in $codes; do
  # 5: no test selected (arguments that name only one kind)
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 5 ]; then exit "$rc"; fi
done
for rc in $codes; do
  if [ "$rc" -ne 5 ]; then exit 0; fi
done
exit 5
