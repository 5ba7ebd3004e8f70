"""The world's lockstep barrier and trajectory record, without ROS (swarm_world.lockstep,
swarm_core.engine.trajectory): what a step needs, when it is complete, what the plan decides on,
what goes out, and faults."""
from __future__ import annotations

import numpy as np
import pytest

from swarm_core.command.plan import CommandPlan, Decided
from swarm_core.command.schedules import ConstantSteering
from swarm_core.engine.trajectory import TrajectoryRecorder, unwrap_headings
from swarm_core.faults.agents import Fault, FaultTimeline
from swarm_core.model.frenet import quaternion_from_heading
from swarm_ros.layouts import AgentStates, Step
from swarm_world.lockstep import LockstepBarrier

NAMES = ['a', 'b', 'c']
DT = 0.5


class ScriptedPlan:
    """The decisions the barrier asks for: λ per step (``lams``, 0.5 unless given), agent b the
    leader steering 0.2; ``seen`` keeps (step, positions, heard) of each call."""

    def __init__(self, lams=None):
        self.lams = lams or {}
        self.seen = []

    def __call__(self, t, pos, cos_t, sin_t, heard):
        k = int(round(t / DT))
        self.seen.append((k, pos.copy(), heard.copy()))
        return Decided(self.lams.get(k, 0.5), np.array([False, True, False]), np.array([0.0, 0.2, 0.0]),
                       np.array([-1, 0, -1]), None, [])


def make(steps=3, faults=(), comms=(), lams=None, decide=None):
    tl = FaultTimeline(list(faults), NAMES, DT)
    rec = TrajectoryRecorder(NAMES, steps, DT, theta0=np.zeros(3))
    plan = decide or ScriptedPlan(lams)
    b = LockstepBarrier(NAMES, steps, DT, tl, rec, comms_events=comms, decide=plan,
                        geometry=lambda: (np.array([5.0, 6.0]), None))
    b.plan = plan
    return b


def state(i, k, theta=0.0):
    qz, qw = quaternion_from_heading(theta)
    return (float(i), float(k), float(qz), float(qw))


def on_state(b, i, k, vals, u):
    """Agent i's state as a one-row ``/lockstep/agent_states`` (`LockstepBarrier.on_states`):
    (the reason it was refused or None, actions)."""
    why, acts = b.on_states(np.array([i]), np.array([k]), np.array([vals]).T, np.array([u]))
    assert len(why) <= 1
    return (why[0] if why else None), acts


def kinds(acts):
    return [a[0] for a in acts]


def feed_states(b, k, agents=range(3), u=0.1):
    acts = []
    for i in agents:
        reason, a = on_state(b, i, k, state(i, k), u * (i + 1))
        assert reason is None
        acts += a
    return acts


def test_a_step_waits_for_every_state_then_decides_and_goes_out():
    b = make()
    assert on_state(b, 0, 0, state(0, 0), 0.0) == (None, [])     # not started: nothing goes out
    assert b.start() == []                                          # b and c not here yet
    assert not b.complete() and list(b.missing()) == [1, 2]
    acts = feed_states(b, 0, [1, 2])
    assert kinds(acts) == ['clock', 'observe', 'step']
    assert acts[0] == ('clock', 0.0)
    k, pos, heard = b.plan.seen[-1]                                 # the plan decided on the table
    assert k == 0 and pos.tolist() == [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]] and heard.all()
    step = Step.from_cdr(acts[2][1].to_cdr())                      # as the agents read it
    assert step.n == 0 and step.lam == 0.5 and list(step.flags) == [False, True, False]
    assert list(step.steering) == [0.0, 0.2, 0.0] and list(step.target) == [5.0, 6.0]
    assert b.cur == 1 and not b.have.any()
    assert len(b.plan.seen) == 1


