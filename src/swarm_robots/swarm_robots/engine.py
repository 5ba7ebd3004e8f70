"""The robot engine of studies (no ROS): a scenario's swarm with some agents on MuJoCo robots
and the rest kinematic, stepped as a lockstep ``swarm run --robots mujoco[:AGENTS]`` steps it.

Each step n (model time t_n = n·dt):

1. the commander and the law give every agent's u_n from the states of t_n (`SwarmStepper`:
   the reference engine's code, which the agent nodes equal bit for bit);
2. the kinematic agents take one ZOH step (the reference engine's ``advance``);
3. each robot agent sends u_n as one cmd_vel (v0, clip(v0·u/L, ±ω_max)) stamped t_n
   (`RobotUnits.command`); the world takes the step's commands in robot order and runs the
   physics to robot time t_(n+1)·L/v0 (`timing.RobotsLockstep`: the robot world node's hold);
4. each robot's pose of t_(n+1) is read from its odometry (`world_setup.OdometryPoses`), as the
   robot world reports it to the world (``/lockstep/robot_states``): the orientation through
   the message's quaternion, its own odom frame turned into the common one from its start pose
   (``frame: odom``; ``world``: ground truth), metres into model units, the yaw unwrapped near
   its last heading.  With a radio model a robot agent's law takes its own heading from its
   row of the table (`swarm_core.robot_units.reported_heading`), as the agent node does.

So a run here equals the ROS lockstep run with the same robots bit for bit
(tests/robots/ros/test_mujoco_runs.py).  Not covered (refused): faults (a killed robot agent's robot
rolls on until its controller's timeout, in wall time) and the RK4 integrator (the agent nodes
step ZOH).  The agents' odometry guard is not modelled: physics never jumps as it rejects.

The run's ``meta['robots']`` (docs/robots.md, "The paper's behaviours on robots"):
`timing.robot_summary` (MuJoCo robot-robot contacts, time at the turn-rate limit and at any
limit) and

- ``iae`` / ``iae_mean``: per robot and its mean, ∫|u_cmd − u_ach| dτ over model time τ, where
  u_cmd is the law's u_n held over the step and u_ach = (ψ(t_(n+1)) − ψ(t_n)) / dt the turn the
  robot achieved over it, ψ its true (ground-truth, unwrapped) yaw: the heading rate per model
  second, which is the achieved curvature in model units at the cruise speed (a kinematic
  agent's u_ach is its u);
- ``turn_limit_fraction``: the robots' time commanded at ω_max over their total time;
- ``collisions`` (every agent, also the kinematic ones): pairs of agents coming closer than a
  robot's footprint diameter (2·radius / L model units), counted at each step they enter.
"""
from __future__ import annotations

import numpy as np

from swarm_core.engine import reference as engine
from swarm_core.model.frenet import quaternion_from_heading
from swarm_core.robot_units import ROBOT_SETS, reported_heading
from swarm_core.scenario.loader import Scenario
from swarm_robots.timing import RobotsLockstep, robot_summary
from swarm_robots.world_setup import OdometryPoses, robot_description, robots_section, start_poses, turn_limit_clock


