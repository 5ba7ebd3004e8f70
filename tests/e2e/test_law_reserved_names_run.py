"""`swarm run` refuses a law parameter of a reserved name at load, in one line and before it
starts a node (each agent used to fail declaring the name twice, with a traceback).  The other
engines: tests/core/test_law_reserved_names.py."""
from __future__ import annotations

import subprocess

import pytest

from tests.core.test_law_reserved_names import scenario


@pytest.mark.parametrize('mode', ['lockstep', 'realtime'])
@pytest.mark.parametrize('name', ['x', 'use_sim_time', 'stale_after'])
def test_swarm_run_refuses_a_law_parameter_of_a_reserved_name(tmp_path, ros_domain, swarm_cmd, name, mode):
    path = scenario(tmp_path, name)
    r = subprocess.run([swarm_cmd, 'run', str(path), '--mode', mode, '--out', str(tmp_path / 'out'), '--no-figure'],
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 2, (r.returncode, r.stdout[-2000:], r.stderr[-2000:])
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"parameter {name!r} takes a reserved name" in lines[0], r.stderr[-3000:]
    assert 'swarm run: run ' not in r.stdout, r.stdout            # no run was started
