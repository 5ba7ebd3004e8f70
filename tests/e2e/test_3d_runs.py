"""End-to-end in 3D (``dim: 3``): `swarm run` in lockstep, with agent processes and with agent
containers, equals `swarm simulate` bit for bit (r, x, y, z, u, v, λ, leaders); the bag's
/swarm/states carry the full pose (the quaternion of the frame [x y z]) and twist.angular =
(0, −v, u); realtime and robots with a 3D scenario are refused in one line before anything starts."""
import subprocess

import numpy as np
import pytest

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.model.natural import frame_from_quaternion_3d, quaternion_from_frame
from swarm_core.scenario.loader import load
from tests.agent.test_natural_core import short_3d
from tests.helpers import Lines

KEYS = ('r', 'x', 'y', 'z', 'u', 'v', 'lam', 'leader')


def bag_states(path):
    """{(agent, step): (position (3,), quaternion (4,), angular (3,))} of the bag's /swarm/states."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message

    from swarm_tools.bags.mcap_io import iter_messages
    out = {}
    for m in iter_messages(path, ['/swarm/states']):
        o = deserialize_message(m.data, Odometry)
        p, q, w = o.pose.pose.position, o.pose.pose.orientation, o.twist.twist.angular
        k = round((o.header.stamp.sec + o.header.stamp.nanosec * 1e-9) / 0.1)
        out[o.child_frame_id, k] = (np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]),
                                    np.array([w.x, w.y, w.z]))
    return out


@pytest.mark.parametrize('per', [1, 3], ids=['processes', 'containers'])
def test_3d_lockstep_equals_simulate(per, tmp_path, ros_domain, processes, swarm_cmd):
    path = short_3d(tmp_path / 'h3.yaml', duration=20.0)
    out, bag = tmp_path / 'run', tmp_path / 'run.mcap'
    p = processes.start([swarm_cmd, 'run', path, '--out', out, '--no-figure', '--agents-per-process', str(per)]
                        + (['--record', bag] if per == 3 else []),
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    got, ref = Trajectory.load(out / 'trajectory.npz'), simulate(load(str(path)))
    assert got.r.shape == ref.r.shape == (201, 6, 3)
    for key in KEYS:
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)      # exact
    assert ref.leader.any() and ref.lam.max() > 0.5 and np.abs(ref.v).max() > 0
    if per != 3:
        return
    states = bag_states(bag)
    names = got.names
    assert len(states) == 202 * 6, len(states)            # steps 0 … 200, and 201 after the last u
    for (name, k), (pos, q, w) in states.items():
        if k > 200:
            continue
        i = names.index(name)
        np.testing.assert_array_equal(pos, got.r[k, i])
        np.testing.assert_array_equal(q, np.array(quaternion_from_frame(got.x[k, i], got.y[k, i], got.z[k, i]))[:, 0])
        frame = frame_from_quaternion_3d(*q)
        for f, want in zip(frame, (got.x[k, i], got.y[k, i], got.z[k, i])):
            np.testing.assert_allclose(f[0], want, atol=1e-12)
        held = (0.0, 0.0) if k == 0 else (got.u[k - 1, i], got.v[k - 1, i])
        np.testing.assert_array_equal(w, [0.0, -held[1], held[0]])                # REP 103: (0, −v, u)


@pytest.mark.parametrize('extra, says', [(['--mode', 'realtime'], 'lockstep only'),
                                         (['--robots', 'external'], 'robots are planar')])
def test_3d_realtime_and_robots_are_refused_in_one_line(extra, says, tmp_path, swarm_cmd):
    path = short_3d(tmp_path / 'h3.yaml', duration=5.0)
    r = subprocess.run([swarm_cmd, 'run', str(path), '--out', str(tmp_path / 'run'), *extra],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert says in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
