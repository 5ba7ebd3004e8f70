"""What can drive a robot agent, pure: the odometry guard bounds a walk per second, not only
per reading (`swarm_core.robot_units.SafetyGuard`), and the robot world's lockstep hold does
not run ahead once every robot's agent is dead (`swarm_robots.timing.RobotsLockstep`)."""
import math

import numpy as np

from swarm_core.robot_units import SafetyGuard
from swarm_robots.timing import RobotsLockstep


def test_a_slow_walk_of_spoofed_odometry_is_refused():
    """100 readings a second, each 0.4 m on from the one before (under max_jump = 0.5 m): the
    guard's pose stays within v0·Δt + max_jump of where the robot was, per second."""
    g = SafetyGuard(max_speed=0.15, max_jump=0.5, needs_neighbours=False)
    assert g.odometry(0.0, 0.0, 0.0, 0.0) is None
    for k in range(1, 301):                                   # 3 s of a walk at 40 m/s
        g.odometry(k * 0.01, 0.4 * k, 0.0, 0.0)
    assert g.last.x <= 3.0 * (0.15 + 0.5) + 0.5, g.last
    assert g.rejected >= 290


def test_a_robot_driving_at_its_speed_with_noisy_odometry_is_never_refused():
    g = SafetyGuard(max_speed=0.15, max_jump=0.5, needs_neighbours=False)
    rng = np.random.default_rng(0)
    for k in range(3000):                                     # 60 s at 50 Hz, 2 cm of noise
        t = k * 0.02
        x, y = 1.5 * math.sin(0.1 * t), 1.5 * (1.0 - math.cos(0.1 * t))     # a circle at 0.15 m/s
        assert g.odometry(t, x + rng.normal(0, 0.02), y + rng.normal(0, 0.02), 0.0) is None, k
    assert g.odometry(60.0, 100.0, 0.0, 0.0) is not None     # and a jump still is


class _Physics:
    def __init__(self):
        self.time = 0.0

    def command(self, k, v, omega):
        pass

    def advance(self, seconds):
        self.time += seconds


def test_the_hold_does_not_run_ahead_once_every_robots_agent_is_dead():
    hold = RobotsLockstep(_Physics(), [1], dt=0.1, robot_per_model=2.0)
    hold.on_command(0, 0.0, 0.15, 0.0)
    assert hold.run() == [0.1]
    hold.stop_awaiting(0)                                     # its agent killed
    assert not hold.ready() and hold.n == 1                   # before: ready, and run() looped for ever
    hold.on_step(1, [True, False])
    assert hold.run() == [0.2]                                # the world's steps still go on
