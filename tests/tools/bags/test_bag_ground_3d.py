"""The ground of a 3D run's bag: `swarm report` takes the floor from the run's ``/swarm/run``
announcement, so a bag recorded without ``/parameter_events`` keeps its floor check and its
drawn floor; a bag of an older run still gives it from ``/parameter_events``; a 3D bag with
neither says so in one line.  The bags are written without ROS."""
from __future__ import annotations

import json

import numpy as np
import pytest

from swarm_core.engine import reference as engine
from swarm_core.model.natural import quaternion_from_frame
from swarm_core.scenario import loader as scenario
from swarm_ros.protocol import CDR_LE, OdometryWriter, string_to_cdr
from swarm_ros.runinfo import parse_run, run_json
from swarm_tools.bags import report
from swarm_tools.bags.mcap_io import BagWriter, qos_dict

LATCHED = [qos_dict(history=1, depth=1, reliability=1, durability=1)]
BASE = 1_700_000_000 * 10**9


@pytest.fixture(scope='module')
def run():
    """ground_3d for 6 s: the swarm flies over a floor at z = 0."""
    scn = scenario.load('ground_3d', duration=6.0)
    return scn, engine.simulate(scn)


def _string(text: str) -> bytes:
    return CDR_LE + string_to_cdr(text, 0)[0]


def _parameter_event(node: str, ground: str) -> bytes:
    """An agent's ``ground`` parameter (text) as a ``/parameter_events`` message declares it."""
    from mcap_ros2._dynamic import serialize_dynamic

    from swarm_tools.bags.msgdefs import message_definition
    kind = 'rcl_interfaces/msg/ParameterEvent'
    encode = serialize_dynamic(kind, message_definition(kind))[kind]
    value = dict(type=4, bool_value=False, integer_value=0, double_value=0.0, string_value=ground,
                 byte_array_value=[], bool_array_value=[], integer_array_value=[], double_array_value=[],
                 string_array_value=[])
    return encode(dict(stamp=dict(sec=0, nanosec=0), node=node, new_parameters=[dict(name='ground', value=value)],
                       changed_parameters=[], deleted_parameters=[]))


def _bag(path, scn, traj, *, announce=None, parameters=None):
    """The run's 3D states as its agents publish them on /swarm/states; ``announce``: the
    /swarm/run text; ``parameters``: the agents' ``ground`` parameter on /parameter_events."""
    with BagWriter(path, flush_interval=3600) as w:
        if announce is not None:
            w.add_topic('/swarm/run', 'std_msgs/msg/String', LATCHED)
            w.write('/swarm/run', _string(announce), BASE)
        if parameters is not None:
            w.add_topic('/parameter_events', 'rcl_interfaces/msg/ParameterEvent')
            for name in traj.names:
                w.write('/parameter_events', _parameter_event(f'/{name}/agent', parameters), BASE + 1)
        w.add_topic('/swarm/states', 'nav_msgs/msg/Odometry', [qos_dict(history=1, depth=10, reliability=1,
                                                                         durability=2)])
        writers = [OdometryWriter(name) for name in traj.names]
        for s in range(len(traj.t)):
            sec, nsec = divmod(int(round(traj.t[s] * 1e9)), 1_000_000_000)
            q = np.stack(quaternion_from_frame(traj.x[s], traj.y[s], traj.z[s]), axis=1)
            for k, odom in enumerate(writers):
                w.write('/swarm/states', odom.full(sec, nsec, traj.r[s, k], q[k], traj.u[s, k], traj.v[s, k]),
                        BASE + 10 + s * 1000 + k)
    return path


def _announce(scn, **more):
    return run_json('ab12cd34', scn.name, 'lockstep', scn.names, 1.0, scn.content_hash, dim=3, **more)


def _report(bag, out, capsys, *more):
    assert report.main([str(bag), '--out', str(out), *more]) == 0
    got = capsys.readouterr()
    return json.loads((out / 'metrics.json').read_text())['summary'], got.err


@pytest.fixture
def figures(monkeypatch):
    """The figures the report closes, kept open to be looked at."""
    import matplotlib.pyplot as plt
    kept = []
    close = plt.close
    monkeypatch.setattr(plt, 'close', lambda fig=None: kept.append(fig))
    yield kept
    for fig in kept:
        close(fig)


def test_the_announcement_of_a_3d_run_carries_its_ground_and_a_planar_one_is_as_before():
    from swarm_ros.runinfo import run_ground
    assert run_ground(parse_run(run_json('a', 's', 'lockstep', ['agent_0'], 1.0, dim=3, ground=-2.5))) == (True, -2.5)
    assert run_ground(parse_run(run_json('a', 's', 'lockstep', ['agent_0'], 1.0, dim=3))) == (True, None)
    planar = json.loads(run_json('a', 's', 'lockstep', ['agent_0'], 1.0, ground=0.0))
    assert 'ground' not in planar and planar['dim'] == 2
    # an older 3D run's announcement does not tell; one of a hostile peer tells nothing usable
    old = json.loads(run_json('a', 's', 'lockstep', ['agent_0'], 1.0, dim=3))
    del old['ground']
    assert run_ground(old) == (False, None) and run_ground(None) == (False, None)
    for bad in ('0', float('inf'), True, [0.0], 1e300):
        assert run_ground(dict(old, ground=bad)) == (False, None), bad


