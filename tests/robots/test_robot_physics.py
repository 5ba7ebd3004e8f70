"""The MuJoCo robot world alone (swarm_robots, no ROS): circles, the diff_drive_controller's
limits and timeout, contacts, wheel odometry and its drift under slip, determinism, and the
robot description's checks."""
import dataclasses

import numpy as np
import pytest

from swarm_robots.description import TURTLEBOT3_BURGER, DescriptionError, RobotDescription
from swarm_robots.diff_drive import DiffDriveControllers, WheelOdometry
from swarm_robots.physics import RobotWorld

BURGER = TURTLEBOT3_BURGER
STEP = 0.2       # one lockstep step: dt 0.1 model units at L = 0.3 m, v0 = 0.15 m/s


def drive(world, v, omega, seconds, robots=None, record=None):
    """Command (v, ω) every STEP (as an agent in lockstep does) for `seconds`."""
    robots = np.arange(world.n) if robots is None else robots
    for _ in range(int(round(seconds / STEP))):
        world.command(robots, v, omega)
        world.advance(STEP)
        if record is not None:
            record.append(world.ground_truth().copy())


def fit_circle(xy):
    """Least-squares (algebraic) circle through points: centre, radius."""
    a = np.column_stack([xy[:, 0], xy[:, 1], np.ones(len(xy))])
    c = np.linalg.lstsq(a, (xy ** 2).sum(axis=1), rcond=None)[0]
    centre = c[:2] / 2
    return centre, float(np.sqrt(c[2] + centre @ centre))


def test_constant_command_drives_a_circle_of_radius_v_over_omega():
    """v = 0.15 m/s, ω = 0.75 rad/s: a circle of radius 0.2 m about (0, 0.2).

    Tolerance 2 % of the radius (4 mm), centre within 1 cm.  The command is inside every
    limit, so what bends the circle is physics: the wheel servos' velocity error under the
    rolling load and the creep of soft contacts (MuJoCo's contact is compliant, as a tyre's
    slip angle), each a fraction of a percent here; the centre also moves by the start, where v
    and ω ramp up at different rates (0.15 s and 0.06 s), a few millimetres.  A wrong wheel
    separation or radius in the command path or the model (a 10 % error at least) fails."""
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0]])
    v, omega = 0.15, 0.75
    drive(world, v, omega, 1.0)
    path = []
    drive(world, v, omega, 2 * np.pi / omega * 1.2, record=path)
    centre, radius = fit_circle(np.array(path)[:, 0, :2])
    assert radius == pytest.approx(v / omega, rel=0.02)
    assert np.hypot(*(centre - [0.0, v / omega])) < 0.01
    assert world.saturated_time[0] < 0.2          # only the start's ramp


def wheel_command(world):
    """(v, ω) the controller sends to robot 0's wheels (from the actuators' targets)."""
    left, right = world.data.ctrl[0] * BURGER.wheel_radius, world.data.ctrl[1] * BURGER.wheel_radius
    return (left + right) / 2, (right - left) / BURGER.wheel_separation


@pytest.mark.parametrize('axis', ['linear', 'angular'])
def test_a_step_in_the_command_reaches_the_wheels_no_faster_than_max_acceleration(axis):
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0]])
    target = 0.2 if axis == 'linear' else 2.5
    accel = BURGER.max_linear_accel if axis == 'linear' else BURGER.max_angular_accel
    k = 0 if axis == 'linear' else 1
    world.command(0, *((target, 0.0) if k == 0 else (0.0, target)))
    sent, achieved = [], []
    for _ in range(40):
        world.advance(world.control_dt)
        sent.append(wheel_command(world)[k])
        achieved.append(world.ground_truth()[0, 3 + k])
    sent, achieved = np.array(sent), np.array(achieved)
    ramp = np.minimum(accel * world.control_dt * np.arange(1, 41), target)
    np.testing.assert_allclose(sent, ramp, rtol=1e-9, atol=1e-12)   # the controller's ramp
    assert np.all(achieved <= ramp + 0.02 * target)                   # the robot follows it
    assert achieved[-1] == pytest.approx(target, rel=0.02)
    assert world.saturated_time[0] == pytest.approx(world.control_dt * np.count_nonzero(ramp < target))


def test_speed_beyond_the_limits_is_clipped_and_counted():
    """The controller clips (1 m/s, 9 rad/s) to (0.22, 2.84); then the motors clip the outer
    wheel to its top speed, so the robot drives and turns slower than even that."""
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0]])
    drive(world, 1.0, 9.0, 2.0)
    limited = world.controllers.limited_command[:, 0]
    assert limited.tolist() == [BURGER.max_linear, BURGER.max_angular]
    top = BURGER.max_wheel_speed
    inner = (BURGER.max_linear - BURGER.max_angular * BURGER.wheel_separation / 2) / BURGER.wheel_radius
    np.testing.assert_allclose(world.data.ctrl, [inner, top], rtol=1e-12)
    v, omega = world.ground_truth()[0, 3:]
    rim = BURGER.wheel_radius * np.array([inner, top])
    assert v == pytest.approx(rim.mean(), rel=0.02)
    assert omega == pytest.approx((rim[1] - rim[0]) / BURGER.wheel_separation, rel=0.02)
    assert world.saturated_time[0] == pytest.approx(2.0)


