"""`swarm run` and signals at the edges: Ctrl-C while the nodes are still starting (no
traceback: the launcher stops its children with SIGTERM, on which a process still importing
ends quietly), and a world killed by SIGKILL (the launcher names the signal and exits 128 + 9)."""
from __future__ import annotations

import json
import os
import signal
import subprocess

from tests.e2e.test_launcher_crash import cmdline, group_members, wait_for
from tests.helpers import Lines


def start(processes, swarm_cmd, out, *more):
    p = processes.start([swarm_cmd, 'run', 'global_alignment', '--duration', '3000', '--out', out, '--no-figure',
                         '--progress-every', '1', *more], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return p, Lines(p)


def test_ctrl_c_as_the_nodes_start_prints_no_traceback(ros_domain, processes, swarm_cmd, tmp_path):
    """SIGINT to the launcher as soon as it has started its nodes (about a second after
    `swarm run` starts): each node was still importing, and SIGINT from the launcher raised
    KeyboardInterrupt in it, with a traceback (one per node)."""
    out = tmp_path / 'out'
    p, lines = start(processes, swarm_cmd, out)
    pgid = None
    try:
        wait_for(lambda: (out / 'pids.json').exists() or p.poll() is not None, 180, 'the nodes to start')
        assert p.poll() is None, ''.join(lines.lines)
        pgid = os.getpgid(next(iter(json.loads((out / 'pids.json').read_text()).values())))
        os.kill(p.pid, signal.SIGINT)                        # what Ctrl-C does to the launcher
        assert lines.wait(p, 60) == 130, ''.join(lines.lines[-50:])
        text = ''.join(lines.lines)
        assert 'swarm run: SIGINT: stopping' in text, text[-3000:]
        assert 'Traceback' not in text and 'KeyboardInterrupt' not in text, text[-5000:]
        wait_for(lambda: not group_members(pgid), 30, 'every node to end')
    finally:
        if pgid is not None and group_members(pgid):
            os.killpg(pgid, signal.SIGKILL)


def test_a_world_killed_by_sigkill_is_named_with_exit_code_137(ros_domain, processes, swarm_cmd, tmp_path):
    """The world SIGKILLed mid-run: the launcher says so by name and exits 128 + 9 (the code a
    shell gives a process killed by SIGKILL; it exited 247, Python's -9), and run.json says it."""
    out = tmp_path / 'out'
    p, lines = start(processes, swarm_cmd, out)
    pgid = None
    try:
        wait_for(lambda: (out / 'pids.json').exists() or p.poll() is not None, 180, 'the nodes to start')
        pgid = os.getpgid(next(iter(json.loads((out / 'pids.json').read_text()).values())))
        assert lines.wait_for('[world] t=    1.00', 180), ''.join(lines.lines[-50:])
        world = [m for m in group_members(pgid) if 'swarm_world' in cmdline(m)]
        assert len(world) == 1
        os.kill(world[0], signal.SIGKILL)
        assert lines.wait(p, 120) == 137, ''.join(lines.lines[-50:])
        text = ''.join(lines.lines)
        assert 'swarm run: the world was killed by SIGKILL; stopping the run (exit code 137)' in text, text[-3000:]
        assert json.loads((out / 'run.json').read_text())['exit_code'] == 137
        wait_for(lambda: not group_members(pgid), 30, 'every child to end')
    finally:
        if pgid is not None and group_members(pgid):
            os.killpg(pgid, signal.SIGKILL)

