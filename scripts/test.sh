#!/usr/bin/env bash
# Set up (.venv, dependencies, project packages), lint (ruff) and run the whole test suite.
#
# Three pytest runs side by side at any time.  The ROS tests (marker `ros`, given by folder: every
# test under a ros/ folder or tests/e2e/; they mostly wait on processes, DDS and the wall clock)
# are three shards of files, dealt out by their measured time (`--shard`, tests/conftest.py;
# tests/durations.json, written by scripts/test_durations.py; each test claims a ROS_DOMAIN_ID of
# its own, so shards do not meet): shards 1 and 2 run from the start, beside the pure tests
# (CPU-bound, no DDS); shard 3, the lightest, runs once the pure tests are done.  The outputs of the
# background runs follow shard 1's; the exit code is the first failure's.  Arguments go to every
# run (a run that selects no test passes).
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh || exit $?
# the lint gate first (ruff.toml): a finding fails the run before any test starts
.venv/bin/ruff check --quiet . || { echo "ruff check found the problems above (ruff.toml); fix them first"; exit 1; }
# the ROS shards' weights (by measured time): 1 and 2 run from the start, 3 after the pure tests
SHARDS=1,1,0.3
work=$(mktemp -d "${TMPDIR:-/tmp}/swarm-tests.XXXXXX")
trap 'rm -rf "$work"' EXIT

run() {         # NAME ARGS...: one pytest run in the background; its log, pid and exit code in $work
  local name=$1; shift
  .venv/bin/python -m pytest -q -p no:cacheprovider "$@" >"$work/$name.log" 2>&1 &
  echo $! >"$work/$name.pid"
  wait $!
  echo $? >"$work/$name.rc"
}
after_pure() {  # the pure tests, then ROS shard 3
  run pure -m "not ros" "$@"
  [ -e "$work/stop" ] && return
  run ros3 -m ros --shard 3/3:$SHARDS "$@"
}
after_pure "$@" &
bg1=$!
run ros2 -m ros --shard 2/3:$SHARDS "$@" &
bg2=$!
stop_all() {
  touch "$work/stop"
  for f in "$work"/*.pid; do kill -INT "$(cat "$f")" 2>/dev/null; done
  wait $bg1 $bg2
  rm -rf "$work"
  exit 130
}
trap stop_all INT TERM
.venv/bin/python -m pytest -q -p no:cacheprovider -m ros --shard 1/3:$SHARDS "$@"
ros1_rc=$?
wait $bg1 $bg2
echo "---- the ROS tests, shard 2"
cat "$work/ros2.log" 2>/dev/null
echo "---- the ROS tests, shard 3"
cat "$work/ros3.log" 2>/dev/null
echo "---- the pure tests (not marked ros)"
cat "$work/pure.log"
codes="$ros1_rc"
for name in ros2 ros3 pure; do codes="$codes $(cat "$work/$name.rc" 2>/dev/null || echo 1)"; done
for rc in $codes; do
  # 5: no test selected (arguments that name only one kind)
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 5 ]; then exit "$rc"; fi
done
for rc in $codes; do
  if [ "$rc" -ne 5 ]; then exit 0; fi
done
exit 5
