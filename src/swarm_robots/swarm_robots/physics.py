"""A MuJoCo world of N differential-drive robots, each behind its own emulated
``diff_drive_controller`` (no ROS; CPU only, nothing renders).

One MJCF model holds every robot.  A robot is a chassis on four joints (slide x, slide y, slide
z, hinge yaw: it drives, turns and rests its weight on its wheels and caster, but cannot roll or
pitch, which a Burger on a flat floor does not do) and two wheels on hinge joints driven by
velocity servos with a speed and a torque limit.  A wheel touches the floor as a sphere of the
wheel radius (one contact point, as a thin tyre) with the description's friction; the ball
caster is a frictionless sphere.  Robots touch each other through a sphere of the footprint radius at one
height, so two robots collide as two discs in the plane; a robot's own parts never collide.

The controllers update every ``control_dt`` (100 Hz) and the physics steps ``physics_dt``
(10 ms by default: one explicit Euler step per period, see `MAX_PHYSICS_DT`); `advance` runs
whole controller periods.  Single-threaded MuJoCo with the same model and the same commands
gives bit-identical results.
"""
from __future__ import annotations

import mujoco
import numpy as np

from swarm_robots.description import RobotDescription
from swarm_robots.diff_drive import DiffDriveControllers, WheelOdometry

#: the controller's update period (controller_manager's update_rate, 100 Hz)
CONTROL_DT = 0.01
#: each wheel's velocity servo: N·m per rad/s of velocity error (the torque limit caps it)
WHEEL_GAIN = 0.5
#: reflected motor inertia on a wheel joint, kg·m²: the rotor's inertia times the gear ratio
#: squared (258.5² for the Burger's Dynamixel XL430-W250).  ROBOTIS publishes no rotor inertia;
#: 0.75 g·cm², of the order of a small cored DC motor's, reflects to 5e-3.  The servo's time
#: constant is WHEEL_ARMATURE / WHEEL_GAIN = 10 ms.
WHEEL_ARMATURE = 5e-3
#: the largest physics_dt.  The servo is integrated explicitly (Euler), stable while
#: WHEEL_GAIN·physics_dt/WHEEL_ARMATURE < 2: this is that bound with a margin of 2.  (MuJoCo's
#: implicitfast would take kv implicitly and lift the bound, but it sizes the contact forces for
#: the mass matrix M and integrates with M + h·kv: a wheel's grip no longer matches its turning.
#: Measured: at 10 ms the chassis outruns its accelerating wheels by 0.045 m/s.)
MAX_PHYSICS_DT = WHEEL_ARMATURE / WHEEL_GAIN
#: the default physics_dt: one MuJoCo step per controller period
PHYSICS_DT = CONTROL_DT
CASTER_RADIUS = 0.01
#: height of the contact sphere's centre above the wheel axle, m
BUMPER_HEIGHT = 0.05
#: chassis height for its inertia (a Burger is 0.192 m tall)
CHASSIS_HEIGHT = 0.19
#: joints per robot in qpos/qvel order: x, y, z, yaw, left wheel, right wheel
JOINTS = 6
X, Y, Z, YAW, LEFT, RIGHT = range(JOINTS)
#: MuJoCo's warnings of a diverged state (after which it resets the state to the model's)
_DIVERGED = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                              mujoco.mjtWarning.mjWARN_BADQACC)]
# collision bits: wheels and casters touch only the floor, bumpers only other bumpers
_FLOOR = 'contype="0" conaffinity="1"'
_ON_FLOOR = 'contype="1" conaffinity="0"'
_BUMPER = 'contype="2" conaffinity="2"'


def robot_mjcf(d: RobotDescription, i: int) -> str:
    """One robot's <body> (its base_link at the wheel axle's midpoint, at axle height)."""
    chassis_mass = d.mass - 2 * d.wheel_mass
    r2, h2 = d.radius ** 2, CHASSIS_HEIGHT ** 2
    ixx = chassis_mass * (3 * r2 + h2) / 12
    izz = chassis_mass * r2 / 2
    iw = d.wheel_mass * d.wheel_radius ** 2
    wheels = ''.join(
        f'<body name="r{i}_{side}" pos="0 {y} 0">'
        f'<joint name="r{i}_{side}" type="hinge" axis="0 1 0" armature="{WHEEL_ARMATURE}"/>'
        f'<inertial pos="0 0 0" mass="{d.wheel_mass}" diaginertia="{iw / 4} {iw / 2} {iw / 4}"/>'
        f'<geom type="sphere" size="{d.wheel_radius}" condim="3" friction="{d.friction} 0 0" '
        f'{_ON_FLOOR}/></body>'
        for side, y in (('left', d.wheel_separation / 2), ('right', -d.wheel_separation / 2)))
    return (
        f'<body name="r{i}" pos="0 0 {d.wheel_radius}">'
        f'<joint name="r{i}_x" type="slide" axis="1 0 0"/>'
        f'<joint name="r{i}_y" type="slide" axis="0 1 0"/>'
        f'<joint name="r{i}_z" type="slide" axis="0 0 1"/>'
        f'<joint name="r{i}_yaw" type="hinge" axis="0 0 1"/>'
        f'<inertial pos="{d.com_x} 0 {BUMPER_HEIGHT}" mass="{chassis_mass}" '
        f'diaginertia="{ixx} {ixx} {izz}"/>'
        f'<geom name="r{i}_bumper" type="sphere" size="{d.radius}" pos="0 0 {BUMPER_HEIGHT}" '
        f'condim="1" {_BUMPER}/>'
        f'<geom type="sphere" size="{CASTER_RADIUS}" '
        f'pos="{d.caster_x} 0 {CASTER_RADIUS - d.wheel_radius}" condim="1" {_ON_FLOOR}/>'
        f'{wheels}</body>')