def test_the_plan_of_the_scenario_decides_as_the_batch_engine_does():
    """A real `CommandPlan`: its live command applies at the step decided next and comes out as
    an event with that step (what ``--replay`` reads)."""
    plan = CommandPlan(fixed_leaders={1: ConstantSteering(0.3)})
    pending = [dict(command='lambda', value=1.0, ramp=0.0, shape='step')]

    def decide(t, pos, cos_t, sin_t, heard):
        commands = list(pending) if t == DT else []
        return plan.decide(t, pos, cos_t, sin_t, heard=heard, commands=commands)
    b = make(decide=decide)
    b.start()
    assert kinds(feed_states(b, 0)) == ['clock', 'observe', 'step']
    acts = feed_states(b, 1)
    assert kinds(acts) == ['clock', 'observe', 'event', 'step']
    ev = acts[2][1]
    assert (ev['kind'], ev['command'], ev['value'], ev['step']) == ('command', 'lambda', 1.0, 1)
    step = acts[3][1]
    assert step.lam == 1.0 and step.flags.tolist() == [False, True, False] and step.steering[1] == 0.3


def test_states_of_another_step_are_refused_and_named():
    b = make()
    b.start()
    reason, acts = on_state(b, 2, 1, state(2, 1), 0.0)
    assert acts == [] and reason == "state of 'c' for step 1 while the world is at step 0"
    assert not b.have[2]


def test_the_run_records_each_step_and_finishes_after_the_last_u():
    b = make(steps=2, lams={k: 0.25 * k for k in range(3)})
    b.start()
    for k in range(3):
        feed_states(b, k, u=0.1 * (k + 1))
    acts = feed_states(b, 3, u=0.9)
    assert kinds(acts) == ['finish'] and b.done
    tr = b.rec.trajectory()
    assert tr.r.shape == (3, 3, 2) and np.allclose(tr.r[:, :, 1], [[0] * 3, [1] * 3, [2] * 3])
    assert list(tr.lam) == [0.0, 0.25, 0.5]
    # u_k comes with the states of step k+1: agent i sent u·(i+1) with the step-(k+1) state
    assert np.allclose(tr.u[:, 0], [0.2, 0.3, 0.9])
    assert np.allclose(tr.u[:, 2], [0.6, 0.9, 2.7])
    assert tr.leader[:, 1].all() and not tr.leader[:, 0].any()


def test_rows_done_counts_rows_whose_u_is_known():
    b = make(steps=3)
    b.start()
    feed_states(b, 0)
    assert b.rows_done() == 0            # u_0 comes with the states of step 1
    feed_states(b, 1)
    assert b.rows_done() == 1


def test_a_kill_signals_the_agent_leaves_it_out_and_its_rows_are_nan():
    b = make(steps=3, faults=[Fault(1.0, 'kill', 'b')])        # t = 1.0: step 2
    b.start()
    for k in range(2):
        acts = feed_states(b, k)
    assert kinds(acts) == ['clock', 'observe', 'step', 'event', 'signal']
    assert acts[3][1]['kind'] == 'kill' and acts[3][1]['agent'] == 'b'
    assert acts[4] == ('signal', 1, 'kill')
    acts = feed_states(b, 2, [0, 2])              # b is not awaited
    assert kinds(acts) == ['clock', 'observe', 'step']
    assert list(acts[2][1].alive) == [True, False, True]
    assert b.plan.seen[-1][2].tolist() == [True, False, True]      # the plan hears a and c only
    tr = b.rec.trajectory()
    assert np.isnan(tr.u[1:, 1]).all() and np.isnan(tr.r[2:, 1]).all()


