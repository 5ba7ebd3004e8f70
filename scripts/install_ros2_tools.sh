#!/usr/bin/env bash
# Install the real ROS 2 launch tools (launch, launch_ros, ros2launch, ros2cli, ros2pkg, ros2run;
# Jazzy) into one directory, for LOCAL TESTING of `ros2 launch swarm_tools swarm.launch.py`
# against the real tools without a full ROS 2 install.  CI does not have them (they are not on
# PyPI): tests/e2e/test_ros2_launch.py skips there, and runs where they are importable:
#
#   scripts/install_ros2_tools.sh                       # -> /work/ros2tools
#   PYTHONPATH=/work/ros2tools .venv/bin/python -m pytest tests/e2e/test_ros2_launch.py
#   PYTHONPATH=/work/ros2tools /work/ros2tools/bin/ros2 launch src/swarm_tools/launch/swarm.launch.py scenario:=global_alignment
#
# Usage: scripts/install_ros2_tools.sh [--target DIR] [--launch REPO] [--launch-ros REPO]
#                                      [--ros2cli REPO] [--branch BRANCH] [--force]
#   REPO      a git repository (bare or not) of github.com/ros2/launch, ros2/launch_ros or
#             ros2/ros2cli, or a directory holding that repository's files (no git; after
#             changing its files, --force reinstalls);
#             defaults: /work/.mirror/ros2+launch/repo, /work/.mirror/ros2+launch_ros/repo,
#             /work/.mirror/ros2+ros2cli/repo (or $ROS2_LAUNCH_REPO, $ROS2_LAUNCH_ROS_REPO,
#             $ROS2_CLI_REPO)
#   DIR       where to install (default /work/ros2tools, or $ROS2_TOOLS_TARGET); put it on PYTHONPATH
#   BRANCH    the branch (or any commit-ish) of the git repositories (default jazzy)
#
# The pure-Python packages are installed with this venv's pip (--no-deps --target), osrf-pycommon
# from PyPI into the same directory, and `composition_interfaces` (no wheel: a ROS message
# package) as an import-only stand-in, just enough for `import launch_ros` (composable nodes do
# not work with it).  Idempotent: a stamp in DIR records what was installed (the commits, this
# script, the interpreter); running it again with the same sources does nothing.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PY=${PYTHON:-$ROOT/.venv/bin/python}
TARGET=${ROS2_TOOLS_TARGET:-/work/ros2tools}
LAUNCH=${ROS2_LAUNCH_REPO:-/work/.mirror/ros2+launch/repo}
LAUNCH_ROS=${ROS2_LAUNCH_ROS_REPO:-/work/.mirror/ros2+launch_ros/repo}
CLI=${ROS2_CLI_REPO:-/work/.mirror/ros2+ros2cli/repo}
BRANCH=jazzy
FORCE=0
OSRF_PYCOMMON='osrf-pycommon==2.0.2'
while [ $# -gt 0 ]; do
  case $1 in
    --target) TARGET=$2; shift 2 ;;
    --launch) LAUNCH=$2; shift 2 ;;
    --launch-ros) LAUNCH_ROS=$2; shift 2 ;;
    --ros2cli) CLI=$2; shift 2 ;;
    --branch) BRANCH=$2; shift 2 ;;
    --force) FORCE=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "install_ros2_tools: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$PY" ] || { echo "install_ros2_tools: no Python at $PY (run scripts/setup.sh, or set PYTHON)" >&2; exit 2; }

