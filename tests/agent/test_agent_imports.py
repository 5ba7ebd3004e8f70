"""What an agent process loads: not the scenario schema (pydantic), the metrics (scipy) or the
compiled kernels.  A run starts one Python process per agent (or per container): each library
an agent does not use costs every one of them its import time (the schema alone ≈ 0.2 s)."""
from __future__ import annotations

import subprocess
import sys

#: modules no agent process may load (top-level package, or a module of the project)
NOT_IN_AN_AGENT = ('pydantic', 'scipy', 'matplotlib', 'numba', 'mujoco', 'swarm_core.scenario',
                   'swarm_core.robot_spec', 'swarm_core.schema')


def test_an_agent_process_loads_no_schema_no_scipy_and_no_kernels():
    code = ('import sys, swarm_agent.agent_node, swarm_agent.container_node; '
            f'banned = {NOT_IN_AN_AGENT!r}; '
            'print(sorted(m for m in sys.modules if m in banned or m.split(".")[0] in banned))')
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == '[]', r.stdout
