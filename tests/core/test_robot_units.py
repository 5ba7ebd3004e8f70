"""The map from model units to a robot's, ω saturation, the robot agent's safety guard and
``swarm run --robots`` (pure: no ROS)."""
import math

import pytest

from swarm_core.robot_spec import RobotsSpec
from swarm_core.robot_units import RateLimit, RobotUnits, SafetyGuard, wrap_near


def test_command_is_v0_and_v0_u_over_L_and_counts_clipping():
    units = RobotUnits(length_scale=0.3, cruise_speed=0.15, max_angular=2.84)
    v, w, clipped = units.command(1.0)
    assert (v, w, clipped) == (0.15, pytest.approx(0.5), False)
    v, w, clipped = units.command(-10.0)          # 0.15·10/0.3 = 5 rad/s > 2.84
    assert (w, clipped) == (-2.84, True)
    units.command(float('nan'))                   # straight on, not a clip
    assert (units.commands, units.saturated) == (3, 1)
    assert units.saturated_fraction == pytest.approx(1 / 3)
    assert units.saturates([5.0, 6.0]).tolist() == [False, True]   # 5 → 2.5 rad/s, 6 → 3.0


def test_time_and_pose_scale():
    units = RobotUnits(0.3, 0.15)
    assert units.robot_time(10.0) == pytest.approx(20.0)            # τ·L/v0
    assert units.model_time(units.robot_time(7.0)) == pytest.approx(7.0)
    assert units.to_model(0.6, -0.3, 1.0) == pytest.approx((2.0, -1.0, 1.0))
    # odom frame: the robot started at (1 m, 2 m) facing +y; 0.3 m straight ahead in its odom frame
    start = units.start_pose(1.0 / 0.3, 2.0 / 0.3, math.pi / 2)
    x, y, yaw = units.to_model(0.3, 0.0, 0.0, start=start)
    assert (x, y, yaw) == pytest.approx((1.0 / 0.3, 2.3 / 0.3, math.pi / 2))
    assert wrap_near(-3.0, 2 * math.pi + 3.0) == pytest.approx(2 * math.pi + 2 * math.pi - 3.0)


def test_units_refuse_nonsense():
    with pytest.raises(ValueError, match='length_scale'):
        RobotUnits(0.0, 0.1)
    with pytest.raises(ValueError, match='cruise_speed'):
        RobotUnits(0.3, float('nan'))


def test_guard_stops_on_stale_odometry_and_resumes():
    g = SafetyGuard(max_speed=0.2, odom_timeout=0.5, neighbour_timeout=2.0, needs_neighbours=False)
    assert g.decide(0.0) == ('stop', 'no odometry yet')
    assert g.decide(0.1) is None                        # said once
    assert g.odometry(0.2, 0.0, 0.0, 0.0) is None
    assert g.decide(0.3) == ('resume', '')
    assert g.decide(0.69) is None                       # 0.49 s old: fresh
    kind, why = g.decide(0.71)
    assert kind == 'stop' and 'odometry 0.51 s old' in why
    assert g.odometry(0.8, 0.05, 0.0, 0.0) is None
    assert g.decide(0.8) == ('resume', '')
    assert g.decide(0.9, paused=True) == ('stop', 'paused')


def test_guard_stops_without_a_neighbour_in_range():
    g = SafetyGuard(max_speed=0.2, neighbour_timeout=2.0, start=0.0)
    g.odometry(1.8, 0.0, 0.0, 0.0)
    assert g.decide(1.9) == ('resume', '')              # the first call says it; the start is a grace period
    g.odometry(2.0, 0.0, 0.0, 0.0)
    kind, why = g.decide(2.1)
    assert kind == 'stop' and 'no neighbour in radio range for 2.1 s' in why
    g.neighbour(2.2)
    assert g.decide(2.2) == ('resume', '')


def test_guard_rejects_bad_odometry_and_keeps_the_last_good_one():
    g = SafetyGuard(max_speed=0.2, max_jump=0.5, needs_neighbours=False)
    assert g.odometry(0.0, 1.0, 1.0, 0.0) is None
    assert 'not finite' in g.odometry(0.1, float('nan'), 1.0, 0.0)
    assert 'jumped' in g.odometry(1.0, 1.8, 1.0, 0.0)    # 0.8 m in 1 s: at most 0.2 + 0.5
    assert g.odometry(1.0, 1.65, 1.0, 0.0) is None        # 0.65 m: allowed
    assert g.rejected == 2 and g.last.x == 1.65