def test_a_3d_bag_without_parameter_events_keeps_its_ground(run, tmp_path, capsys, figures):
    scn, traj = run
    bag = _bag(tmp_path / 'run.mcap', scn, traj, announce=_announce(scn, ground=scn.ground))
    summary, err = _report(bag, tmp_path / 'rep', capsys)
    assert scn.ground == 0.0 and summary['dim'] == 3 and summary['ground'] == 0.0
    assert summary['floor_intrusions_total'] == 0 and summary['floor_clearance'] > 3.0, summary
    assert 'ground' not in err, err
    (fig,) = figures
    side = next(ax for ax in fig.axes if ax.get_title() == 'side view')
    assert 'ground' in side.get_legend_handles_labels()[1]


def test_a_3d_bag_of_a_run_without_a_floor_says_nothing_of_one(run, tmp_path, capsys):
    scn, traj = run
    bag = _bag(tmp_path / 'run.mcap', scn, traj, announce=_announce(scn, ground=None))
    summary, err = _report(bag, tmp_path / 'rep', capsys, '--no-figure')
    assert summary['ground'] is None and 'floor_intrusions_total' not in summary
    assert 'ground' not in err, err


def test_an_older_3d_bag_gives_its_ground_from_parameter_events(run, tmp_path, capsys):
    scn, traj = run
    old = json.loads(_announce(scn))
    del old['ground']                          # announced before the announcement told the ground
    bag = _bag(tmp_path / 'run.mcap', scn, traj, announce=json.dumps(old), parameters='0.0')
    summary, err = _report(bag, tmp_path / 'rep', capsys, '--no-figure')
    assert summary['ground'] == 0.0 and summary['floor_intrusions_total'] == 0, summary
    assert 'ground' not in err, err
    # an older run without a floor: its agents' ground parameter is empty
    bag = _bag(tmp_path / 'none.mcap', scn, traj, announce=json.dumps(old), parameters='')
    summary, err = _report(bag, tmp_path / 'none', capsys, '--no-figure')
    assert summary['ground'] is None and 'floor_intrusions_total' not in summary and 'ground' not in err, err


@pytest.mark.parametrize('announce', [True, False])
def test_a_3d_bag_that_does_not_tell_its_ground_says_so_in_one_line(run, tmp_path, capsys, announce):
    scn, traj = run
    old = json.loads(_announce(scn))
    del old['ground']
    bag = _bag(tmp_path / 'run.mcap', scn, traj, announce=json.dumps(old) if announce else None)
    summary, err = _report(bag, tmp_path / 'rep', capsys, '--no-figure')
    assert summary['dim'] == 3 and summary['ground'] is None and 'floor_intrusions_total' not in summary
    said = [line for line in err.splitlines() if 'ground' in line]
    assert said == [f'swarm report: {bag}: the bag does not tell the ground (no ground in its /swarm/run '
                    "announcement, no agent's ground parameter on /parameter_events): no floor intrusion check, "
                    'no floor drawn'], err


def test_a_planar_bag_says_nothing_of_a_ground(tmp_path, capsys):
    from swarm_core.model.frenet import quaternion_from_heading
    from tests.helpers import SIX_GLOBAL
    f = tmp_path / 'six.yaml'
    f.write_text(SIX_GLOBAL)
    scn = scenario.load(str(f))
    traj = engine.simulate(scn)
    qz, qw = quaternion_from_heading(traj.theta)
    bag = tmp_path / 'p.mcap'
    with BagWriter(bag, flush_interval=3600) as w:
        w.add_topic('/swarm/run', 'std_msgs/msg/String', LATCHED)
        w.write('/swarm/run', _string(run_json('ab12cd34', scn.name, 'lockstep', scn.names, 1.0)), BASE)
        w.add_topic('/swarm/states', 'nav_msgs/msg/Odometry')
        writers = [OdometryWriter(name) for name in traj.names]
        for s in range(len(traj.t)):
            sec, nsec = divmod(int(round(traj.t[s] * 1e9)), 1_000_000_000)
            for k, odom in enumerate(writers):
                w.write('/swarm/states', odom(sec, nsec, traj.r[s, k, 0], traj.r[s, k, 1], qz[s, k], qw[s, k],
                                              traj.u[s, k]), BASE + 10 + s * 1000 + k)
    summary, err = _report(bag, tmp_path / 'rep', capsys, '--no-figure')
    assert 'dim' not in summary and 'ground' not in summary and 'ground' not in err, err
