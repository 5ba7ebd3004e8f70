"""When the MuJoCo world advances its robots (pure: no ROS import).

Model time τ (the swarm's sim time, /clock) maps to robot time s = τ·L/v0 (L the length scale
in m per model unit, v0 the cruise speed in m/s; `swarm_core.robot_units`, docs/robots.md).

Lockstep (`RobotsLockstep`): after the world's step n (sim time t_n) each robot agent sends one
command stamped t_n; the world holds until it has that command from every robot whose agent is
alive in step n (the alive mask of ``/lockstep/step``), then advances the physics to robot time
t_(n+1)·L/v0 and publishes odometry stamped t_(n+1).  So a robot run is deterministic: the
physics sees the same commands at the same robot times whatever the order of arrival.

Realtime (`RealtimePacer`): the physics follows the sim clock; odometry at the controller's
publish rate.
"""
from __future__ import annotations

import math

import numpy as np

#: diff_drive_controller's default publish_rate (Hz): odometry in realtime
ODOM_RATE = 50.0
#: lockstep: commands for at most this many steps ahead of the held one are kept
AHEAD = 100


class RobotsLockstep:
    """The lockstep hold of one robot world over the robots at roster rows ``rows`` (robot k
    drives the agent of row ``rows[k]``); ``world`` a `swarm_robots.physics.RobotWorld`-like
    object (``command(k, v, omega)``, ``advance(seconds)``, ``time``)."""

    def __init__(self, world, rows, dt: float, robot_per_model: float):
        self.world = world
        self.rows = np.asarray(rows, dtype=int)
        self.dt = float(dt)
        self.scale = float(robot_per_model)     # robot s per model s: L / v0
        self.n = 0                              # the step whose commands are awaited
        self.commands = {}                      # step -> {robot k: (v, omega)}
        self.known = {}                         # step -> ((K,) bool: whose agent is alive, wall s its
                                                # step message first came)
        self.dead = set()                       # robots whose agent was killed: never awaited again
        self.ignored = 0                        # commands of no step or too far ahead
        self.repeated = 0                       # commands of a step already advanced (an agent's resend)
        self.asked = 0.0                        # robot s asked of the physics so far

    def step_of(self, t: float) -> int | None:
        """The step whose sim time is ``t``, or None if ``t`` is no step's time."""
        k = round(t / self.dt)
        return k if abs(k * self.dt - t) <= 1e-6 * max(1.0, abs(t)) else None

    def on_command(self, k: int, t: float, v: float, omega: float) -> bool:
        """A command of robot ``k`` stamped ``t``: kept for its step.  One of a step already
        advanced changes nothing (an agent sends its command again when the world repeats a
        stalled step: counted in ``repeated``, True); one of no step or too far ahead is ignored
        (False).  The first command of a robot for a step counts (an agent repeats the same one)."""
        n = self.step_of(t)
        if n is not None and n < self.n:
            self.repeated += 1
            return True
        if n is None or n > self.n + AHEAD:
            self.ignored += 1
            return False
        self.commands.setdefault(n, {}).setdefault(int(k), (float(v), float(omega)))
        return True

    def on_step(self, n: int, alive_rows, now: float = 0.0) -> None:
        """The world's step ``n`` with its alive mask over the whole roster, at wall time ``now``.
        The world repeats a step while it stalls: a repeat changes nothing (a release stays)."""
        if self.n <= n <= self.n + AHEAD and n not in self.known:
            self.known[n] = (np.asarray(alive_rows, dtype=bool)[self.rows], now)

    def overdue(self, now: float, timeout: float) -> bool:
        """The held step's message came ``timeout`` wall s or more before ``now``."""
        return self.n in self.known and now - self.known[self.n][1] >= timeout

    def waiting_for(self) -> list:
        """Robots whose command for the held step is still missing: every robot until the step's
        alive mask is known, then the robots of alive agents only."""
        have = self.commands.get(self.n, {})
        mask = self.known.get(self.n, (None,))[0]
        return [k for k in range(len(self.rows))
                if k not in have and (mask is None or mask[k]) and k not in self.dead]

    def ready(self) -> bool:
        """The held step may advance: it has begun (its message or a command came) and no
        command of it is awaited.  With every robot's agent dead the physics follows the world's
        steps (before, it ran ahead without end)."""
        return (self.n in self.known or self.n in self.commands) and not self.waiting_for()

    def stop_awaiting(self, k: int) -> None:
        """Robot ``k``'s agent was killed (its kill event): its command is not awaited from the
        held step on.  The world kills an agent right after it sends a step, so the agent may
        die before it commands that step; without this the step would wait for the hold's
        time-out.  A command of it that came is still applied."""
        self.dead.add(int(k))

    def release(self) -> list:
        """Stop waiting for the held step's missing robots, once the step itself is known (its
        agents died after the world sent it: without this the robots of the others would never
        move and the world would lose them too).  They get no command this step; returns them."""
        if self.n not in self.known:
            return []
        missing = self.waiting_for()
        self.known[self.n][0][missing] = False
        return missing

    def advance(self) -> float:
        """Apply the held step's commands (in robot order), advance the physics to robot time
        t_(n+1)·L/v0 and move on; returns t_(n+1), the stamp of the odometry to publish."""
        for k, (v, omega) in sorted(self.commands.pop(self.n, {}).items()):
            self.world.command(k, v, omega)
        self.known.pop(self.n, None)
        self.n += 1
        t = self.n * self.dt
        self.asked = advance_to(self.world, self.asked, t * self.scale)
        return t

    def run(self) -> list:
        """Advance while ready; the sim times of the odometry to publish, in order."""
        out = []
        while self.ready():
            out.append(self.advance())
        return out


