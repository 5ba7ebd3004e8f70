#!/usr/bin/env bash
# Set up (.venv, dependencies, project packages) and run the whole test suite.
#
# Two pytest runs side by side: the ROS tests (marker `ros`: they mostly wait on processes and
# DDS, one at a time) and the pure ones (CPU-bound, no DDS).  Together they use the two cores
# that one run would leave half idle.  The pure run's output follows the ROS run's; the exit
# code is the first failure's.  Arguments go to both runs (a run that selects no test passes).
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh || exit $?
pure_log=$(mktemp "${TMPDIR:-/tmp}/swarm-pure-tests.XXXXXX")
trap 'rm -f "$pure_log"' EXIT
.venv/bin/python -m pytest -q -p no:cacheprovider -m "not ros" "$@" >"$pure_log" 2>&1 &
pure=$!
trap 'kill -INT $pure 2>/dev/null; wait $pure; rm -f "$pure_log"; exit 130' INT TERM
.venv/bin/python -m pytest -q -m ros "$@"
ros_rc=$?
wait $pure
pure_rc=$?
echo "---- the pure tests (not marked ros)"
cat "$pure_log"
for rc in $ros_rc $pure_rc; do
  # 5: no test selected (arguments that name only one kind)
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 5 ]; then exit "$rc"; fi
done
if [ "$ros_rc" -eq 5 ] && [ "$pure_rc" -eq 5 ]; then exit 5; fi
exit 0