def test_a_wheel_at_its_top_speed_counts_as_saturated():
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0]])
    drive(world, 0.2, 1.0, 2.0)                    # inside the controller's limits
    assert world.controllers.limited_command[:, 0].tolist() == [0.2, 1.0]
    assert world.data.ctrl[1] == BURGER.max_wheel_speed       # (0.2 + 0.08) / 0.033 > 7
    assert world.saturated_time[0] == pytest.approx(2.0)


def test_cmd_vel_timeout_stops_the_robot():
    """One command, then silence: the robot brakes cmd_vel_timeout later and stands; one
    commanded every step keeps going."""
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    world.command(0, 0.15, 0.0)
    drive(world, 0.15, 0.0, 1.0, robots=np.array([1]))
    stopped_at = world.ground_truth()[0, 0]
    drive(world, 0.15, 0.0, 1.0, robots=np.array([1]))
    gt = world.ground_truth()
    assert abs(gt[0, 3]) < 1e-3 and gt[0, 0] == pytest.approx(stopped_at, abs=1e-3)
    # ~0.5 s at 0.15 m/s, less the ramps up and down (0.15 s each at 1 m/s²)
    assert 0.06 < gt[0, 0] < 0.085
    assert gt[1, 3] == pytest.approx(0.15, rel=0.02) and gt[1, 0] > 0.25


def test_two_robots_driven_into_each_other_touch_and_do_not_pass():
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0], [0.6, 0.0, np.pi], [0.0, 2.0, 0.0]])
    drive(world, 0.2, 0.0, 4.0)
    gt = world.ground_truth()
    assert world.contacts >= 1
    gap = gt[1, 0] - gt[0, 0]
    assert gap > 2 * BURGER.radius - 0.01           # they push, they do not pass
    assert gt[2, 0] > 0.7                           # the third one drove on untouched
    assert world.touching.tolist() == [[0, 1]]
    contacts = world.contacts
    drive(world, -0.1, 0.0, 1.0)                    # back off: no new contact event
    assert world.contacts == contacts and world.touching.size == 0


def odom_in_world(odom, start):
    """A robot's odometry (x, y, yaw in its odom frame) in the world frame."""
    c, s = np.cos(start[2]), np.sin(start[2])
    return np.array([start[0] + c * odom[0] - s * odom[1], start[1] + s * odom[0] + c * odom[1],
                     start[2] + odom[2]])


def position_error(world, start):
    est = odom_in_world(world.odometry()[0], start)
    return float(np.hypot(*(est[:2] - world.ground_truth()[0, :2])))


def test_wheel_odometry_follows_ground_truth_and_drifts_when_the_wheels_slip():
    start = [1.0, 2.0, np.pi / 2]
    plain = RobotWorld(BURGER, [start])
    for omega in (0.5, -1.0, 0.0, 2.0):
        drive(plain, 0.15, omega, 2.0)
    plain_error = position_error(plain, start)
    assert plain_error < 0.01                        # 1 cm after 1.2 m of driving
    assert plain.odometry()[0, 3] == pytest.approx(plain.ground_truth()[0, 3], abs=0.01)

    # a slippery floor and a controller that accelerates far beyond the grip (μ·g ≈ 0.5 m/s²)
    icy = dataclasses.replace(BURGER, friction=0.05, max_linear_accel=50.0, max_angular_accel=500.0)
    slipping = RobotWorld(icy, [start])
    for omega in (0.5, -1.0, 0.0, 2.0):
        drive(slipping, 0.22, omega, 1.0)
        drive(slipping, -0.22, -omega, 1.0)
    slip_error = position_error(slipping, start)
    assert slip_error > 0.05 and slip_error > 10 * plain_error


def test_the_same_commands_give_bit_identical_runs():
    rng = np.random.default_rng(3)
    omegas = rng.uniform(-3, 3, (30, 6))
    poses = [[0.3 * k, 0.2 * (k % 2), np.pi * (k % 2)] for k in range(6)]

    def run():
        world = RobotWorld(BURGER, poses)
        for omega in omegas:
            world.command(np.arange(6), 0.2, omega)
            world.advance(STEP)
        return world.ground_truth(), world.odometry(), world.contacts, world.saturated_time

    first, second = run(), run()
    assert first[2] >= 1                             # the run has contacts to reproduce
    for a, b in zip(first, second):
        assert np.array_equal(a, b)


