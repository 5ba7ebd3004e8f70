"""λ schedules, leader steering programs and leader choice rules (no ROS).

The commander's logic lives here (`CommandPlan`) so that the batch engine and the ROS
commander node compute the same λ(t), the same leaders and the same steering values s_k.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .faults import Failover, elect_successor, followers_of

RAMP_SHAPES = ('smoothstep', 'linear', 'step', 'tanh')


def ramp_shape(x, shape: str):
    """Normalised ramp profile on x ∈ [0, 1] → [0, 1] (C¹ 'smoothstep' 3x² − 2x³ by default)."""
    x = np.clip(x, 0.0, 1.0)
    if shape == 'smoothstep':
        return x * x * (3.0 - 2.0 * x)
    if shape == 'linear':
        return x
    if shape == 'step':
        return np.where(x > 0.0, 1.0, 0.0)
    if shape == 'tanh':  # tanh profile rescaled to hit 0 and 1 exactly at the ends
        return 0.5 * (np.tanh(6.0 * (x - 0.5)) / math.tanh(3.0) + 1.0)
    raise ValueError(f'ramp shape must be one of {RAMP_SHAPES}, got {shape!r}')


class LambdaSchedule:
    """λ(t) ∈ [0, 1]; subclasses implement `value`."""

    def value(self, t: float) -> float:  # pragma: no cover - interface
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantLambda(LambdaSchedule):
    level: float = 0.0

    def value(self, t):
        return self.level


@dataclass(frozen=True)
class TanhWindow(LambdaSchedule):
    """λ(t) = low + (high − low)·½[tanh((t − rise_at)/τ) − tanh((t − fall_at)/τ)]: smooth,
    up near t = rise_at, down near t = fall_at (docs/model.md: τ = 30 gives a clean split)."""

    rise_at: float = 400.0
    fall_at: float = 600.0
    tau: float = 30.0
    low: float = 0.0
    high: float = 1.0

    def value(self, t):
        bump = 0.5 * (math.tanh((t - self.rise_at) / self.tau) - math.tanh((t - self.fall_at) / self.tau))
        return self.low + (self.high - self.low) * bump


@dataclass(frozen=True)
class Ramp:
    """From whatever λ is at ``start``, go to ``to`` over ``duration`` with ``shape``."""

    start: float
    to: float
    duration: float = 20.0
    shape: str = 'smoothstep'


@dataclass
class RampSchedule(LambdaSchedule):
    """Piecewise ramps from an initial level; a ramp that starts before the previous one has
    finished starts from the value reached then (so live set-points chain smoothly)."""

    initial: float = 0.0
    ramps: list = field(default_factory=list)

    def then(self, start: float, to: float, duration: float = 20.0, shape: str = 'smoothstep'):
        """Append a ramp (the commander's live set-point) and return self."""
        ramp_shape(0.0, shape)  # validates the shape name
        self.ramps.append(Ramp(float(start), float(to), float(duration), shape))
        self.ramps.sort(key=lambda r: r.start)
        return self

    def value(self, t):
        level = self.initial
        for i, r in enumerate(self.ramps):
            if t < r.start:
                break
            nxt = self.ramps[i + 1].start if i + 1 < len(self.ramps) else math.inf
            upto = min(t, nxt)
            x = 1.0 if r.duration <= 0 else (upto - r.start) / r.duration
            level = level + (r.to - level) * float(ramp_shape(x, r.shape))
        return level


class LiveSchedule(LambdaSchedule):
    """A schedule with live set-points: the base schedule until the first set-point; from
    then on smooth ramps from the value reached to each new set-point (`RampSchedule`)."""

    def __init__(self, base: LambdaSchedule):
        self.base = base
        self.override: RampSchedule | None = None

    def set_point(self, t: float, to: float, duration: float, shape: str = 'smoothstep'):
        if self.override is None:
            self.override = RampSchedule(initial=float(self.base.value(t)))
        self.override.then(t, to, duration, shape)

    def value(self, t):
        return self.base.value(t) if self.override is None else self.override.value(t)


# ---------------------------------------------------------------- live commands

COMMANDS = ('lambda', 'steer')


def check_command(cmd: dict, n_agents: int) -> dict:
    """A live command, validated and normalised (ValueError names the bad field):
    ``{'command': 'lambda', 'value': λ ∈ [0, 1], 'ramp': s ≥ 0, 'shape': RAMP_SHAPES}`` or
    ``{'command': 'steer', 'agent': index, 'value': finite s_k}``; other keys are kept."""
    out = dict(cmd)
    kind = out.get('command')
    if kind not in COMMANDS:
        raise ValueError(f'command {kind!r}: one of {", ".join(COMMANDS)}')
    try:
        value = float(out.get('value'))
    except (TypeError, ValueError):
        raise ValueError(f'{kind} value {out.get("value")!r}: not a number') from None
    if not math.isfinite(value):
        raise ValueError(f'{kind} value {value!r}: not finite')
    out['value'] = value
    if kind == 'lambda':
        if not 0.0 <= value <= 1.0:
            raise ValueError(f'λ={value!r}: must be in [0, 1]')
        ramp = float(out.get('ramp', 0.0))
        if not (math.isfinite(ramp) and ramp >= 0.0):
            raise ValueError(f'ramp {ramp!r}: must be finite and ≥ 0')
        out['ramp'] = ramp
        out.setdefault('shape', 'smoothstep')
        if out['shape'] not in RAMP_SHAPES:
            raise ValueError(f'ramp shape {out["shape"]!r}: one of {", ".join(RAMP_SHAPES)}')
    else:
        agent = out.get('agent')
        if isinstance(agent, bool) or not isinstance(agent, (int, np.integer)) or not 0 <= agent < n_agents:
            raise ValueError(f'steer agent {agent!r}: not an agent index in [0, {n_agents})')
        out['agent'] = int(agent)
    return out


# ---------------------------------------------------------------- steering programs s_k

class SteeringProgram:
    """A leader's explicit steering program s_k (eq. 9, 12): curvature as a function of
    time and of the leader's own state."""

    def value(self, t: float, pos, heading: float) -> float:  # pragma: no cover - interface
        """s_k at time t for a leader at ``pos`` with ``heading`` = atan2(sin θ, cos θ)."""
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantSteering(SteeringProgram):
    """Constant curvature, e.g. the paper's s1 = 0.01, s2 = −0.01."""

    curvature: float = 0.0

    def value(self, t, pos=None, heading=None):
        return self.curvature


@dataclass(frozen=True)
class SinusoidSteering(SteeringProgram):
    """s(t) = offset + amplitude · sin(2π t / period + phase)."""

    amplitude: float = 0.01
    period: float = 200.0
    phase: float = 0.0
    offset: float = 0.0

    def value(self, t, pos=None, heading=None):
        return self.offset + self.amplitude * math.sin(2.0 * math.pi * t / self.period + self.phase)


@dataclass(frozen=True)
class WaypointSteering(SteeringProgram):
    """Pursuit of a point: s = clip(gain · bearing error, ±max_curvature), the bearing error
    being the angle from the heading x_k to the direction of the waypoint."""

    point: tuple = (0.0, 0.0)
    gain: float = 0.05
    max_curvature: float = 0.05

    def value(self, t, pos, heading):
        bearing = math.atan2(self.point[1] - pos[1], self.point[0] - pos[0])
        err = math.remainder(bearing - heading, 2.0 * math.pi)
        return max(-self.max_curvature, min(self.max_curvature, self.gain * err))


# ---------------------------------------------------------------- leaders

LEADER_RULES = ('lateral_extremes',)

#: a leader rule also fires as soon as λ has risen this much above the lowest λ so far, whoever
#: raised it (the schedule, a live set-point): raising λ splits the swarm
CHOOSE_RISE = 0.01


def lateral_extremes(pos, cos_t, sin_t):
    """Indices (left, right) of the agents at the lateral extremes of the swarm, relative to
    its mean heading: left = largest offset along the mean heading rotated by +90°."""
    pos = np.asarray(pos, dtype=float)
    hx, hy = float(np.mean(cos_t)), float(np.mean(sin_t))
    norm = math.hypot(hx, hy)
    hx, hy = (1.0, 0.0) if norm == 0.0 else (hx / norm, hy / norm)
    rel = pos - pos.mean(axis=0)
    lateral = -rel[:, 0] * hy + rel[:, 1] * hx
    return int(np.argmax(lateral)), int(np.argmin(lateral))


@dataclass
class CommandPlan:
    """What the commander decides each step: λ, the leaders and their steering values.

    Leaders are either fixed (``fixed_leaders``: agent index → program) or chosen by
    ``rule`` at the first step with t ≥ ``choose_at`` or with λ risen by `CHOOSE_RISE` above
    its lowest value so far (the left extreme gets programs[0], the right one programs[1]).
    Before the choice there are no leaders.

    Live commands (``update(..., commands=[...])``, see `check_command`) are applied at the
    start of the step they are given to: a λ set-point starts a ramp from the λ reached at
    t_n; a steering command makes that agent a leader with a constant program.  The batch
    engine replays recorded commands at their steps the same way.

    Beyond the paper (see `swarm_core.faults`): ``failover_timeout`` (None: off) replaces a
    leader not heard for that long by the elected successor, which inherits its program and
    slot (``slots``: slot → agent index; slot i = programs[i] / the i-th fixed leader);
    ``rendezvous`` entries switch on a shared rendezvous target (``rendezvous_now`` after
    each update: (point, gain, normalised) or None).  ``events`` lists what the last update
    decided (leader choice, leader lost, failover, rendezvous on/off) as dicts.
    """

    schedule: LambdaSchedule = field(default_factory=ConstantLambda)
    fixed_leaders: dict = field(default_factory=dict)
    rule: str | None = None
    choose_at: float = 0.0
    rule_programs: Sequence[SteeringProgram] = ()
    leaders: dict = field(default_factory=dict)   # current: agent index → program
    failover_timeout: float | None = None
    rendezvous: Sequence = ()

    def __post_init__(self):
        if not self.leaders:
            self.leaders = dict(self.fixed_leaders)
        if self.rule is not None and self.rule not in LEADER_RULES:
            raise ValueError(f'leader rule must be one of {LEADER_RULES}, got {self.rule!r}')
        self.slots = {s: i for s, i in enumerate(self.leaders)}
        self.failover = Failover(self.failover_timeout) if self.failover_timeout is not None else None
        self.events = []
        self.rendezvous_now = None
        self._rdv_on = [False] * len(self.rendezvous)
        self._lam_low = math.inf

    def command(self, t: float, cmd: dict, n_agents: int) -> dict:
        """Apply one live command at time t (validated by `check_command`); returns its event."""
        cmd = check_command(cmd, n_agents)
        if cmd['command'] == 'lambda':
            if not isinstance(self.schedule, LiveSchedule):
                self.schedule = LiveSchedule(self.schedule)
            self.schedule.set_point(t, cmd['value'], cmd['ramp'], cmd['shape'])
        else:
            self.leaders[cmd['agent']] = ConstantSteering(cmd['value'])
        return dict(cmd, t=t, kind='command')

    @property
    def pending_choice(self) -> bool:
        return self.rule is not None and not self.leaders

    def update(self, t: float, pos, cos_t, sin_t, heard=None, commands=()):
        """Advance to time t with the swarm's states; returns (λ, leader indices, steering).

        pos (N, 2) and the frames (cos θ, sin θ) are what the agents publish, so the batch
        engine and the ROS commander get the same answer.  ``heard`` (bool (N,), default all):
        the agents whose states of t are known; the rows of the others are not read.
        steering is an array (N,) with s_k for leaders (from their last known state if not
        heard) and 0 elsewhere.  The leader indices include leaders that are not heard (until
        failover replaces them).  ``commands``: live commands applied first (`command`); their
        events come first in ``events``."""
        self.events = []
        n = len(cos_t)
        for cmd in commands:
            self.events.append(self.command(t, cmd, n))
        heard = np.ones(n, bool) if heard is None else np.asarray(heard, bool)
        lam = float(self.schedule.value(t))
        self._lam_low = min(self._lam_low, lam)
        if self.pending_choice and (t >= self.choose_at or lam - self._lam_low >= CHOOSE_RISE):
            rows = np.flatnonzero(heard)
            pos_h = np.asarray(pos, float)[rows]
            left, right = lateral_extremes(pos_h, np.asarray(cos_t)[rows], np.asarray(sin_t)[rows])
            left, right = int(rows[left]), int(rows[right])
            progs = list(self.rule_programs)
            self.leaders = {left: progs[0]}
            self.slots = {0: left}
            if right != left and len(progs) > 1:
                self.leaders[right] = progs[1]
                self.slots[1] = right
            self.events.append(dict(t=t, kind='leaders_chosen', leaders=sorted(self.leaders),
                                    slots=[self.slots[k] for k in sorted(self.slots)]))
        if self.failover is not None and self.leaders:
            self._failover(t, pos, heard)
        steering = np.zeros(n)
        for idx, prog in self.leaders.items():
            heading = math.atan2(float(sin_t[idx]), float(cos_t[idx]))
            steering[idx] = prog.value(t, pos[idx], heading)
        self.rendezvous_now = None
        for j, r in enumerate(self.rendezvous):
            now = r.update(t, pos, heard)
            if now is not None and self.rendezvous_now is None:
                self.rendezvous_now = now
            if (now is not None) != self._rdv_on[j]:
                self._rdv_on[j] = now is not None
                ev = dict(t=t, kind='rendezvous_on' if now is not None else 'rendezvous_off')
                if now is not None:
                    ev.update(point=None if now[0] is None else list(now[0]), gain=now[1], coupling=now[3])
                self.events.append(ev)
        return lam, sorted(self.leaders), steering

    def _failover(self, t, pos, heard):
        fo = self.failover
        lost = []
        for idx in sorted(self.leaders):
            if heard[idx]:
                fo.missing_since.pop(idx, None)
            else:
                fo.missing_since.setdefault(idx, t)
                if idx in fo.last_position and t - fo.missing_since[idx] >= fo.timeout - 1e-9:
                    lost.append(idx)
        for idx in lost:
            prog = self.leaders.pop(idx)
            slot = next((s for s, i in self.slots.items() if i == idx), None)
            eligible = fo.followers.get(idx, np.zeros(len(heard), bool)) & heard
            eligible[list(self.leaders)] = False
            succ = elect_successor(fo.last_position[idx], pos, eligible)
            fo.missing_since.pop(idx, None)
            ev = dict(t=t, kind='failover' if succ >= 0 else 'leader_lost', lost=idx, slot=slot)
            if succ >= 0:
                self.leaders[succ] = prog
                if slot is not None:
                    self.slots[slot] = succ
                ev['agent'] = succ
            elif slot is not None:
                self.slots.pop(slot)
            self.events.append(ev)
        # remember, for every heard leader, where it is and who follows it (for a later loss)
        rows = sorted(self.leaders)
        lk = followers_of(pos, heard, rows)
        for idx in rows:
            if heard[idx]:
                fo.last_position[idx] = np.array(pos[idx], float)
                fo.followers[idx] = lk == idx


def read_commands(lines, names) -> dict:
    """{step: [command, ...]} of the ``command`` events among JSON lines (a run's
    ``events.jsonl``, or ``/swarm/events`` messages), agent names turned into indices.
    ValueError names the line of a bad event (no step, unknown agent, bad value)."""
    import json
    row = {nm: i for i, nm in enumerate(names)}
    out: dict[int, list] = {}
    for k, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            ev = json.loads(line)
        except ValueError as err:
            raise ValueError(f'line {k}: not JSON ({err})') from None
        if not isinstance(ev, dict) or ev.get('kind') != 'command':
            continue
        step = ev.get('step')
        if isinstance(step, bool) or not isinstance(step, int) or step < 0:
            raise ValueError(f'line {k}: command without a step ≥ 0 (step={step!r})')
        cmd = {key: v for key, v in ev.items() if key not in ('t', 'kind', 'step', 'node')}
        if cmd.get('command') == 'steer':
            if cmd.get('agent') not in row:
                raise ValueError(f'line {k}: steer command for unknown agent {cmd.get("agent")!r}')
            cmd['agent'] = row[cmd['agent']]
        try:
            out.setdefault(step, []).append(check_command(cmd, len(names)))
        except ValueError as err:
            raise ValueError(f'line {k}: {err}') from None
    return out