def world_mjcf(d: RobotDescription, n: int, physics_dt: float) -> str:
    """The whole world: a floor, n robots, one velocity actuator per wheel (left, right, ...)."""
    actuators = ''.join(
        f'<velocity joint="r{i}_{side}" kv="{WHEEL_GAIN}" forcelimited="true" '
        f'forcerange="{-d.wheel_torque} {d.wheel_torque}"/>'
        for i in range(n) for side in ('left', 'right'))
    return (
        '<mujoco model="swarm_robots"><compiler angle="radian"/>'
        f'<option timestep="{physics_dt}" integrator="Euler" cone="pyramidal" '
        'solver="Newton" iterations="20" ls_iterations="10"/>'
        '<worldbody><geom name="floor" type="plane" size="0 0 1" condim="1" friction="0 0 0" '
        f'{_FLOOR}/>{"".join(robot_mjcf(d, i) for i in range(n))}</worldbody>'
        f'<actuator>{actuators}</actuator></mujoco>')


class RobotWorld:
    """N differential-drive robots in one MuJoCo model, each behind a diff_drive_controller.

    ``poses`` (N, 3): start x, y (m) and yaw (rad) in the world frame.  Times are robot
    seconds."""

    def __init__(self, description: RobotDescription, poses, physics_dt: float = PHYSICS_DT,
                 control_dt: float = CONTROL_DT):
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        if not np.isfinite(poses).all():
            raise ValueError('poses: must be finite')
        if not 0 < physics_dt <= MAX_PHYSICS_DT:
            raise ValueError(f'physics_dt: must be in (0, {MAX_PHYSICS_DT}] s (got {physics_dt!r})')
        self.substeps = int(round(control_dt / physics_dt))
        if self.substeps < 1 or abs(self.substeps * physics_dt - control_dt) > 1e-12:
            raise ValueError(f'control_dt ({control_dt}) must be a whole number of physics_dt '
                             f'({physics_dt})')
        self.description = description
        self.n = len(poses)
        self.physics_dt = physics_dt
        self.control_dt = control_dt
        self.model = mujoco.MjModel.from_xml_string(world_mjcf(description, self.n, physics_dt))
        self.data = mujoco.MjData(self.model)
        self._qpos = self.data.qpos.reshape(self.n, JOINTS)       # views into MuJoCo's arrays
        self._qvel = self.data.qvel.reshape(self.n, JOINTS)
        self._qpos[:, [X, Y, YAW]] = poses
        mujoco.mj_forward(self.model, self.data)
        self.controllers = DiffDriveControllers(description, self.n)
        self.wheel_odometry = WheelOdometry(description, self.n)
        bumpers = [self.model.geom(f'r{i}_bumper').id for i in range(self.n)]
        self._robot_of_geom = np.full(self.model.ngeom, -1)
        self._robot_of_geom[bumpers] = np.arange(self.n)
        self._floor = self.model.geom('floor').id
        self._touching = ()                                        # see `_count_contacts`
        self._ctrl = self.data.ctrl.reshape(self.n, 2)             # left, right per robot (a view)
        self._at_top = np.zeros(self.n, dtype=bool)                # which are beyond the motors'
        self._any_at_top = False
        self._steps = 0
        self._target = 0.0
        self.contacts = 0
        self.saturated_time = np.zeros(self.n)

    @property
    def time(self) -> float:
        """Robot seconds simulated (whole controller periods)."""
        return self._steps * self.control_dt

    def command(self, i, v, omega, stamp: float | None = None):
        """A cmd_vel for robot(s) `i` (an index or an index array), stamped `stamp` (default:
        now).  The controller limits it and stops the wheels cmd_vel_timeout after it; one
        already older than the timeout is dropped, as the controller's subscriber does."""
        stamp = self.time if stamp is None else stamp
        if self.controllers.fresh(self.time, stamp):
            self.controllers.command(i, v, omega, stamp)

    def advance(self, seconds: float):
        """Run the physics for `seconds` more (rounded to whole controller periods, so the
        time never drifts from the sum of what was asked by more than half a period)."""
        if not seconds >= 0:
            raise ValueError(f'seconds: must be >= 0 (got {seconds!r})')
        self._target += seconds
        steps = int(round(self._target / self.control_dt)) - self._steps
        if steps <= 0:
            return
        wheels = np.empty((steps, 2, self.n))       # wheel positions at each period's end
        times = np.empty(steps)
        for k in range(steps):
            self._control_step(wheels[k])
            times[k] = self.time
        if any(self.data.warning[w].number for w in _DIVERGED):     # not a silent reset
            raise RuntimeError(f'the physics diverged before t = {self.time:.3f} s')
        self.wheel_odometry.update_many(wheels[:, 0], wheels[:, 1], times)

    def _control_step(self, wheels):
        """One controller period: the controllers' update, physics_dt substeps, then the
        contacts at the period's end; its wheel positions into ``wheels`` (2, N) (`advance`
        gives them to the wheel odometry, one update per period)."""
        targets, saturated, same = self.controllers.update(self.time, self.control_dt)
        if same:                                # a settled controller repeats its answer: ctrl holds,
            saturated, limited = self._at_top, self._any_at_top     # and no controller limit acts
        else:
            left, right = targets
            top = self.description.max_wheel_speed      # the motors' limit, not the controller's
            self._at_top = (np.abs(left) > top) | (np.abs(right) > top)
            self._any_at_top = np.count_nonzero(self._at_top) > 0
            ctrl = self._ctrl
            ctrl[:, 0], ctrl[:, 1] = left, right
            np.clip(ctrl, -top, top, out=ctrl)
            saturated |= self._at_top
            limited = np.count_nonzero(saturated) > 0
        mujoco.mj_step(self.model, self.data, nstep=self.substeps)
        self._steps += 1
        if limited:
            np.add(self.saturated_time, self.control_dt, out=self.saturated_time, where=saturated)
        wheels[0], wheels[1] = self._qpos[:, LEFT], self._qpos[:, RIGHT]
        self._count_contacts()

    def _count_contacts(self):
        """Robot-robot contact events: a pair of robots touching now that did not before.  The
        pairs (i·n + j, i < j) are a sorted tuple: robots that touch do so for many periods,
        and a few Python ints compare faster than numpy's set routines."""
        ncon = self.data.ncon
        pairs = ()
        if ncon:
            contact = self.data.contact
            g1 = contact.geom1[:ncon]
            others = g1 != self._floor      # MuJoCo orders a pair's geoms by type: the plane first
            if np.count_nonzero(others):    # not only wheels on the floor
                a = self._robot_of_geom[g1[others]]
                b = self._robot_of_geom[contact.geom2[:ncon][others]]
                both = (a >= 0) & (b >= 0)
                keys = np.minimum(a, b)[both] * self.n + np.maximum(a, b)[both]
                pairs = tuple(sorted(set(keys.tolist())))
        if pairs and pairs != self._touching:
            self.contacts += len(set(pairs).difference(self._touching))
        self._touching = pairs

    @property
    def touching(self) -> np.ndarray:
        """(K, 2) the pairs of robots (i < j) in contact at the end of the last period."""
        pairs = np.array(self._touching, dtype=np.int64)
        return np.column_stack([pairs // self.n, pairs % self.n])

    def odometry(self) -> np.ndarray:
        """(N, 5) x, y, yaw, v, ω: wheel odometry, each robot in its own odom frame from
        (0, 0, 0), as diff_drive_controller publishes it.  Yaw is not wrapped (odometry.cpp
        keeps adding to its heading)."""
        return np.column_stack([self.wheel_odometry.pose.T, self.wheel_odometry.velocity.T])

    def odometry_pose(self) -> np.ndarray:
        """(N, 3) x, y, yaw of `odometry`, without the velocities."""
        return self.wheel_odometry.pose.T

    def ground_truth(self) -> np.ndarray:
        """(N, 5) x, y, yaw, v, ω in the world frame (yaw not wrapped); v and ω in the body
        frame."""
        q, dq = self._qpos, self._qvel
        yaw = q[:, YAW]
        v = np.cos(yaw) * dq[:, X] + np.sin(yaw) * dq[:, Y]
        return np.column_stack([q[:, X], q[:, Y], yaw, v, dq[:, YAW]])
