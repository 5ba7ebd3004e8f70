"""The paper's laws lifted to 3D (no ROS): worked numbers, the planar reduction, gauge invariance,
blend, and the refusal of a law that returns the wrong shape."""
import numpy as np
import pytest

from swarm_core.laws import Blend, Law, LawError, make_law, natural_control, swarm_control
from swarm_core.model.frenet import heading_frame
from swarm_core.model.natural import initial_frames

KINDS = ('global', 'local', 'leader_following', 'homotopy', 'target')


def test_two_agents_match_the_worked_numbers():
    law = make_law({'kind': 'global', 'eta': 0.3, 'alpha': 0.5, 'mu': 0.2, 'r0': 1.0})
    pos = np.array([[0.0, 0, 0], [1, 2, 0.5]])
    frames = initial_frames([[1.0, 0, 0], [0, 0.6, 0.8]])
    np.testing.assert_allclose(frames[1][1], [-1, 0, 0], atol=1e-15)
    uv = natural_control(pos, frames, np.arange(2), law)
    np.testing.assert_allclose(uv[:, 0], [0.359019441334464, 0.068081149238660], atol=1e-14)
    np.testing.assert_allclose(uv[:, 1], [0.219754860333616, 0.348505494010259], atol=1e-14)


def _planar_table(rng, n):
    pos = rng.uniform(-5, 5, (n, 2))
    pos[2] = pos[4]                                         # coincident agents add 0
    theta = rng.uniform(-3, 3, n)
    c, s = heading_frame(theta)
    frames = initial_frames(np.stack([c, s, np.zeros(n)], axis=1))
    return pos, c, s, np.concatenate([pos, np.zeros((n, 1))], axis=1), frames


@pytest.mark.parametrize('kind', KINDS)
@pytest.mark.parametrize('lam', (0.0, 0.37, 1.0))
def test_a_planar_table_gives_the_planar_u_and_v_zero(kind, lam):
    rng = np.random.default_rng(5)
    n = 9
    pos, c, s, pos3, frames = _planar_table(rng, n)
    law = make_law({'kind': kind, 'q0': 0.05}).with_parameters(target_gain=0.05, barrier_gain=5.0)
    leaders = np.zeros(n, bool)
    leaders[[1, 6]] = True
    steer = rng.uniform(-0.02, 0.02, n)
    target, barrier = np.array([3.0, -1.0]), np.array([[1.0, 1], [2, 0], [1, -1], [0, 0]])
    u = swarm_control(pos, c, s, np.arange(n), law, lambda_=lam, is_leader=leaders, steering=steer,
                      target=target, barrier=barrier)
    uv = natural_control(pos3, frames, np.arange(n), law, lambda_=lam, is_leader=leaders,
                         steering=np.stack([steer, np.zeros(n)], axis=1), target=np.append(target, 0.0),
                         barrier=np.concatenate([barrier, np.zeros((4, 1))], axis=1))
    np.testing.assert_allclose(uv[:, 0], u, atol=1e-13, rtol=1e-12)
    assert np.all(uv[:, 1] == 0.0)
    one = natural_control(pos3, frames, np.array([6]), law, lambda_=lam, is_leader=leaders,
                          steering=np.array([[steer[6], 0.0]]), target=np.append(target, 0.0))
    alone = natural_control(pos3, frames, np.arange(n), law, lambda_=lam, is_leader=leaders,
                            steering=np.stack([steer, np.zeros(n)], axis=1), target=np.append(target, 0.0))
    np.testing.assert_array_equal(one[0], alone[6])         # one receiver alone: the same numbers


def test_rotating_the_normals_about_x_rotates_u_v_and_keeps_the_steering():
    rng = np.random.default_rng(7)
    n = 7
    pos = rng.uniform(-4, 4, (n, 3))
    x, y, z = initial_frames(rng.normal(size=(n, 3)))
    law = make_law({'kind': 'homotopy', 'q0': 0.3}).with_parameters(target_gain=0.05)
    leaders = np.zeros(n, bool)
    leaders[3] = True
    kw = dict(lambda_=0.6, is_leader=leaders, target=np.array([10.0, 2, -3]))
    uv = natural_control(pos, (x, y, z), np.arange(n), law, **kw)
    phi = rng.uniform(-3, 3, n)[:, None]
    y2, z2 = np.cos(phi) * y + np.sin(phi) * z, -np.sin(phi) * y + np.cos(phi) * z
    uv2 = natural_control(pos, (x, y2, z2), np.arange(n), law, **kw)
    turn, turn2 = uv[:, :1] * y + uv[:, 1:] * z, uv2[:, :1] * y2 + uv2[:, 1:] * z2
    followers = ~leaders                                    # a leader's own program is in its (y, z)
    np.testing.assert_allclose(turn2[followers], turn[followers], atol=1e-15)


def test_a_blend_in_3d_is_its_two_laws_by_lambda():
    rng = np.random.default_rng(8)
    pos = rng.uniform(-4, 4, (5, 3))
    frames = initial_frames(rng.normal(size=(5, 3)))
    a, b = make_law({'kind': 'global'}), make_law({'kind': 'local', 'cutoff_radius': 3.0})
    blend = Blend(a, b)
    assert blend.dims == (2, 3)
    got = natural_control(pos, frames, np.arange(5), blend, lambda_=0.25)
    want = 0.75 * natural_control(pos, frames, np.arange(5), a) + 0.25 * natural_control(pos, frames, np.arange(5), b)
    np.testing.assert_allclose(got, want, atol=1e-16)
    assert Blend(a, make_law({'kind': 'spl_parallel'})).dims == (2,)


def test_a_law_of_its_own_in_3d_reads_the_frames_and_its_shape_is_checked():
    class Climb(Law):
        """Turn toward +z."""
        kind = 'climb'
        dims = (2, 3)

        def control(self, view):
            return np.stack([view.y[view.receivers, 2], view.z[view.receivers, 2]], axis=1) * 0.1

    class Wrong(Climb):
        def control(self, view):
            return np.zeros(view.receivers.size)

    frames = initial_frames([[1.0, 0, 0], [0, 1.0, 0]])
    uv = natural_control(np.zeros((2, 3)), frames, np.arange(2), Climb())
    np.testing.assert_allclose(uv, [[0, 0.1], [0, 0.1]])
    with pytest.raises(LawError, match=r'returned shape \(2,\), want \(2, 2\)'):
        natural_control(np.zeros((2, 3)), frames, np.arange(2), Wrong())
