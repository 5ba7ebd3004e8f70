"""Agent containers end to end: `swarm run --agents-per-process K` (K agents per OS process,
each its own node) in lockstep equals `swarm simulate` exactly, the ROS graph lists every agent
node, and faults hit one agent of a container while the others in that process go on."""
import json
import subprocess
import time

import numpy as np
import pytest
import yaml

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.helpers import Lines, short_homotopy


def scenario(tmp_path, n, duration):
    """The short homotopy scenario (leaders at t = 2, λ rising from t = 4) with n agents."""
    path = short_homotopy(tmp_path / f'containers_{n}.yaml', duration=duration,
                          lam='{kind: tanh_window, rise_at: 4, fall_at: 1000, tau: 1}', at=2)
    if n != 6:
        doc = yaml.safe_load(path.read_text())
        side = int(np.ceil(np.sqrt(n)))
        doc['agents']['positions'] = [[float(i % side), float(i // side)] for i in range(n)]
        path.write_text(yaml.safe_dump(doc))
    return path


def graph_agents(want, proc, timeout):
    """The nodes ``ros2 node list`` shows (the faithful stand-in, tests/fakes/ros2cli_verbs.py:
    a fresh participant, 0.5 s of discovery, one look), run again as a user would until all of
    ``want`` are there (or ``proc`` ends)."""
    from tests.fakes.ros2cli_verbs import node_list
    end = time.monotonic() + timeout
    seen = set()
    while time.monotonic() < end and proc.poll() is None:
        seen = set(node_list())
        if want <= seen:
            break
    return seen


def node_services(ns, lean, proc, timeout):
    """The service servers of node ``<ns>/agent`` as ``ros2 node info`` lists them (the stand-in),
    run again until its parameter services are there (``lean`` False) or, for a lean node,
    until its /swarm/states writer is listed."""
    from tests.fakes.ros2cli_verbs import NodeNotFound, node_info
    end = time.monotonic() + timeout
    names = set()
    while time.monotonic() < end and proc.poll() is None:
        try:
            info = node_info(f'{ns}/agent')
        except NodeNotFound:
            continue
        names = set(info['services'])
        if (f'{ns}/agent/set_parameters' in names) if not lean else '/swarm/states' in info['publishers']:
            break
    return names


@pytest.mark.parametrize('n,per', [(6, 1), (6, 3), (6, 6), (24, 12)], ids=['6x1', '2x3', '1x6', '24-2x12'])
def test_containers_lockstep_equal_simulate(n, per, tmp_path, ros_domain, processes, swarm_cmd):
    from swarm_agent.container_core import split_agents
    from swarm_tools.run.params import node_parameters, write_params_file
    from swarm_tools.run.processes import agent_commands
    path = scenario(tmp_path, n, duration=10.0 if n == 6 else 6.0)
    scn = load(str(path))
    # the graph: the agent processes as the launcher spawns them (`agent_commands`), on their own
    # (a run may end before a watcher has discovered it): every agent node, one host per container
    params = write_params_file(node_parameters(scn, str(path), 'lockstep'), tmp_path / 'params.yaml')
    groups = split_agents(scn.names, per)
    lean = n == 24          # the agent nodes without services (`swarm run --agent-services off`)
    agents = [processes.start(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
              for _, _, cmd in agent_commands(groups, ['--ros-args', '--params-file', str(params)], not lean)]
    want = {f'/{nm}/agent' for nm in scn.names}
    hosts = set() if per == 1 else {f'/agent_container_{i}' for i in range(0, n, per)}
    seen = graph_agents(want | hosts, agents[0], 180)
    services = node_services('/agent_1', lean, agents[0], 60) if want <= seen else set()
    for a in agents:
        a.terminate()
    for a in agents:
        a.wait(timeout=30)
    assert want <= seen, f'graph lacks {sorted(want - seen)[:5]}'
    assert {nm for nm in seen if nm.startswith('/agent_container_')} == hosts, seen   # one host node per container
    assert ('/agent_1/agent/set_parameters' in services) != lean, services
    # the run
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', str(per)]
                        + (['--agent-services', 'off'] if lean else []),
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    if per > 1:
        assert f'({per} agents per process' + (', agent nodes without services)' if lean else ')') in text
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(scn)
    np.testing.assert_array_equal(got.r, ref.r)                # exact
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
    assert ref.leader.any() and ref.lam.max() > 0.5            # leaders and λ were in the run
    pids = json.loads((out / 'pids.json').read_text())
    assert len(set(pids.values())) == n // per                 # agents of a container share its pid


FAULTS = """\
faults:
  - {at: 3, freeze: agent_1, for: 2.0}
  - {at: 6, kill: agent_4}
"""
RADIO = """\
comms: {loss: 0.3, latency: 0.1}
"""


@pytest.mark.parametrize('per, extra', [('3', FAULTS), ('3', RADIO), ('1', FAULTS)],
                         ids=['faults', 'radio', 'lone-agents-faults'])
def test_compiled_containers_equal_simulate(per, extra, tmp_path, ros_domain, processes, swarm_cmd):
    """``--compiled on``: two containers of three sum their rows in the compiled kernels and
    take their usual steps in one compiled call (`compiled_step`), lone agents too, and the run
    equals ``simulate(compiled='on')`` bit for bit, with faults and with the radio."""
    pytest.importorskip('numba')
    path = scenario(tmp_path, 6, duration=8.0)
    path.write_text(path.read_text() + extra)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', per,
                         '--compiled', 'on'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    scn = load(str(path))
    ref = simulate(scn, compiled='on')
    assert ref.meta['neighbour_search'] == 'compiled'
    got = Trajectory.load(out / 'trajectory.npz')
    np.testing.assert_array_equal(got.r, ref.r)                 # NaN where dead, in both
    both = np.isfinite(got.u) & np.isfinite(ref.u)              # (a frozen agent's u is not recorded)
    assert np.isnan(got.u[np.isnan(ref.u)]).all() and both.mean() > 0.9
    np.testing.assert_array_equal(got.u[both], ref.u[both])
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)


def test_container_fault_one_agent_killed_one_frozen(tmp_path, ros_domain, processes, swarm_cmd):
    """All six agents in one process: agent_4 killed, agent_1 frozen for 2 s; the four others
    in the same process go on, and the run equals the batch engine with the same faults."""
    path = scenario(tmp_path, 6, duration=12.0)
    path.write_text(path.read_text() + FAULTS)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', '6'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    assert 'fault: kill (in-process' in text and 'not in the table from step' in text, text[-3000:]
    scn = load(str(path))
    ref = simulate(scn)
    got = Trajectory.load(out / 'trajectory.npz')
    assert np.array_equal(np.isfinite(got.r), np.isfinite(ref.r))
    fin = np.isfinite(ref.r)
    np.testing.assert_array_equal(got.r[fin], ref.r[fin])
    both = np.isfinite(got.u) & np.isfinite(ref.u)
    assert np.isnan(got.u[np.isnan(ref.u)]).all()
    np.testing.assert_array_equal(got.u[both], ref.u[both])
    k_kill, k_freeze = int(round(6 / scn.dt)), int(round(3 / scn.dt))
    assert np.isnan(got.r[k_kill + 1:, 4]).all()                    # dead from its kill on
    others = [0, 2, 3, 5]
    assert np.isfinite(got.r[:, others]).all()                      # the process's other agents went on
    assert np.all(np.diff(got.r[k_freeze + 2:k_freeze + 38, 1, 0]) == 0)   # agent_1 held still while frozen
    assert np.any(np.diff(got.r[-20:, 1, 0]) != 0)                 # ... and moves again
    want = sorted((e['kind'], e.get('agent'), e['t']) for e in ref.meta['events'])
    events = [json.loads(ln) for ln in (out / 'events.jsonl').read_text().splitlines()]
    assert sorted((e['kind'], e.get('agent'), e['t']) for e in events) == want
    pids = json.loads((out / 'pids.json').read_text())
    assert len(set(pids.values())) == 1                             # one process held all six


def test_container_live_faults_and_a_killed_container(tmp_path, ros_domain, processes, swarm_cmd):
    """Three containers of two: `swarm kill agent_4` and `swarm pause agent_1 5` act on that
    agent alone (its container partner goes on); SIGKILL to the container of agent_2 and agent_3
    kills both, and the world drops them as lost after its missing_timeout."""
    import os
    import signal
    path = scenario(tmp_path, 6, duration=150.0)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', '2',
                         '--missing-timeout', '3', '--progress-every', '25'],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait_for('discovered in', 120), ''.join(lines.lines)
    cli = [processes.start([swarm_cmd, 'kill', 'agent_4'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True),
           processes.start([swarm_cmd, 'pause', 'agent_1', '5'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)]
    pids = json.loads((out / 'pids.json').read_text())
    assert pids['agent_2'] == pids['agent_3'] and len(set(pids.values())) == 3
    os.kill(pids['agent_2'], signal.SIGKILL)                   # the whole container, from outside
    for c in cli:
        msg, _ = c.communicate(timeout=60)
        assert c.returncode == 0, msg
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    text = ''.join(lines.lines)
    assert 'agents[agent_2..agent_3] exited with code' in text and 'its 2 agents are gone' in text, text[-3000:]
    events = [json.loads(ln) for ln in (out / 'events.jsonl').read_text().splitlines()]
    by = {(e['kind'], e.get('agent')): e for e in events}
    kill, freeze, resume = by[('kill', 'agent_4')], by[('freeze', 'agent_1')], by[('resume', 'agent_1')]
    assert ('lost', 'agent_2') in by and ('lost', 'agent_3') in by
    live = Trajectory.load(out / 'trajectory.npz')
    assert np.isnan(live.r[kill['step']:, 4]).all() and np.isfinite(live.r[:kill['step'], 4]).all()
    for nm in ('agent_2', 'agent_3'):
        k = by[('lost', nm)]['step']
        i = int(nm[-1])
        assert np.isnan(live.r[k:, i]).all() and np.isfinite(live.r[:k, i]).all()
    assert np.isfinite(live.r[:, [0, 1, 5]]).all()             # the partners went on to the end
    k0, k1 = freeze['step'], resume['step']
    assert np.array_equal(live.r[k1, 1], live.r[k0, 1])       # agent_1 held still while paused
    assert not np.array_equal(live.r[-1, 1], live.r[k1, 1])    # ... and flew on


def run_realtime(swarm_cmd, processes, path, out, *extra, timeout=300):
    p = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--out', out, '--no-figure', *extra],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, timeout) == 0, ''.join(lines.lines[-40:])
    return ''.join(lines.lines)


def test_realtime_container_faults_act_on_one_agent(tmp_path, ros_domain, processes, swarm_cmd):
    """Realtime, all six agents in one process driven by one timer: agent_4 killed, agent_1
    frozen for 2 s; the others fly on at unit speed, and the run reports its timing."""
    path = scenario(tmp_path, 6, duration=12.0)
    path.write_text(path.read_text() + FAULTS)
    out = tmp_path / 'run'
    text = run_realtime(swarm_cmd, processes, path, out, '--rtf', '2', '--agents-per-process', '6')
    assert 'fault: kill (in-process' in text and 'fault: freeze (in-process' in text, text[-3000:]
    assert 'swarm run: timing: ' in text, text[-2000:]
    timing = json.loads((out / 'metrics.json').read_text())['timing']
    assert timing['states'] > 0 and 0 <= timing['on_time_share'] <= 1
    events = [json.loads(ln) for ln in (out / 'events.jsonl').read_text().splitlines()]
    by = {(e['kind'], e.get('agent')): e for e in events}
    kill, freeze, resume = by[('kill', 'agent_4')], by[('freeze', 'agent_1')], by[('resume', 'agent_1')]
    live = Trajectory.load(out / 'trajectory.npz')
    assert np.isnan(live.r[kill['step'] + 1:, 4]).all()            # dead: gone from its kill on, as in lockstep
    assert np.isfinite(live.r[:kill['step'] - 1, 4]).all()
    k0, k1 = freeze['step'] + 3, resume['step']
    assert np.all(live.r[k0:k1, 1] == live.r[k0, 1])               # agent_1 held still while frozen
    assert not np.array_equal(live.r[-1, 1], live.r[k1, 1])        # ... and flew on
    # the others fly on at unit speed up to their last state (the rest is held); a late tick flies
    # every period, but the chords of the states that caught up several periods are shorter than their arcs
    for i in (0, 2, 3, 5):
        step = np.linalg.norm(np.diff(live.r[:, i], axis=0), axis=1)
        last = np.flatnonzero(step > 0)[-1] + 1
        assert 0.95 <= step.sum() / live.t[last] <= 1.01, (i, step.sum(), live.t[last])


# the container falls behind its clock by more than future_tolerance, so it refuses some decisions as
# from the future: the overload this test makes on purpose
@pytest.mark.refuses_inputs
def test_realtime_run_that_falls_behind_says_so(tmp_path, ros_domain, processes, swarm_cmd):
    """24 agents in one process at a clock 100 times real time (a control period of 1 ms wall):
    the run cannot keep up, and it says so with its late share instead of hiding it."""
    path = scenario(tmp_path, 24, duration=40.0)
    out = tmp_path / 'run'
    text = run_realtime(swarm_cmd, processes, path, out, '--rtf', '100', '--agents-per-process', '24')
    timing = json.loads((out / 'metrics.json').read_text())['timing']
    assert timing['states'] > 24 * 100 and timing['on_time_share'] < 0.99, timing
    assert timing['achieved_rtf'] < 100
    assert 'swarm run: fell behind: ' in text and 'swarm run: timing: ' in text, text[-2000:]
    assert '[world] fell behind: ' in text
