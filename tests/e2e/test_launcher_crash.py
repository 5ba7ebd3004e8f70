"""`swarm run` when things are killed: the launcher (no orphans), the recorder (the run goes
on, the bag is recoverable) and the world (the trajectory is rebuilt from the bag)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import Lines


def group_members(pgid: int) -> list[int]:
    """Live (not zombie) processes of process group ``pgid``, from /proc."""
    out = []
    for d in Path('/proc').iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / 'stat').read_text()
        except OSError:
            continue
        fields = stat[stat.rfind(')') + 2:].split()      # state, ppid, pgrp, ...
        if int(fields[2]) == pgid and fields[0] not in ('Z', 'X'):
            out.append(int(d.name))
    return out


def cmdline(pid: int) -> str:
    try:
        return Path(f'/proc/{pid}/cmdline').read_bytes().replace(b'\0', b' ').decode()
    except OSError:
        return ''


def wait_for(cond, timeout, what):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return
        time.sleep(0.2)
    pytest.fail(f'timed out after {timeout} s waiting for {what}')


def start_run(processes, swarm_cmd, tmp_path):
    """A long lockstep run of six agents with --record; returns (launcher, lines, out, bag,
    children's process group) once the world has made progress."""
    out, bag = tmp_path / 'out', tmp_path / 'run.mcap'
    p = processes.start([swarm_cmd, 'run', 'global_alignment', '--duration', '3000', '--record', bag,
                         '--out', out, '--no-figure', '--progress-every', '1'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    wait_for(lambda: (out / 'pids.json').exists() or p.poll() is not None, 180, 'the agents to start')
    assert p.poll() is None, ''.join(lines.lines)
    pids = json.loads((out / 'pids.json').read_text())
    pgid = os.getpgid(next(iter(pids.values())))
    assert lines.wait_for('[world] t=    2.00', 180), ''.join(lines.lines[-50:])
    return p, lines, out, bag, pgid


def _cleanup(pgid):
    if pgid is not None:
        try:
            os.killpg(pgid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def test_dead_recorder_is_a_warning_and_a_killed_launcher_leaves_no_orphans(
        ros_domain, processes, swarm_cmd, tmp_path):
    pgid = None
    try:
        p, lines, out, bag, pgid = start_run(processes, swarm_cmd, tmp_path)
        members = group_members(pgid)
        assert len(members) == 9, [cmdline(m) for m in members]   # 6 agents, world, commander, recorder
        rec = [m for m in members if ' record ' in cmdline(m)]
        assert len(rec) == 1, [cmdline(m) for m in members]
        os.kill(rec[0], signal.SIGKILL)
        assert lines.wait_for('WARNING: the recorder exited', 60), ''.join(lines.lines[-50:])
        n_progress = sum('[world] t=' in ln for ln in lines.lines)
        wait_for(lambda: sum('[world] t=' in ln for ln in lines.lines) >= n_progress + 3, 120,
                 'the run to go on without its recorder')
        assert p.poll() is None, ''.join(lines.lines[-50:])
        # the recorder's bag (killed: no summary) is recovered into a readable one
        r = subprocess.run([swarm_cmd, 'bag', 'recover', bag, tmp_path / 'fixed.mcap'],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        # the launcher killed with SIGKILL: its children follow (parent-death signal)
        p.kill()
        p.wait(timeout=30)
        wait_for(lambda: not group_members(pgid), 30,
                 'the children of the killed launcher to end: '
                 + '; '.join(cmdline(m) for m in group_members(pgid)))
    finally:
        _cleanup(pgid)


def test_killed_world_trajectory_is_rebuilt_from_the_bag(ros_domain, processes, swarm_cmd, tmp_path):
    pgid = None
    try:
        p, lines, out, bag, pgid = start_run(processes, swarm_cmd, tmp_path)
        world = [m for m in group_members(pgid) if 'swarm_world' in cmdline(m)]
        assert len(world) == 1
        os.kill(world[0], signal.SIGKILL)
        code = lines.wait(p, 120)
        text = ''.join(lines.lines)
        assert code != 0, text
        assert 'rebuilt t = 0..' in text, text[-3000:]
        from swarm_core.engine.reference import Trajectory
        traj = Trajectory.load(out / 'trajectory.npz')
        assert len(traj.names) == 6 and len(traj.t) > 40
        assert np.isfinite(traj.r).all()
        assert (out / 'metrics.json').exists()
        wait_for(lambda: not group_members(pgid), 30, 'every child to end')
    finally:
        _cleanup(pgid)


def test_sighup_stops_the_run_and_keeps_the_steps_done(ros_domain, processes, swarm_cmd, tmp_path):
    """A closed terminal (SIGHUP) used to kill the launcher alone, leaving its children."""
    pgid = None
    try:
        out = tmp_path / 'out'
        p = processes.start([swarm_cmd, 'run', 'global_alignment', '--duration', '3000', '--out', out,
                             '--no-figure', '--progress-every', '1'],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        lines = Lines(p)
        wait_for(lambda: (out / 'pids.json').exists() or p.poll() is not None, 180, 'the agents to start')
        pgid = os.getpgid(next(iter(json.loads((out / 'pids.json').read_text()).values())))
        assert lines.wait_for('[world] t=    2.00', 180), ''.join(lines.lines[-50:])
        p.send_signal(signal.SIGHUP)
        assert lines.wait(p, 120) == 130, ''.join(lines.lines[-50:])
        assert not group_members(pgid)
        from swarm_core.engine.reference import Trajectory
        assert (out / 'trajectory.npz').exists(), ''.join(lines.lines[-30:])
        assert len(Trajectory.load(out / 'trajectory.npz').t) > 40
    finally:
        _cleanup(pgid)
