"""An agent's law parameters set live in a lockstep run (``ros2 param set /agent_1/agent alpha
0.3``) land on a defined step and are replayed exactly.

The sets go through the stock path of ``ros2 param set``: ros2cli (Jazzy)
``ros2param/api/__init__.py`` ``call_set_parameters``, one rcl_interfaces/srv/SetParameters
request to ``/<agent>/agent/set_parameters`` with the value typed from the text as
``get_parameter_value`` types it (`tests.agent.ros.test_agent_parameters.ros2_param_set`).
Each agent announces its change on /swarm/events as a ``command`` event (``command: law``)
with the step it took effect at; the world writes it to events.jsonl, and the batch engine
given that file's commands (``swarm simulate --replay``) reproduces the run.
"""
import json

import numpy as np
import yaml

from tests.agent.ros.test_agent_parameters import ros2_param_set
from tests.helpers import short_homotopy


def lockstep_in_one_executor(path, scn, out, ctx):
    """(world, agents, a ``ros2 param``-like node, the executor of them all): the run of the
    scenario file ``path`` (loaded: ``scn``) in lockstep, writing to ``out``."""
    import rclpy

    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.launch import build_nodes
    from swarm_tools.run.params import node_parameters
    params = node_parameters(scn, str(path), 'lockstep', output_dir=str(out))
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    shell = rclpy.create_node('ros2cli_param', context=ctx)
    ex = make_executor(ctx, events=False)
    for nd in [world, commander, *agents, shell]:
        ex.add_node(nd)
    return world, agents, shell, ex


def test_lockstep_live_law_changes_replay_in_the_batch_engine(tmp_path, rclpy_context):
    """Three sets during a lockstep run (nodes in one executor): agent_1 alpha 0.3 near step
    100, agent_3 mu 1 (an integer in the shell) near step 200, agent_1 cutoff_radius 2.5 near
    step 300.  The run's events.jsonl holds three law commands; the batch engine given them
    (reference, and the default fast engine, which falls back to it) reproduces the ROS
    trajectory: positions, λ and leaders bit for bit, θ and u to 1e-9 (θ travels as a
    quaternion); without them it does not."""

    from swarm_core.command.plan import read_commands
    from swarm_core.engine import fast as compiled
    from swarm_core.engine.reference import simulate
    from swarm_core.scenario.loader import load
    from tests.helpers import spin_for

    path = short_homotopy(tmp_path / 'law.yaml', duration=20, lam='{kind: constant, value: 0.3}', at=5.0)
    scn = load(str(path))
    out = tmp_path / 'out'
    world, agents, shell, ex = lockstep_in_one_executor(path, scn, out, rclpy_context)
    sets = [(100, 'agent_1', 'alpha', '0.3'), (200, 'agent_3', 'mu', '1'), (300, 'agent_1', 'cutoff_radius', '2.5')]
    for k, (at_step, agent, name, text) in enumerate(sets):
        assert spin_for(ex, lambda at_step=at_step: world.driver.lock.cur >= at_step, 120)
        res = ros2_param_set(ex, shell, f'/{agent}/agent', name, text)
        assert res.successful, res.reason
        assert spin_for(ex, lambda k=k: len([e for e in world.events if e.get('command') == 'law']) > k, 60)
    assert spin_for(ex, lambda: world.done, 300)
    got = world.trajectory()
    lines = (out / 'events.jsonl').read_text().splitlines()
    laws = [json.loads(ln) for ln in lines if json.loads(ln).get('command') == 'law']
    assert [(e['agent'], e['parameters'], e['node']) for e in laws] == [
        ('agent_1', {'alpha': 0.3}, 'agent'), ('agent_3', {'mu': 1.0}, 'agent'),
        ('agent_1', {'cutoff_radius': 2.5}, 'agent')], laws
    assert [e['step'] for e in laws] == sorted(e['step'] for e in laws) and laws[0]['step'] >= 100
    commands = read_commands(lines, scn.names)
    assert sum(c['command'] == 'law' for cs in commands.values() for c in cs) == 3
    for ref in (simulate(scn, commands=commands), compiled.simulate(scn, commands=commands)):
        assert np.array_equal(got.r, ref.r)                  # positions bit for bit
        assert np.abs(got.theta - ref.theta).max() <= 1e-9   # θ comes back from the quaternion
        assert np.abs(got.u - ref.u).max() <= 1e-9
        assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)
        assert [e for e in ref.meta['events'] if e.get('command') == 'law'] == [
            {k: v for k, v in e.items() if k != 'node'} for e in laws]
    plain = simulate(scn)
    first = laws[0]['step']
    assert np.array_equal(got.r[:first + 1], plain.r[:first + 1])      # the same run up to the first change
    assert not np.array_equal(got.r[first + 2:], plain.r[first + 2:])  # and another one from it on
    shell.destroy_node()