def test_a_freeze_stops_the_agent_once_its_state_is_held_and_resumes_it():
    b = make(steps=6, faults=[Fault(1.0, 'freeze', 'c', 1.0)])    # steps 2..4
    b.start()
    for k in range(2):
        acts = feed_states(b, k)
    assert kinds(acts) == ['clock', 'observe', 'step', 'event']     # no stop yet: its step-2 state not held
    assert 2 in b.stop_pending
    acts = feed_states(b, 2, [0, 1])                  # the step completes without c
    assert kinds(acts) == ['clock', 'observe', 'step']
    reason, acts = on_state(b, 2, 2, state(2, 2), 0.7)  # c's state of its freeze step
    assert reason is None and acts == [('signal', 2, 'stop')]
    acts = feed_states(b, 3, [0, 1])
    assert kinds(acts) == ['clock', 'observe', 'step', 'event', 'signal'] and acts[4] == ('signal', 2, 'cont')
    # step 3 is observed over its own table (a, b): c, resumed at step 4, has no state at 3 (its
    # NaN row once went to the metrics' k-d tree, which raised, and step 3 was never sent)
    assert acts[1][:2] == ('observe', 3) and acts[1][2].tolist() == [0, 1]
    assert np.isfinite(b.rec.r[3, acts[1][2]]).all() and np.isnan(b.rec.r[3, 2]).all()
    assert b.have[2]                                  # resumes with the held state
    feed_states(b, 4, [0, 1])
    tr = b.rec.trajectory()
    assert np.allclose(tr.r[4, 2], [2.0, 2.0]) and tr.u[1, 2] == pytest.approx(0.7)
    assert np.allclose(tr.r[2:4, 2], [[2.0, 2.0]] * 2)   # held at its freeze-step state


def test_a_live_fault_applies_at_the_next_step():
    b = make(steps=4)
    b.start()
    feed_states(b, 0, [0, 1])
    assert b.add_fault(Fault(0.0, 'kill', 'a', source='live')) == 1
    acts = feed_states(b, 0, [2])
    assert ('signal', 0, 'kill') in acts


def test_drop_missing_loses_the_silent_agents_and_goes_on():
    b = make()
    b.start()
    feed_states(b, 0, [0, 2])
    acts = b.drop_missing()
    assert kinds(acts) == ['event', 'clock', 'observe', 'step']
    assert acts[0][1] == dict(t=0.0, step=0, kind='lost', agent='b')
    assert not b.faults.alive[1]


def test_scheduled_radio_events_go_out_with_their_step():
    b = make(comms=[(1, {'kind': 'drop', 'loss': 0.5})])
    b.start()
    assert kinds(feed_states(b, 0)) == ['clock', 'observe', 'step']
    acts = feed_states(b, 1)
    assert acts[2] == ('comms', 1, {'kind': 'drop', 'loss': 0.5}) and kinds(acts) == ['clock', 'observe', 'comms',
                                                                                       'step']


def test_realtime_record_holds_states_between_stamps():
    rec = TrajectoryRecorder(['a'], 3, DT, theta0=np.zeros(1), realtime=True)
    rec.record_realtime(0, 0, state(0, 0), 0.0, 0.0, np.array([False]))
    rec.record_realtime(0, 2, (3.0, 4.0, *quaternion_from_heading(0.5)), 0.3, 1.0, np.array([True]))
    tr = rec.trajectory()
    assert np.allclose(tr.r[:, 0], [[0, 0], [0, 0], [3, 4], [3, 4]])
    assert list(tr.lam) == [0.0, 0.0, 1.0, 1.0] and list(tr.leader[:, 0]) == [False, False, True, True]
    assert tr.u[1, 0] == 0.3 and np.allclose(tr.theta[2:, 0], 0.5)


def test_headings_unwrap_in_time_from_the_initial_heading():
    th = np.array([[3.1, 0.0], [-3.1, np.nan], [-3.0, 0.1]])
    out = unwrap_headings(th, np.array([3.1 + 2 * np.pi, 0.0]))
    assert out[1, 0] == pytest.approx(2 * np.pi - 3.1 + 2 * np.pi)
    assert out[0, 0] == pytest.approx(3.1 + 2 * np.pi)
    assert np.isnan(out[1, 1]) and out[2, 1] == pytest.approx(0.1)


def feed_batch(b, k, agents=range(3), u=0.1):
    """`feed_states` as one agent process's /lockstep/agent_states (packed and unpacked)."""
    agents = list(agents)
    rows = np.array([(i, k, *state(i, k), u * (i + 1)) for i in agents]).reshape(-1, 7).T
    m = AgentStates.from_cdr(AgentStates(7.0, rows[0], rows[1], rows[2:6], rows[6]).to_cdr())
    assert m.tag == 7.0 and list(m.index) == agents
    late, acts = b.on_states(m.index, m.step, m.pose, m.u)
    assert late == []
    return acts


