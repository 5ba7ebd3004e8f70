"""A 3D run's lockstep without DDS (`swarm_agent.natural_core`, `swarm_world.natural`): the
world's barrier and record, and the agents in containers of K, talking through the packed
messages' bytes (`NaturalStep`, `NaturalAgentStates`), write what `swarm simulate` writes, bit
for bit (r, x, y, z, u, v, λ, leaders), for every K, also with a radio model and faults (each
agent hears through its own radio); the quaternion round trip of a frame."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from swarm_agent.natural_core import NaturalAgentCore, NaturalContainerCore
from swarm_core.engine.reference import simulate
from swarm_core.laws import Law, param
from swarm_core.model.natural import frame_from_quaternion_3d, initial_frames, quaternion_from_frame
from swarm_core.radio import CommModel
from swarm_core.scenario.loader import load
from swarm_ros.layouts import NaturalAgentStates, NaturalStep
from swarm_world.natural import NaturalBarrier, NaturalRecorder

SHIPPED = Path(__file__).resolve().parents[2] / 'src/swarm_core/swarm_core/scenarios/homotopy_3d.yaml'


def short_3d(path, duration=20.0, leaders_at=2, **more):
    """homotopy_3d shortened: the leaders chosen at t = 2, λ up from t = 4 (τ = 1)."""
    doc = yaml.safe_load(SHIPPED.read_text())
    doc.update(duration=duration, **{'lambda': {'kind': 'tanh_window', 'rise_at': 4, 'fall_at': 1000, 'tau': 1}})
    doc['leaders']['at'] = leaders_at
    doc.pop('expect', None)
    doc.update(more)
    Path(path).write_text(yaml.safe_dump(doc, sort_keys=False))
    return Path(path)


def lockstep(scn, per, faults=False):
    """The world's barrier and the agents' containers of ``per`` agents, the messages as bytes;
    each agent with the scenario's radio model if it has one (as an agent node attaches it).
    ``faults``: agents leave the table and come back (the world's signals are left out)."""
    n = len(scn.names)
    noise = (scn.spec.noise.position, scn.spec.noise.heading)
    cores = [NaturalAgentCore(i, n, scn.pos0[i], np.concatenate([f[i] for f in scn.frames0]), scn.law, scn.dt,
                              noise, scn.noise_rng(i)) for i in range(n)]
    for c in cores if scn.comm_model() is not None else ():
        c.attach_comms(CommModel.from_config(scn.comms_config(), scn.names, scn.dt, scn.seed))
    boxes = [NaturalContainerCore(cores[i:i + per]) for i in range(0, n, per)]
    rec = NaturalRecorder(scn.names, scn.steps, scn.dt)
    plan = scn.command_plan()
    barrier = NaturalBarrier(scn.names, scn.steps, scn.dt, scn.fault_timeline(), rec, ground=scn.ground,
                             geometry=lambda: (scn.target, scn.barrier),
                             decide=lambda t, p, c, s, heard: plan.decide(t, p, c, s, heard=heard))
    answers = [NaturalAgentStates.from_cdr(b.bank.message(1.0, b.rows, np.arange(len(b.cores))).to_cdr('r'), 'r')
               for b in boxes]
    acts = barrier.start()
    for m in answers:
        acts += barrier.on_states(m.index, m.step, m.state, m.uv)[1]
    while True:
        steps = [a[1] for a in acts if a[0] == 'step']
        if any(a[0] == 'finish' for a in acts):
            return rec.trajectory()
        assert len(steps) == 1, acts
        s = NaturalStep.from_cdr(steps[0].to_cdr('r'), 'r')
        acts = []
        for b in boxes:
            moved, repeat, rules, nan = b.step_rows(s)
            assert not nan and not repeat.size and all(kind in ('silent', 'back') for _, kind, _ in rules), rules
            assert faults or not rules and moved.size == len(b.cores)
            if not moved.size:
                continue
            m = NaturalAgentStates.from_cdr(b.bank.message(1.0, b.rows[moved], moved).to_cdr('r'), 'r')
            acts += barrier.on_states(m.index, m.step, m.state, m.uv)[1]


@pytest.mark.parametrize('per', [1, 2, 3, 6])
def test_3d_lockstep_containers_equal_simulate(per, tmp_path):
    scn = load(str(short_3d(tmp_path / 'h3.yaml')))
    got, ref = lockstep(scn, per), simulate(scn)
    for key in ('r', 'x', 'y', 'z', 'u', 'v', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    assert ref.leader.any() and ref.lam.max() > 0.5 and np.abs(ref.v).max() > 0


def test_3d_lockstep_with_noise_equals_simulate(tmp_path):
    """Noise (each agent's own stream: r and two turn angles) and Gram-Schmidt at step 100."""
    scn = load(str(short_3d(tmp_path / 'h3n.yaml', duration=12.0, noise={'position': 0.001, 'heading': 0.002})))
    got, ref = lockstep(scn, 3), simulate(scn)
    for key in ('r', 'x', 'y', 'z', 'u', 'v'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)


#: a lossy, delayed radio with a range, one worse link and a partition from t = 5 to 8
RADIO = {'loss': 0.3, 'latency': 0.1, 'jitter': 0.2, 'timeout': 0.6, 'radio_range': 5.0,
         'links': [{'sender': 'agent_0', 'receiver': 'agent_3', 'loss': 0.9}],
         'events': [{'at': 5.0, 'partition': [['agent_0', 'agent_1', 'agent_2']]}, {'at': 8.0, 'partition': []}]}
#: a frozen follower and a killed agent
FAULTS = [{'at': 3, 'freeze': 'agent_4', 'for': 2}, {'at': 6, 'kill': 'agent_2'}]


def radio_3d(path, duration=12.0, **more):
    """`short_3d` over `RADIO` with `FAULTS`: the radio mattered (a perfect one flies otherwise)."""
    return load(str(short_3d(path, duration=duration, comms=RADIO, faults=FAULTS, **more)))


@pytest.mark.parametrize('per', [1, 3, 6])
def test_3d_containers_with_a_radio_and_faults_equal_simulate(per, tmp_path):
    """Each agent hears the step's table (r, x, y, z and the (u, v) each sender held) through its
    own radio and takes (u, v) from its own beliefs: r, x, y, z, λ and the leaders exactly, u and
    v where both know them (a killed agent's last (u, v) never reaches the world)."""
    scn = radio_3d(tmp_path / 'h3r.yaml')
    got, ref = lockstep(scn, per, faults=True), simulate(scn)
    for key in ('r', 'x', 'y', 'z', 'lam', 'leader'):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    for key in ('u', 'v'):
        a, b = getattr(got, key), getattr(ref, key)
        both = np.isfinite(a) & np.isfinite(b)
        assert np.isnan(a[np.isnan(b)]).all() and both.mean() > 0.85
        np.testing.assert_array_equal(a[both], b[both], err_msg=key)
    kinds = [e['kind'] for e in ref.meta['events']]
    assert 'kill' in kinds and 'freeze' in kinds and ref.leader.any() and ref.lam.max() > 0.5
    assert 0.4 < ref.meta['comms']['delivered_fraction'] < 0.8
    doc = yaml.safe_load(Path(scn.source).read_text())
    doc.pop('comms')
    (tmp_path / 'perfect.yaml').write_text(yaml.safe_dump(doc))
    perfect = simulate(load(str(tmp_path / 'perfect.yaml')))
    assert np.nanmax(np.abs(perfect.r - ref.r)) > 1e-3         # the radio mattered


def test_the_quaternion_of_a_frame_round_trips():
    rng = np.random.default_rng(3)
    x, y, z = initial_frames(rng.normal(size=(500, 3)))
    X, Y, Z = frame_from_quaternion_3d(*quaternion_from_frame(x, y, z))
    for a, b in ((X, x), (Y, y), (Z, z)):
        np.testing.assert_allclose(a, b, atol=1e-14)
    th = rng.uniform(-np.pi, np.pi, 50)                       # planar: (0, 0, sin θ/2, cos θ/2) up to sign
    c, s = np.cos(th), np.sin(th)
    qx, qy, qz, qw = quaternion_from_frame(np.stack([c, s, 0 * th], 1), np.stack([-s, c, 0 * th], 1),
                                           np.tile([0.0, 0.0, 1.0], (50, 1)))
    sign = np.sign(np.cos(th / 2))
    np.testing.assert_allclose(np.stack([qx, qy, qz, qw]), np.stack([0 * th, 0 * th, sign * np.sin(th / 2),
                                                                      sign * np.cos(th / 2)]), atol=1e-15)


class Picky3D(Law):
    """Climbs by gain; raises above gain 5 once it has neighbours (on its own it never does)."""

    dims = (2, 3)
    gain = param(1.0, lo=0.0, hi=10.0)

    def control(self, view):
        if self.gain > 5 and len(view.pos) > 1:
            raise ValueError(f'gain {self.gain:g} with neighbours')
        return np.full((view.receivers.size, 2), 0.01 * self.gain)


@pytest.mark.parametrize('loss', [0.0, 1.0])
def test_a_set_is_tried_on_the_beliefs_of_a_3d_agent_with_a_radio(loss):
    """A live law set is tried on what the agent's radio delivered at its last step: with the
    others believed it raises there (refused in one line); when its radio lost them all it
    does not; nothing of the agent changes."""
    from types import SimpleNamespace

    from swarm_core.command.plan import law_with
    n, law = 3, Picky3D()
    x, y, z = initial_frames(np.eye(3))
    pos = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [-0.5, 1.0, 0.3]])
    cores = [NaturalAgentCore(i, n, pos[i], np.concatenate([x[i], y[i], z[i]]), law, 0.1) for i in range(n)]
    for c in cores:
        c.attach_comms(CommModel.from_config(dict(loss=loss), [f'a{i}' for i in range(n)], 0.1, 0))
    state = np.stack([pos, x, y, z])
    s = SimpleNamespace(n=0, t=0.0, lam=0.3, flags=np.zeros(n, bool), steering=np.zeros((n, 2)), state=state,
                        uv=np.zeros((n, 2)), alive=np.ones(n, bool), target=None, barrier=None, ground=None,
                        rendezvous=None, x=state[0, :, 0])
    box = NaturalContainerCore(cores)
    assert [kind for _, kind, _ in box.on_step(s)] == ['moved'] * n
    for c in cores:
        before = [a.copy() for a in c.row] + [c.states.u.copy(), c.step]
        why = c.trial(law_with(law, {'gain': 6.0}))
        assert (why is None) == (loss == 1.0), why
        if why is not None:
            assert 'gain 6 with neighbours' in why and '\n' not in why
        assert c.trial(law_with(law, {'gain': 4.0})) is None
        after = [a.copy() for a in c.row] + [c.states.u.copy(), c.step]
        for a, b in zip(before, after):
            np.testing.assert_array_equal(a, b)
