"""The robot world's timing, pure: the lockstep hold (it waits for the command of every robot
whose agent is alive in the step, ignores stale stamps, advances by dt·L/v0) and the realtime
pacer; a small fake of the physics API stands in for MuJoCo."""
import numpy as np
import pytest

from swarm_robots.timing import RealtimePacer, RobotsLockstep, TurnLimitClock, robot_summary
from swarm_robots.world_setup import chosen_rows, robots_section, start_poses


class FakeWorld:
    """What `RobotsLockstep` uses of `swarm_robots.physics.RobotWorld`, recording its calls."""

    def __init__(self):
        self.time = 0.0
        self.calls = []

    def command(self, k, v, omega):
        self.calls.append(('command', k, v, omega))

    def advance(self, seconds):
        self.calls.append(('advance', round(seconds, 12)))
        self.time += seconds


DT, SCALE = 0.05, 2.0          # L / v0 = 0.3 m / 0.15 m/s


def hold(rows=(0, 2, 4)):
    return RobotsLockstep(FakeWorld(), list(rows), DT, SCALE)


def test_hold_waits_for_every_robot_then_advances_dt_times_l_over_v0():
    h = hold()
    assert h.run() == []
    h.on_command(2, 0.0, 0.15, 0.1)
    h.on_command(0, 0.0, 0.15, -0.1)
    assert h.run() == [] and h.waiting_for() == [1] and h.world.calls == []
    h.on_command(1, 0.0, 0.15, 0.0)
    assert h.run() == [pytest.approx(DT)]
    # commands in robot order whatever the arrival order, then one advance of dt·L/v0
    assert h.world.calls == [('command', 0, 0.15, -0.1), ('command', 1, 0.15, 0.0), ('command', 2, 0.15, 0.1),
                             ('advance', DT * SCALE)]
    assert h.n == 1 and h.waiting_for() == [0, 1, 2]


def test_a_killed_agents_robot_is_not_waited_for():
    h = hold(rows=(0, 2, 4))
    alive = np.ones(6, bool)
    alive[2] = False                        # the agent of robot 1 is dead in step 0
    h.on_command(0, 0.0, 0.1, 0.0)
    h.on_command(2, 0.0, 0.1, 0.0)
    assert h.run() == []                    # the mask of step 0 is not known yet: wait for all
    h.on_step(0, alive)
    assert h.run() == [pytest.approx(DT)]
    assert [c[1] for c in h.world.calls if c[0] == 'command'] == [0, 2]
    h.on_step(1, np.ones(6, bool))          # alive again in step 1: waited for again
    h.on_command(0, DT, 0.1, 0.0)
    h.on_command(2, DT, 0.1, 0.0)
    assert h.run() == [] and h.waiting_for() == [1]


def test_a_robot_whose_agent_is_killed_in_a_step_already_sent_is_not_waited_for():
    """The world kills an agent right after it sends a step: its kill event lets the step go
    on without its command (without waiting for the hold's time-out), and every step after."""
    h = hold(rows=(0, 2, 4))
    h.on_step(0, np.ones(6, bool))                   # robot 1's agent alive in step 0 ...
    h.on_command(0, 0.0, 0.1, 0.0)
    h.on_command(2, 0.0, 0.1, 0.0)
    assert h.run() == [] and h.waiting_for() == [1]
    h.stop_awaiting(1)                                        # ... and killed before it commanded it
    assert h.run() == [pytest.approx(DT)] and h.waiting_for() == [0, 2]
    h.on_step(1, np.ones(6, bool))
    assert h.waiting_for() == [0, 2]


def test_release_leaves_out_the_robots_of_a_known_step_that_did_not_answer():
    h = hold(rows=(0, 2, 4))
    h.on_command(0, 0.0, 0.1, 0.0)
    assert h.release() == [] and not h.ready()      # step 0 not sent yet: nothing to give up on
    h.on_step(0, np.ones(6, bool))
    assert h.release() == [1, 2] and h.run() == [pytest.approx(DT)]
    assert [c[1] for c in h.world.calls if c[0] == 'command'] == [0]
    assert h.waiting_for() == [0, 1, 2]              # the next step waits for every robot again


def test_the_hold_is_overdue_from_the_steps_first_message_and_a_repeat_keeps_the_release():
    h = hold(rows=(0, 2, 4))
    assert not h.overdue(100.0, 5.0)                 # no step message yet: nothing to time out
    h.on_step(0, np.ones(6, bool), now=10.0)
    h.on_step(0, np.ones(6, bool), now=14.0)         # the world repeats it while it stalls
    assert not h.overdue(14.9, 5.0) and h.overdue(15.0, 5.0)
    h.on_command(0, 0.0, 0.1, 0.0)
    assert h.release() == [1, 2]
    h.on_step(0, np.ones(6, bool), now=16.0)         # repeated again: the released robots stay out
    assert h.run() == [pytest.approx(DT)] and not h.overdue(100.0, 5.0)