@pytest.mark.parametrize('feed', [feed_states, feed_batch])
def test_states_in_one_message_per_process_make_the_same_run(feed):
    """A freeze, a kill and a repeat, fed one state at a time and as batches: the same actions
    and the same record, bit for bit."""
    runs = []
    for f in (feed_states, feed):
        b = make(steps=6, faults=[Fault(1.0, 'freeze', 'c', 1.0), Fault(2.5, 'kill', 'a')])
        out = [b.start()]
        for k in range(7):
            alive = [i for i in range(3) if b.faults.alive[i] and not b.have[i]]   # a resumed c is held
            out.append(f(b, k, alive))
            if k == 2:                             # c's state of its freeze step, late
                out.append(f(b, 2, [2], u=0.7 / 3))
            if k == 4 and f is feed_batch:         # a repeat of step 4 (stall recovery) is ignored
                assert b.on_states(np.array([1]), np.array([3]), np.array([state(1, 3)]).T, np.array([0.2])) == ([], [])
        runs.append((b.rec.trajectory(), [kinds(a) for a in out]))
    (t1, k1), (t2, k2) = runs
    assert k1 == k2
    assert np.array_equal(t1.r, t2.r, equal_nan=True) and np.array_equal(t1.u, t2.u, equal_nan=True)


def test_a_batch_state_of_a_later_step_is_named():
    b = make()
    b.start()
    late, acts = b.on_states(np.array([0, 1]), np.array([0, 2]), np.array([state(0, 0), state(1, 2)]).T,
                             np.array([0.0, 0.0]))
    assert late == ["state of 'b' for step 2 while the world is at step 0"] and acts == []
    assert b.have.tolist() == [True, False, False]


def test_when_every_agent_is_dropped_the_run_fails_instead_of_waiting_for_nobody():
    b = make(steps=4)
    b.start()
    feed_states(b, 0)
    acts = b.drop_missing()                       # no state of step 1 from anyone
    assert kinds(acts) == ['event', 'event', 'event', 'fail'] and b.done
    assert acts[-1][1] == ('step 1: no state from a, b, c (dropped): every agent is lost or killed: '
                           'no agent is left, the run ends here')
    assert b.rows_done() == 1                     # step 0 whole (u_0 unknown: lost), kept as a partial run
    assert np.isnan(b.rec.trajectory().u[0]).all()
    assert feed_states(b, 1) == []                # nothing goes out any more


def test_the_last_agents_dropped_after_others_were_killed_end_the_run():
    b = make(steps=4, faults=[Fault(0.5, 'kill', 'a')])        # step 1
    b.start()
    assert kinds(feed_states(b, 0)) == ['clock', 'observe', 'step', 'event', 'signal'] and not b.done
    acts = b.drop_missing()
    assert kinds(acts) == ['event', 'event', 'fail'] and 'no state from b, c (dropped)' in acts[-1][1]


def test_a_run_whose_agents_are_all_killed_ends_at_that_step():
    b = make(steps=4, faults=[Fault(1.0, 'kill', nm) for nm in NAMES])    # step 2
    b.start()
    feed_states(b, 0)
    acts = feed_states(b, 1)
    assert kinds(acts) == ['clock', 'observe', 'step'] + ['event', 'signal'] * 3 + ['fail'] and b.done
    assert acts[-1][1].startswith('step 2: every agent is killed or lost')
    assert b.rows_done() == 2


def test_while_every_agent_is_frozen_the_steps_go_on_without_states():
    b = make(steps=6, faults=[Fault(1.0, 'freeze', nm, 1.0) for nm in NAMES])    # steps 2..3, back at 4
    b.start()
    feed_states(b, 0)
    acts = feed_states(b, 1)                           # nobody to wait for at steps 2 and 3
    assert kinds(acts).count('step') == 3 and b.cur == 4     # steps 1, 2 and 3; at 4 they are back
    assert not b.done and [k for k, _, _ in b.plan.seen] == [0, 1, 2, 3]


