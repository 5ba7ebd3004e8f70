"""The launcher's process supervision (swarm_tools.run.processes.Supervisor), with plain
Python child processes: no ROS."""
from __future__ import annotations

import sys
import time

from swarm_tools.run.processes import Supervisor

# a child that takes ``delay`` s after SIGINT or SIGTERM (the launcher's stop signal, as a node
# stops on either: `rosutil.stop_on_signals`) to write its output, then exits
SLOW_SAVER = '''
import signal, sys, time
def save(*_):
    time.sleep(float(sys.argv[2]))
    open(sys.argv[1], "w").write("saved")
    sys.exit(130)
signal.signal(signal.SIGINT, save)
signal.signal(signal.SIGTERM, save)
print("ready", flush=True)
while True:
    time.sleep(0.05)
'''
# a child that ignores the stop signals (a process stuck in a callback)
DEAF = ('import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n'
        'signal.signal(signal.SIGTERM, signal.SIG_IGN)\nprint("ready", flush=True)\ntime.sleep(60)\n')


def _start(sup, label, code, *args):
    import subprocess
    p = sup.start(label, [sys.executable, '-c', code, *args], None, stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == 'ready'
    return p


def test_a_process_that_writes_the_outputs_gets_time_to_save_them(tmp_path):
    """The world saves its trajectory after the stop signal; on a loaded machine that can outlast the
    grace the other processes get.  It is waited for (up to its own grace); the others are
    killed at theirs."""
    sup = Supervisor()
    out = tmp_path / 'trajectory.npz'
    _start(sup, 'world', SLOW_SAVER, str(out), '1.5')
    deaf = _start(sup, 'agents', DEAF)
    t0 = time.monotonic()
    sup.stop(grace=0.3, keep=('world',), keep_grace=20)
    took = time.monotonic() - t0
    assert out.read_text() == 'saved'
    assert sup.procs['world'].returncode == 130
    assert deaf.returncode == -9
    assert took < 10, took                      # waited for the save, not for the whole grace


def test_a_keeper_that_never_ends_is_killed_after_its_grace(tmp_path):
    sup = Supervisor()
    world = _start(sup, 'world', DEAF)
    t0 = time.monotonic()
    sup.stop(grace=0.2, keep=('world',), keep_grace=1.0)
    assert world.returncode == -9
    assert 0.9 < time.monotonic() - t0 < 8


def test_the_discovery_server_stops_after_the_others_have_left(tmp_path):
    """The processes named ``last`` (the discovery server) get the stop signal only once the others have
    ended, and `LAST_LINGER` s later: time to tell the other hosts that the run's participants
    have left (`swarm join` ends on that)."""
    from swarm_tools.run.processes import LAST_LINGER
    sup = Supervisor()
    agent_out, server_out = tmp_path / 'agent', tmp_path / 'server'
    _start(sup, 'agents', SLOW_SAVER, str(agent_out), '0.5')
    _start(sup, 'discovery_server', SLOW_SAVER, str(server_out), '0')
    sup.stop(grace=5, last=('discovery_server',))
    assert sup.procs['agents'].returncode == 130 and sup.procs['discovery_server'].returncode == 130
    gap = server_out.stat().st_mtime - agent_out.stat().st_mtime
    assert gap >= 0.9 * LAST_LINGER, gap