def test_rate_limit_says_once_per_period_and_counts_what_it_held():
    say = RateLimit(every=5.0)
    assert say('odom', 0.0) == 0
    assert say('odom', 1.0) is None and say('odom', 2.0) is None
    assert say('other', 2.0) == 0
    assert say('odom', 5.5) == 2


def test_robots_section_is_validated():
    spec = RobotsSpec.model_validate({'length_scale': 0.3, 'cruise_speed': 0.15})
    assert (spec.max_angular, spec.odom_timeout, spec.frame, spec.cmd_type) == (2.84, 0.5, 'odom', 'TwistStamped')
    line = spec.units().describe(4.0, 1.5)
    assert 'r0 = 0.45 m' in line and 'w = 1.2 m' in line
    for bad in ({'length_scale': 0, 'cruise_speed': 0.1}, {'length_scale': 0.3},
                {'length_scale': 0.3, 'cruise_speed': 0.1, 'frame': 'map'},
                {'length_scale': 0.3, 'cruise_speed': 0.1, 'spin': 1}):
        with pytest.raises(ValueError):
            RobotsSpec.model_validate(bad)


def test_scenario_robots_section_and_error_names_the_field(tmp_path):
    from swarm_core.scenario.loader import ScenarioError, parse
    base = {'name': 'r', 'agents': {'positions': [[0, 0], [1, 0]]}, 'duration': 1.0}
    scn = parse(dict(base, robots={'length_scale': 0.3, 'cruise_speed': 0.15}))
    assert scn.spec.robots.units().robot_time(1.0) == pytest.approx(2.0)
    with pytest.raises(ScenarioError, match='robots.cruise_speed'):
        parse(dict(base, robots={'length_scale': 0.3, 'cruise_speed': -1}))


NAMES = [f'agent_{i}' for i in range(6)]


def test_parse_robots_kinds_and_selections():
    from swarm_tools.run.robots import parse_robots
    assert parse_robots(None, NAMES) == {}
    assert parse_robots(['external'], NAMES) == {nm: 'external' for nm in NAMES}
    assert parse_robots(['external:agent_0-agent_2'], NAMES) == {f'agent_{i}': 'external' for i in range(3)}
    assert parse_robots(['mujoco:agent_1,agent_4-agent_5', 'external:agent_0'], NAMES) == {
        'agent_0': 'external', 'agent_1': 'mujoco', 'agent_4': 'mujoco', 'agent_5': 'mujoco'}
    for bad, why in ((['gazebo'], 'kind must be one of external, mujoco'),
                     (['external:agent_9'], "'agent_9' is not an agent"),
                     (['external:agent_3-agent_1'], 'empty range'),
                     (['external:agent_0', 'mujoco'], 'agent_0 is already on a robot'),
                     (['none'], 'kind must be')):
        with pytest.raises(ValueError, match=why):
            parse_robots(bad, NAMES)


def test_robot_agents_get_their_parameters():
    from swarm_core.scenario.loader import parse
    from swarm_tools.run.params import node_parameters
    from swarm_tools.run.robots import apply_robots
    scn = parse({'name': 'r', 'agents': {'positions': [[i, 0] for i in range(6)]}, 'duration': 1.0,
                 'robots': {'length_scale': 0.5, 'cruise_speed': 0.25, 'cmd_type': 'Twist'}})
    params = node_parameters(scn, 'r.yaml', 'realtime')
    line = apply_robots(params, scn, {'agent_1': 'external'}, 'realtime')
    assert params['/agent_1/agent']['robot'] == 'external' and params['/agent_1/agent']['cmd_type'] == 'Twist'
    assert params['/agent_1/agent']['robot_clock'] == 'wall'      # a robot's controller: wall time
    assert 'robot' not in params['/agent_0/agent']
    assert params['/world']['rtf'] == pytest.approx(0.5)     # v0/L: robots live in wall time
    assert '1 of 6 agents on robots (external)' in line and 'w = 2 m' in line
    with pytest.raises(ValueError, match='no robots: section'):
        plain = parse({'name': 'p', 'agents': {'positions': [[0, 0]]}, 'duration': 1.0})
        apply_robots(node_parameters(plain, 'p', 'lockstep'), plain, {'agent_0': 'external'}, 'lockstep')


def test_guard_in_lockstep_watches_only_the_pause():
    g = SafetyGuard(max_speed=0.2)
    assert g.decide(100.0, watch=False) == ('resume', '')      # no odometry, no neighbour: lockstep waits
    assert g.decide(101.0, paused=True, watch=False) == ('stop', 'paused')
    assert g.decide(102.0, watch=False) == ('resume', '')