# ------------------------------------------------------------------ robots of the MuJoCo world

def test_a_robot_agents_state_joins_its_robots_pose_with_its_own_u():
    """Agent b is on a MuJoCo robot: its answer gives u (its pose there is not taken), the robot
    world's report gives the pose; the state goes to the barrier once both parts of a step came,
    in either order, and the others pass as they are."""
    from swarm_world.lockstep import RobotPoseJoin
    join = RobotPoseJoin([1], 3)
    rows, ks, vals, us = join.from_agents([0, 1], [4, 4], np.array([state(0, 4), state(9, 9)]).T, [0.1, 0.2])
    assert rows.tolist() == [0] and ks.tolist() == [4] and vals[:, 0].tolist() == list(state(0, 4))
    rows, ks, vals, us = join.from_robots(4, [1], np.array([state(1, 4, 0.3)]).T)
    assert (rows.tolist(), ks.tolist(), us.tolist()) == ([1], [4], [0.2])
    assert vals[:, 0].tolist() == list(state(1, 4, 0.3))
    assert join.from_robots(5, [1], np.array([state(1, 5)]).T)[0].size == 0      # the pose first
    rows, ks, vals, us = join.from_agents([1], [5], np.array([state(9, 9)]).T, [0.5])
    assert (rows.tolist(), ks.tolist(), us.tolist(), vals[:, 0].tolist()) == ([1], [5], [0.5], list(state(1, 5)))
    # parts of steps before a state handed on are dropped; a kept part waits for its twin
    join.from_robots(6, [1], np.array([state(1, 6)]).T)
    join.from_robots(7, [1], np.array([state(1, 7)]).T)
    assert join.from_agents([1], [7], np.array([state(9, 9)]).T, [0.7])[1].tolist() == [7]
    assert join.poses[1] == {} and join.us[1] == {}
    with pytest.raises(ValueError, match=r'rows \[0\].*robot_poses'):
        join.from_robots(8, [0, 1], np.zeros((4, 2)))


def test_a_dead_robot_agents_reports_are_kept_bounded(monkeypatch):
    from swarm_world.lockstep import RobotPoseJoin
    monkeypatch.setattr(RobotPoseJoin, 'KEPT', 5)
    join = RobotPoseJoin([0], 3)
    for k in range(20):
        join.from_robots(k, [0], np.zeros((4, 1)))
    assert sorted(join.poses[0]) == [15, 16, 17, 18, 19]


def test_a_run_with_a_robot_agent_records_its_robots_poses():
    """The barrier and the join together: b's states are its robot's poses, with its own u."""
    from swarm_world.lockstep import RobotPoseJoin
    b, join = make(steps=2), RobotPoseJoin([1], 3)
    b.start()
    for k in range(4):
        acts = b.on_states(*join.from_agents([0, 1, 2], [k] * 3, np.array([state(i, k) for i in (0, 7, 2)]).T,
                                             [0.1, 0.2 * k, 0.3]))[1]
        assert 'step' not in kinds(acts)                            # b's pose is not here yet
        acts = b.on_states(*join.from_robots(k, [1], np.array([state(1, 2 * k)]).T))[1]
        assert kinds(acts)[:1] == (['finish'] if k == 3 else ['clock'])
    tr = b.rec.trajectory()
    assert tr.r[:, 1].tolist() == [[1.0, 0.0], [1.0, 2.0], [1.0, 4.0]]
    assert tr.u[:, 1].tolist() == pytest.approx([0.2, 0.4, 0.6])


def test_the_join_says_when_a_robot_agents_pose_is_what_is_missing():
    from swarm_world.lockstep import RobotPoseJoin
    join = RobotPoseJoin([1], 3)
    join.from_agents([1], [2], np.zeros((4, 1)), [0.5])
    assert join.awaits_pose(1, 2) and not join.awaits_pose(1, 3) and not join.awaits_pose(0, 2)
    join.from_robots(2, [1], np.zeros((4, 1)))
    assert not join.awaits_pose(1, 2)