class RealtimePacer:
    """Realtime: where the physics should be at sim time ``t`` and when odometry is due (each
    ``1 / ODOM_RATE`` robot s, and at least each ``1 / ODOM_RATE`` wall s while sim time stands
    still, e.g. before the clock starts, so that the agents have a fresh pose)."""

    def __init__(self, robot_per_model: float, rate: float = ODOM_RATE):
        self.scale = float(robot_per_model)
        self.period = 1.0 / rate
        self.next_robot = 0.0
        self.last_wall = -math.inf

    def target(self, t: float) -> float:
        """Robot time of sim time ``t``."""
        return t * self.scale

    def odom_due(self, robot_time: float, wall: float) -> bool:
        """Is odometry due at ``robot_time`` (robot s) and ``wall`` (wall s)? If so it is taken."""
        due = robot_time >= self.next_robot or wall >= self.last_wall + self.period
        if due:
            self.next_robot = (math.floor(robot_time / self.period) + 1) * self.period
            self.last_wall = wall
        return due


class TurnLimitClock:
    """A robot world (`swarm_robots.physics.RobotWorld`'s API) that also adds up the robot
    seconds each robot is commanded at the turn-rate limit ``max_angular`` (the agents clip
    ω there: `swarm_core.robot_units.RobotUnits.command`), while its command is younger than
    the controller's ``cmd_vel_timeout`` (after that the robot stops).  Everything else is the
    wrapped world's."""

    def __init__(self, world, max_angular: float, cmd_vel_timeout: float):
        self.world = world
        self.limit = float(max_angular) * (1 - 1e-9)
        self.timeout = float(cmd_vel_timeout)
        self.at_limit = np.zeros(world.n, dtype=bool)
        self.since = np.full(world.n, -np.inf)          # robot time of each robot's newest command
        self.seconds = np.zeros(world.n)

    def command(self, i, v, omega):
        self.at_limit[i] = abs(omega) >= self.limit
        self.since[i] = self.world.time
        self.world.command(i, v, omega)

    def advance(self, seconds):
        live = self.at_limit & ((self.world.time - self.since < self.timeout) if self.timeout > 0 else True)
        self.seconds[live] += seconds
        self.world.advance(seconds)

    def __getattr__(self, name):
        return getattr(self.world, name)


def advance_to(world, asked: float, target: float, limit: float = math.inf) -> float:
    """Advance ``world`` from robot time ``asked`` (the sum of what it was asked so far) to
    ``target``, by at most ``limit`` robot s (the rest on later calls: no callback runs the
    physics for an unbounded time); returns the new sum.  The physics may round each advance
    to whole controller periods and keeps the remainder, so it is asked the exact
    differences, never ``target`` minus its rounded clock (which would add each rounding again)."""
    if target > asked:
        if target - asked > limit:
            target = asked + limit
        world.advance(target - asked)
        return target
    return asked


def robot_summary(names, contacts: int, turn_limit_time, saturated_time, robot_per_model: float,
                  commands_missed=None) -> dict:
    """What the robots did, for metrics.json: robot-robot contacts (a pair coming into contact),
    the time each robot was commanded at the turn-rate limit (`TurnLimitClock`) and the time its
    controller held it at any velocity or acceleration limit (robot s; totals also in model s).
    ``commands_missed`` (lockstep, the robot world): {agent: [steps]} that went on without that
    robot's command (`RobotsLockstep.release`); any makes the run no longer deterministic."""
    turn = np.asarray(turn_limit_time, dtype=float)
    sat = np.asarray(saturated_time, dtype=float)
    missed = {} if commands_missed is None else {nm: list(v) for nm, v in commands_missed.items()}
    return dict(robots=list(names), contacts=int(contacts), commands_missed=missed, deterministic=not missed,
                turn_limit_seconds={nm: float(s) for nm, s in zip(names, turn)},
                turn_limit_seconds_total=float(turn.sum()),
                turn_limit_model_seconds_total=float(turn.sum() / robot_per_model),
                limit_seconds={nm: float(s) for nm, s in zip(names, sat)},
                limit_seconds_total=float(sat.sum()),
                limit_model_seconds_total=float(sat.sum() / robot_per_model))
