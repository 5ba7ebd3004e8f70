"""`swarm join`'s watch of the run (`join._watch`, no ROS: the graph, the announcement and the
agents here are stand-ins): it starts its agents once the run is heard, stops at once with the
refusal's exit code when one of them refused its parameters (it used to wait until the run ended
without it), and says so when every agent here has exited."""
from __future__ import annotations

from types import SimpleNamespace

from swarm_tools.run.join import JoinPlan, _watch
from swarm_tools.run.processes import REFUSED_EXIT

RUN = dict(run_id='1a2b3c4d', scenario='s', mode='lockstep', agents=['agent_0', 'agent_1'], scenario_hash='h',
           remote=['agent_1'], since=1.0)


def _join():
    return JoinPlan(scenario='s', roster=['agent_0', 'agent_1'], agents='1', names=['agent_1'],
                    params={'/agent_1/agent': {}}, server='127.0.0.1:11811', wait=30.0, scenario_hash='h')


def _go(refused, alive, spins=20):
    node = SimpleNamespace(get_node_names_and_namespaces=lambda: [('world', '/')])
    started, ticks = [], []
    code = _watch(_join(), node, lambda: ticks.append(1), SimpleNamespace(runs={'1a2b3c4d': RUN}),
                  started.append, alive, lambda: len(ticks) >= spins, refused)
    return code, started, len(ticks)


def test_an_agent_here_that_refused_its_parameters_stops_the_join(capsys):
    calls = []

    def refused():
        calls.append(1)
        return 'agent_1' if len(calls) >= 3 else None
    code, started, ticks = _go(refused, alive=lambda: {'agent_1': object()})
    assert code == REFUSED_EXIT and started == [RUN] and ticks == 4
    assert 'swarm join: agent_1 refused its parameters' in capsys.readouterr().err


def test_every_agent_here_gone_is_exit_1_and_a_live_one_keeps_the_join(capsys):
    code, _, _ = _go(lambda: None, alive=lambda: {})
    assert code == 1 and 'every agent here has exited' in capsys.readouterr().err
    code, _, ticks = _go(lambda: None, alive=lambda: {'agent_1': object()})
    assert code == 130 and ticks == 20                         # stopped by the signal stand-in