def test_controller_keeps_the_reference_on_a_nan_command_and_drops_a_stale_one():
    ctl = DiffDriveControllers(BURGER, 1)
    ctl.command(0, 0.1, 0.0, now=0.0)
    ctl.update(0.0, 0.01)
    ctl.command(0, np.nan, 0.0, now=0.01)            # NaN: the reference stays 0.1
    for k in range(1, 30):
        (left, right), _, _ = ctl.update(0.01 * k, 0.01)
    assert left[0] * BURGER.wheel_radius == pytest.approx(0.1)
    assert not ctl.fresh(now=1.0, stamp=0.4) and ctl.fresh(now=1.0, stamp=0.6)
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0]])
    world.advance(1.0)
    world.command(0, 0.15, 0.0, stamp=0.2)           # older than cmd_vel_timeout: dropped
    world.advance(0.5)
    assert world.ground_truth()[0, 0] == pytest.approx(0.0, abs=1e-4)


def test_a_settled_controller_brakes_at_the_first_update_past_its_timeout():
    """Settled long before, each controller still brakes at the first update where
    now - stamp > cmd_vel_timeout (diff_drive_controller.cpp's test), each at its own stamp."""
    ctl = DiffDriveControllers(BURGER, 2)
    stamps = [0.0, 0.2]
    ctl.command(np.arange(2), 0.1, 0.0, now=0.0)
    braked = [None, None]
    for k in range(100):
        now = k * 0.01                              # as RobotWorld.time counts
        if k == 20:
            ctl.command(1, 0.1, 0.0, now=stamps[1])
        (left, _), _, _ = ctl.update(now, 0.01)
        for i in range(2):
            if braked[i] is None and k > 30 and left[i] * BURGER.wheel_radius < 0.1 - 1e-9:
                braked[i] = k
    assert braked == [next(k for k in range(100) if k * 0.01 - s > BURGER.cmd_vel_timeout) for s in stamps]


def test_wheel_odometry_integrates_an_arc_exactly():
    """odometry.cpp integrateExact: a quarter turn on a 0.5 m radius from wheel distances."""
    odom = WheelOdometry(BURGER, 1)
    radius, angle = 0.5, np.pi / 2
    half = BURGER.wheel_separation / 2
    left, right = (radius - half) * angle, (radius + half) * angle
    assert odom.update(np.array([left]) / BURGER.wheel_radius,
                       np.array([right]) / BURGER.wheel_radius, 1.0)
    np.testing.assert_allclose(odom.pose[:, 0], [radius, radius, angle], atol=1e-12)
    np.testing.assert_allclose(odom.velocity[:, 0], [radius * angle, angle], atol=1e-12)
    both = np.array([left + 0.3, right + 0.3]) / BURGER.wheel_radius    # then 0.3 m straight on
    assert odom.update(both[:1], both[1:], 2.0)
    np.testing.assert_allclose(odom.pose[:, 0], [radius, radius + 0.3, angle], atol=1e-12)


def test_a_yaml_description_sets_fields_and_keeps_the_burgers_defaults(tmp_path):
    path = tmp_path / 'robot.yaml'
    path.write_text('wheel_radius: 0.05\nmax_linear: 0.5\n')
    d = RobotDescription.from_yaml(path)
    assert (d.wheel_radius, d.max_linear, d.wheel_separation) == (0.05, 0.5, 0.160)


@pytest.mark.parametrize('text, field', [
    ('wheel_radius: -0.1', 'wheel_radius'),
    ('wheel_radus: 0.05', 'wheel_radus'),
    ('mass: heavy', 'mass'),
    ('max_angular: .nan', 'max_angular'),
    ('wheel_separation: 0.3', 'wheel_separation'),    # wider than the footprint
    ('wheel_mass: 0.6', 'wheel_mass'),
    ('friction: 0', 'friction'),
    ('cmd_vel_timeout: true', 'cmd_vel_timeout'),
    ('[1, 2]', 'mapping'),
])
def test_a_bad_yaml_description_names_the_bad_field(tmp_path, text, field):
    path = tmp_path / 'robot.yaml'
    path.write_text(text + '\n')
    with pytest.raises(DescriptionError, match=field) as e:
        RobotDescription.from_yaml(path)
    assert str(path) in str(e.value)


def test_advance_runs_whole_controller_periods_without_drift():
    world = RobotWorld(BURGER, [[0.0, 0.0, 0.0]])
    step = 0.1 * 0.5 / 0.22                            # 0.227... s: dt 0.1 at L = 0.5, v0 = 0.22
    for k in range(1, 11):
        world.advance(step)
        assert abs(world.time - k * step) <= world.control_dt / 2
    assert world.data.time == pytest.approx(world.time)


@pytest.mark.parametrize('kw, field', [(dict(physics_dt=0.02), 'physics_dt'),
                                       (dict(physics_dt=0.003), 'control_dt')])
def test_a_physics_step_the_wheel_servo_cannot_take_is_refused(kw, field):
    with pytest.raises(ValueError, match=field):
        RobotWorld(BURGER, [[0.0, 0.0, 0.0]], **kw)


def test_diverged_physics_is_an_error_not_a_silent_reset(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)                    # MuJoCo writes its warning to MUJOCO_LOG.TXT here
    world = RobotWorld(BURGER, [[1.0, 0.0, 0.0]])
    world.data.qvel[0] = np.inf                    # as a blown-up simulation would have it
    with pytest.raises(RuntimeError, match='diverged'):
        world.advance(0.1)