def robot_rows(n: int, robot_set: str) -> list:
    """Roster rows on robots: none, the first half (rounded up), or all of ``n`` agents."""
    if robot_set not in ROBOT_SETS:
        raise ValueError(f'robot set {robot_set!r}: one of {", ".join(ROBOT_SETS)}')
    return {'none': [], 'half': list(range((n + 1) // 2)), 'all': list(range(n))}[robot_set]


class RobotStepper(engine.SwarmStepper):
    """`engine.SwarmStepper` whose agents at ``rows`` are robots of one MuJoCo world."""

    def __init__(self, scn: Scenario, rows):
        from swarm_robots.physics import RobotWorld
        super().__init__(scn, 'zoh')
        if not self.faults.all_alive or scn.spec.faults:
            raise ValueError('the robot engine does not run faults')
        self.sec = robots_section(scn)
        self.units = self.sec.units()
        self.rows = list(rows)
        self.description = robot_description(self.sec)
        self.world = turn_limit_clock(RobotWorld(self.description, start_poses(scn, self.rows, self.units)),
                                      self.sec, self.description)
        self.hold = RobotsLockstep(self.world, self.rows, self.dt, self.units.seconds_per_model_unit)
        self.everyone = np.ones(self.n, dtype=bool)
        self.odometry = OdometryPoses(self.world, scn, self.rows, self.units, self.sec.frame)
        # a radio model's law takes each robot agent's own heading from its row of the table
        # (`robot_units.reported_heading`), unwrapped near the one before
        self.own_theta = self.theta.copy()
        self._own_headings()
        self.yaw = self.world.ground_truth()[:, 2].copy()
        self.iae = np.zeros(len(self.rows))

    def _own_headings(self):
        qz, qw = quaternion_from_heading(self.theta[self.rows])
        for i, z, w in zip(self.rows, qz.tolist(), qw.tolist()):
            self.own_theta[i] = reported_heading(z, w, self.own_theta[i])

    def own_headings(self, theta):
        """The headings the agents' radio law takes as their own: a robot agent's from the table."""
        out = np.asarray(theta, dtype=float).copy()
        out[self.rows] = self.own_theta[self.rows]
        return out

    def advance(self, t, u, lam, is_leader, steering):
        super().advance(t, u, lam, is_leader, steering)
        if not self.rows:
            return
        n = self.step_index - 1
        sent = np.asarray(u, dtype=float)[self.rows]
        sent[~np.isfinite(sent)] = 0.0                     # the agent holds u = 0 (and says so)
        self.hold.on_step(n, self.everyone)
        for k, uk in enumerate(sent.tolist()):
            v, omega, _ = self.units.command(uk)
            self.hold.on_command(k, n * self.dt, v, omega)
        self.hold.run()
        for i, pose in zip(self.rows, self.odometry.read()):
            self.pos[i] = pose[:2]
            self.theta[i] = pose[2]
        self._own_headings()
        yaw = self.world.ground_truth()[:, 2]
        self.iae += np.abs(sent - (yaw - self.yaw) / self.dt) * self.dt
        self.yaw = yaw.copy()

    def summary(self, duration: float) -> dict:
        """The robot metrics of the run (module docstring) for ``meta['robots']``."""
        names = [self.scn.names[i] for i in self.rows]
        w, scale = self.world, self.units.seconds_per_model_unit
        out = robot_summary(names, w.contacts, w.seconds, w.saturated_time, scale)
        robot_time = len(self.rows) * duration * scale
        out.update(iae={nm: float(e) for nm, e in zip(names, self.iae)},
                   iae_mean=float(self.iae.mean()) if self.rows else 0.0,
                   turn_limit_fraction=out['turn_limit_seconds_total'] / robot_time if robot_time else 0.0)
        return out


def collisions(r, diameter: float) -> int:
    """Pairs of agents coming closer than ``diameter`` (model units) in a trajectory's
    positions ``r`` (T, N, 2), each time they enter (NaN rows never touch)."""
    i, j = np.triu_indices(r.shape[1], 1)
    close = np.linalg.norm(r[:, i] - r[:, j], axis=2) < diameter           # (T, pairs)
    return int(close[0].sum() + (close[1:] & ~close[:-1]).sum())


def simulate(scn: Scenario, robot_set: str = 'all', progress=None):
    """Run ``scn`` with the agents of ``robot_set`` (`ROBOT_SETS`) on robots; a `Trajectory`
    in model units with the robot metrics in ``meta['robots']``."""
    stepper = RobotStepper(scn, robot_rows(len(scn.names), robot_set))
    traj = engine.simulate(scn, progress=progress, stepper=stepper)
    meta = stepper.summary(scn.steps * scn.dt)
    meta['collisions'] = collisions(traj.r, 2 * stepper.description.radius / stepper.units.length_scale)
    meta['robot_set'] = robot_set
    traj.meta['robots'] = meta
    return traj