# what each source is: "<repo> <commit>" for a git repository, "<dir> dir" for plain files
describe() {
  if git -C "$1" rev-parse --git-dir >/dev/null 2>&1; then
    echo "$1 $(git -C "$1" rev-parse "$BRANCH^{commit}")"
  elif [ -d "$1" ]; then
    echo "$1 dir"
  else
    echo "install_ros2_tools: $1: not a git repository or a directory" >&2
    return 1
  fi
}
want="$(describe "$LAUNCH")
$(describe "$LAUNCH_ROS")
$(describe "$CLI")
$OSRF_PYCOMMON
$(sha256sum "$0" | cut -d' ' -f1)
$("$PY" -c 'import sys; print(sys.version.split()[0])')"
STAMP=$TARGET/.swarm_ros2_tools.stamp
check() {
  PYTHONPATH="$TARGET${PYTHONPATH:+:$PYTHONPATH}" "$PY" -c \
    'import launch, launch_ros.actions, ros2launch.command.launch, ros2cli.cli, ros2pkg.api' 2>/dev/null
}
if [ "$FORCE" = 0 ] && [ "$(cat "$STAMP" 2>/dev/null)" = "$want" ] && check; then
  echo "[ros2tools] up to date in $TARGET"
  exit 0
fi

SRC=$(mktemp -d "${TMPDIR:-/tmp}/ros2tools-src.XXXXXX")
trap 'rm -rf "$SRC"' EXIT
unpack() {        # repository or directory -> $SRC/<name>
  mkdir -p "$SRC/$2"
  if git -C "$1" rev-parse --git-dir >/dev/null 2>&1; then
    git -C "$1" archive "$BRANCH" | tar -x -C "$SRC/$2"
  else
    cp -a "$1/." "$SRC/$2/"
  fi
}
unpack "$LAUNCH" launch
unpack "$LAUNCH_ROS" launch_ros
unpack "$CLI" ros2cli
mkdir -p "$TARGET"
pip_target() {
  "$PY" -m pip install --disable-pip-version-check -q --no-deps --upgrade --target "$TARGET" "$@" 2>&1 \
    | grep -v -e '^WARNING: Location' -e 'WARNING: Target directory' || true
}
echo "[ros2tools] installing launch, launch_ros, ros2launch, ros2cli, ros2pkg, ros2run ($BRANCH) and $OSRF_PYCOMMON into $TARGET"
pip_target "$SRC/launch/launch" "$SRC/launch_ros/launch_ros" "$SRC/launch_ros/ros2launch" \
  "$SRC/ros2cli/ros2cli" "$SRC/ros2cli/ros2pkg" "$SRC/ros2cli/ros2run" "$OSRF_PYCOMMON"

# composition_interfaces: import-only stand-in (launch_ros.actions.load_composable_nodes imports
# composition_interfaces.srv and names LoadNode.Request in annotations)
CI_DIR=$TARGET/composition_interfaces
mkdir -p "$CI_DIR/srv"
cat > "$CI_DIR/__init__.py" <<'EOF'
"""Import-only stand-in for ROS 2's composition_interfaces (scripts/install_ros2_tools.sh of
homotopy-swarm): enough for `import launch_ros`; composable nodes cannot be loaded with it."""
EOF
cat > "$CI_DIR/srv/__init__.py" <<'EOF'
"""Stand-ins for composition_interfaces.srv: using one raises (no message support here)."""


class _StandIn:
    def __init__(self, *args, **kwargs):
        raise RuntimeError('composition_interfaces is an import-only stand-in here '
                           '(scripts/install_ros2_tools.sh): composable nodes are not supported')


def _service(name):
    return type(name, (), {'Request': type(f'{name}_Request', (_StandIn,), {}),
                           'Response': type(f'{name}_Response', (_StandIn,), {})})


LoadNode = _service('LoadNode')
UnloadNode = _service('UnloadNode')
ListNodes = _service('ListNodes')
EOF

check || { echo "install_ros2_tools: the tools do not import from $TARGET:" >&2
           PYTHONPATH="$TARGET" "$PY" -c 'import launch_ros.actions, ros2launch.command.launch' >&2; exit 1; }
echo "$want" > "$STAMP"
echo "[ros2tools] ready: PYTHONPATH=$TARGET $TARGET/bin/ros2 launch ... (or: $PY -c 'import sys; from ros2cli.cli import main; sys.exit(main())' launch ...)"