def test_stale_and_off_step_stamps_are_ignored_and_the_first_command_counts():
    h = hold(rows=(0,))
    assert h.on_command(0, 0.0, 0.1, 0.5)
    assert h.on_command(0, 0.0, 0.1, 9.9)   # a second command for the same step: the first counts
    assert h.run() == [pytest.approx(DT)]
    assert h.on_command(0, 0.0, 0.1, 0.5)               # step 0 is done: an agent's resend, no change
    assert not h.on_command(0, 0.0123, 0.1, 0.5)        # no step's time
    assert not h.on_command(0, 1000 * DT, 0.1, 0.5)     # far beyond the held step
    assert h.repeated == 1 and h.ignored == 2 and h.run() == []
    assert h.world.calls[0] == ('command', 0, 0.1, 0.5)
    h.on_step(0, np.ones(1, bool))                      # a repeated old step changes nothing
    assert 0 not in h.known and h.run() == []


def test_commands_ahead_are_kept_for_their_step_and_time_does_not_drift():
    h = hold(rows=(0,))
    h.on_command(0, DT, 0.1, 0.2)               # step 1's command before step 0's
    assert h.run() == []
    h.on_command(0, 0.0, 0.1, 0.1)
    assert h.run() == [pytest.approx(DT), pytest.approx(2 * DT)]
    for n in range(2, 1000):
        h.on_command(0, n * DT, 0.1, 0.0)
        h.run()
    assert h.world.time == pytest.approx(1000 * DT * SCALE, abs=1e-9)


class RoundingWorld(FakeWorld):
    """A physics that runs whole controller periods of 0.01 s and keeps the remainder of what
    it is asked (as `swarm_robots.physics.RobotWorld.advance` does)."""

    def __init__(self):
        super().__init__()
        self.target = 0.0

    def advance(self, seconds):
        self.target += seconds
        self.time = round(self.target / 0.01) * 0.01


def test_a_physics_that_rounds_to_its_periods_does_not_drift():
    h = RobotsLockstep(RoundingWorld(), [0], 0.05, 2.468)     # 0.1234 robot s a step
    for n in range(1000):
        h.on_command(0, n * 0.05, 0.1, 0.0)
        h.run()
    assert h.world.target == pytest.approx(1000 * 0.1234) and abs(h.world.time - 123.4) <= 0.005


def test_realtime_pacer_odometry_at_50_hz_robot_time_and_while_time_stands_still():
    p = RealtimePacer(SCALE)
    assert p.target(1.5) == 3.0
    assert p.odom_due(0.0, 100.0)
    assert not p.odom_due(0.01, 100.001)        # neither 1/50 robot s nor 1/50 wall s
    assert p.odom_due(0.021, 100.002)           # a robot period crossed
    assert not p.odom_due(0.021, 100.01)
    assert p.odom_due(0.021, 100.03)            # time stands still: every 1/50 wall s


def test_run_setup_rows_poses_and_a_scenario_without_robots(tmp_path):
    from swarm_core.robot_units import RobotUnits
    from swarm_core.scenario.loader import load
    names = [f'agent_{i}' for i in range(6)]
    assert chosen_rows(names, []) == list(range(6))
    assert chosen_rows(names, ['agent_4', 'agent_1']) == [1, 4]
    with pytest.raises(ValueError, match='no agent agent_9'):
        chosen_rows(names, ['agent_9'])
    path = tmp_path / 's.yaml'
    path.write_text('name: s\nagents: {positions: [[0, 0], [2, 1]], headings: [0.5, -1]}\nduration: 1\n')
    scn = load(str(path))
    assert start_poses(scn, [1], RobotUnits(0.3, 0.15)).tolist() == [pytest.approx([0.6, 0.3, -1.0])]
    with pytest.raises(ValueError, match='no robots: section'):
        robots_section(scn)


def test_turn_limit_clock_counts_commands_at_the_limit_until_the_controller_times_out():
    world = FakeWorld()
    world.n = 2
    w = TurnLimitClock(world, 2.84, 0.5)
    w.command(0, 0.15, -2.84)          # clipped by the agent: at the limit
    w.command(1, 0.15, 2.0)
    w.advance(0.3)
    w.command(1, 0.15, 2.84)
    w.advance(0.1)
    assert w.seconds.tolist() == pytest.approx([0.4, 0.1])
    w.advance(0.2)                     # robot 0's command is 0.4 s old: still counts
    w.advance(0.2)                     # 0.6 s old: the controller has stopped robot 0
    assert w.seconds.tolist() == pytest.approx([0.6, 0.5])
    assert w.time == pytest.approx(0.8) and world.calls[0] == ('command', 0, 0.15, -2.84)


def test_robot_summary_for_metrics():
    s = robot_summary(['agent_0', 'agent_1'], 3, [0.0, 1.0], [0.5, 1.5], SCALE)
    assert s['contacts'] == 3 and s['limit_seconds'] == {'agent_0': 0.5, 'agent_1': 1.5}
    assert s['limit_seconds_total'] == 2.0 and s['limit_model_seconds_total'] == 1.0
    assert s['turn_limit_seconds'] == {'agent_0': 0.0, 'agent_1': 1.0} and s['turn_limit_model_seconds_total'] == 0.5