PICKY = '''\
import numpy as np

from swarm_core.laws import Law, param


class Picky(Law):
    """Turns by gain; raises above gain 5 once it has neighbours."""
    gain = param(1.0, lo=0.0, hi=10.0)

    def control(self, view):
        if self.gain > 5 and len(view.pos) > 1:
            raise ValueError(f'gain {self.gain:g} with neighbours')
        return np.full(view.receivers.size, 0.01 * self.gain) + 0.001 * view.receivers
'''


def test_a_set_that_makes_the_law_raise_is_refused_and_the_run_goes_on(tmp_path, rclpy_context):
    """A lockstep run of a user's law file (nodes in one executor): ``gain 6``, in range, makes
    the law raise on agent_1's table, so the set is refused with the law's one line and the run
    goes on to its end; ``gain 4`` is taken.  events.jsonl starts with the law file's hash, the
    law command carries it too, and the batch engine replays the run."""

    from swarm_core.command.plan import read_commands
    from swarm_core.engine.reference import simulate
    from swarm_core.laws.registry import law_code_hash
    from swarm_core.scenario.loader import load
    from tests.helpers import spin_for

    (tmp_path / 'picky.py').write_text(PICKY)
    path = short_homotopy(tmp_path / 'picky.yaml', duration=10, lam='{kind: constant, value: 0.0}', at=5.0)
    data = yaml.safe_load(path.read_text())
    data['law'] = {'kind': 'picky.py:Picky', 'gain': 1.0}
    path.write_text(yaml.safe_dump(data))
    scn = load(str(path))
    law_hash = law_code_hash({'kind': 'picky.py:Picky'}, tmp_path)
    out = tmp_path / 'out'
    world, agents, shell, ex = lockstep_in_one_executor(path, scn, out, rclpy_context)
    agent = agents[1]
    assert spin_for(ex, lambda: world.driver.lock.cur >= 20, 120)
    law = agent.law
    res = ros2_param_set(ex, shell, '/agent_1/agent', 'gain', '6')
    assert not res.successful
    assert 'Picky raised ValueError: gain 6 with neighbours' in res.reason and '\n' not in res.reason, res.reason
    assert agent.law is law and agent.get_parameter('gain').value == 1.0
    assert 'law parameters gain=6.0' in agent.reject.lines[-1], agent.reject.lines
    assert ros2_param_set(ex, shell, '/agent_1/agent', 'gain', '4').successful
    assert spin_for(ex, lambda: world.done, 300)
    assert world.failed is None and world.driver.lock.cur > scn.steps - 1
    lines = (out / 'events.jsonl').read_text().splitlines()
    first = json.loads(lines[0])
    assert first == dict(t=0.0, kind='law', law=scn.law.kind, law_hash=law_hash), first
    laws = [json.loads(ln) for ln in lines if json.loads(ln).get('command') == 'law']
    assert [(e['agent'], e['parameters'], e['law_hash']) for e in laws] == [('agent_1', {'gain': 4.0}, law_hash)]
    got = world.trajectory()
    ref = simulate(scn, commands=read_commands(lines, scn.names))
    assert np.array_equal(got.r, ref.r) and np.abs(got.u - ref.u).max() <= 1e-9
    assert got.u[laws[0]['step'] + 1, 1] > got.u[laws[0]['step'] - 1, 1]    # gain 4 steers harder than 1
    shell.destroy_node()
