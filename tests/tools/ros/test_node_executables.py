"""The node executables (setup.py entry points) answer ``--help`` without starting a node: the
parameters they list come from a node built in an rclpy context of its own."""
import subprocess
from pathlib import Path

import pytest


@pytest.mark.parametrize('exe, param', [('swarm_world', 'scenario (str)'), ('swarm_agent', 'leader_gain (float)'),
                                        ('homotopy_commander', 'ramp (float)')])
def test_node_executables_answer_help_without_starting(ros_domain, swarm_cmd, exe, param):
    """`swarm_world --help` (a setup.py entry point) prints its usage and parameters and
    exits 0; it used to start a world node that waited for agents for 180 s."""
    r = subprocess.run([str(Path(swarm_cmd).with_name(exe)), '--help'], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f'usage: {exe}') and param in r.stdout, r.stdout
