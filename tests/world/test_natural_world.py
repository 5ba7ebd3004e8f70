"""The world's 3D pieces without DDS (`swarm_world.natural`, `markers`): the /world/markers of
a 3D run carry each agent's z and the quaternion of its frame; the realtime record holds each
agent's last state between its stamps."""
import numpy as np
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import MarkerArray

from swarm_core.model.natural import initial_frames, quaternion_from_frame
from swarm_world.markers import Trails, markers_message
from swarm_world.natural import NaturalRecorder


def test_3d_markers_carry_z_and_the_frames_quaternions():
    rng = np.random.default_rng(2)
    pos = rng.uniform(-3, 3, (4, 3))
    quats = np.stack(quaternion_from_frame(*initial_frames(rng.normal(size=(4, 3)))), axis=1)
    raw = markers_message(1.5, pos, quats, np.array([0, 0, 1, 1]), np.arange(4), np.zeros(4, bool), Trails(4, 5),
                          target=np.array([1.0, 2.0, 3.0]), barrier=np.array([[0.0, 0, 0], [1, 0, 1], [0, 1, 2]]))
    m = deserialize_message(raw, MarkerArray)
    agents = [mk for mk in m.markers if mk.ns == 'agents']
    for mk, p, q in zip(agents, pos, quats):
        o = mk.pose.orientation
        assert [mk.pose.position.x, mk.pose.position.y, mk.pose.position.z] == p.tolist()
        assert [o.x, o.y, o.z, o.w] == q.tolist()
    trail = [mk for mk in m.markers if mk.ns == 'trails'][0]
    assert [trail.points[0].x, trail.points[0].y, trail.points[0].z] == pos[0].tolist()
    assert [mk for mk in m.markers if mk.ns == 'target'][0].pose.position.z == 3.0
    assert [p.z for p in [mk for mk in m.markers if mk.ns == 'barrier'][0].points] == [0.0, 1.0, 2.0, 0.0]


def test_the_realtime_3d_record_holds_states_between_stamps():
    rec = NaturalRecorder(['a', 'b'], 4, 0.1, realtime=True)
    state = np.arange(24, dtype=float).reshape(2, 12)
    rec.record_realtime([0, 1], [0, 0], state, np.zeros((2, 2)), 0.0, np.zeros(2, bool))
    rec.record_realtime([0], [2], state[:1] + 1.0, np.array([[0.1, 0.2]]), 0.5, np.array([True, False]))
    got = rec.trajectory()
    assert got.dim == 3 and np.isfinite(got.r).all()
    np.testing.assert_array_equal(got.r[1, 0], state[0, :3])                # held from t = 0
    np.testing.assert_array_equal(got.r[2:, 0], np.tile(state[0, :3] + 1.0, (3, 1)))
    np.testing.assert_array_equal(got.z[4, 1], state[1, 9:12])
    assert got.u[1, 0] == 0.1 and got.v[1, 0] == 0.2 and got.lam.tolist() == [0.0, 0.0, 0.5, 0.5, 0.5]
