"""The commander's logic (no ROS): `CommandPlan` decides λ, the leaders and their steering
values each step, and applies live commands at defined steps.

The batch engine and the ROS commander node both run it, so they compute the same λ(t), the
same leaders and the same s_k.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple, Sequence

import numpy as np

from swarm_core.checks import LAMBDA_BOUND, RAMP_BOUND, STEERING_BOUND, json_value
from swarm_core.command.schedules import (
    RAMP_SHAPES,
    ConstantLambda,
    ConstantSteering,
    LambdaSchedule,
    LiveSchedule,
    SteeringProgram,
)
from swarm_core.faults.agents import Failover, elect_successor, followers_of
from swarm_core.laws import LawError, flat_parameters, parameter_specs

# ---------------------------------------------------------------- live commands

#: the plan's commands (λ, steering) and an agent's law change (`law_with`; the engine applies it)
COMMANDS = ('lambda', 'steer', 'law')
#: at most this many parameters in one law command
MAX_LAW_CHANGES = 64


def check_command(cmd: dict, n_agents: int) -> dict:
    """A live command, validated and normalised (ValueError names the bad field):
    ``{'command': 'lambda', 'value': λ (LAMBDA_BOUND), 'ramp': s (RAMP_BOUND), 'shape':
    RAMP_SHAPES}``, ``{'command': 'steer', 'agent': index, 'value': s_k (STEERING_BOUND)}`` or
    ``{'command': 'law', 'agent': index, 'parameters': {name: value}}`` (an agent's law
    parameters set live; their values are checked against its law by `law_with`); other keys
    are kept."""
    out = dict(cmd)
    kind = out.get('command')
    if not isinstance(kind, str) or kind not in COMMANDS:
        raise ValueError(f'command {kind!r}: one of {", ".join(COMMANDS)}')
    if kind == 'law':
        changes = out.get('parameters')
        if not isinstance(changes, dict) or not 0 < len(changes) <= MAX_LAW_CHANGES or not all(
                isinstance(k, str) and isinstance(v, (bool, int, float, str)) for k, v in changes.items()):
            raise ValueError(f'law command: parameters must be a mapping of 1 to {MAX_LAW_CHANGES} names to '
                             f'numbers, booleans or strings, got {str(changes)[:80]}')
        out['agent'] = _agent_index(out.get('agent'), 'law', n_agents)
        return out
    value = out.get('value')
    if kind == 'steer' and isinstance(value, (list, tuple)):     # 3D: (s_u, s_v)
        if len(value) != 2:
            raise ValueError(f'steer command: a value of {len(value)} numbers (want s, or [s_u, s_v] in 3D)')
        out['value'] = tuple(STEERING_BOUND.check(v) for v in value)
    else:
        out['value'] = (LAMBDA_BOUND if kind == 'lambda' else STEERING_BOUND).check(value)
    if kind == 'lambda':
        out['ramp'] = RAMP_BOUND.check(out.get('ramp', 0.0))
        out.setdefault('shape', 'smoothstep')
        if not isinstance(out['shape'], str) or out['shape'] not in RAMP_SHAPES:
            raise ValueError(f'ramp shape {out["shape"]!r}: one of {", ".join(RAMP_SHAPES)}')
    else:
        out['agent'] = _agent_index(out.get('agent'), 'steer', n_agents)
    return out


def _agent_index(agent, kind, n_agents) -> int:
    if isinstance(agent, bool) or not isinstance(agent, (int, np.integer)) or not 0 <= agent < n_agents:
        raise ValueError(f'{kind} agent {agent!r}: not an agent index in [0, {n_agents})')
    return int(agent)


def is_kind(name: str) -> bool:
    """Is flat law parameter ``name`` a law's kind (``law``, a blend's ``from.law``...)?  A kind
    names the law's parameters: it is fixed for the run."""
    return name == 'law' or name.endswith('.law')


def law_with(law, changes: dict):
    """``law`` with some of its flat parameters (`laws.flat_parameters`: alpha, eta, ...,
    cutoff_radius, a blend's from.alpha...) set to new values: an agent's law after a live
    change (``ros2 param set /agent_0/agent alpha 0.5``; replayed from its ``law`` command).
    ValueError names a bad change: not a parameter of the law, its kind (fixed), or a value of
    the wrong type or out of its range (the agent node declares the same ranges)."""
    flat = flat_parameters(law)
    specs = parameter_specs(law)
    out = dict(flat)
    for name, v in changes.items():
        if name not in flat or is_kind(name):
            raise ValueError(f'law parameter {name!r}: not a parameter of law {law.kind} that may change '
                             f'(those: {", ".join(k for k in flat if not is_kind(k))})')
        was, limits = flat[name], specs[name][2]
        if isinstance(was, bool) or isinstance(was, str):
            if type(v) is not type(was) or (limits and isinstance(was, str) and v not in limits):
                raise ValueError(f'law parameter {name}: {v!r} is not ' + (
                    f'one of {", ".join(limits)}' if isinstance(was, str) and limits else f'a {type(was).__name__}'))
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f'law parameter {name}: {v!r} is not a finite number')
            if isinstance(was, int) and v != int(v):
                raise ValueError(f'law parameter {name}: {v!r} is not an integer')
            v = int(v) if isinstance(was, int) else float(v)
            if limits is not None and not limits[0] <= v <= limits[1]:
                raise ValueError(f'law parameter {name}: {v!r} is outside [{limits[0]:g}, {limits[1]:g}]')
        out[name] = v
    try:
        return _rebuilt(law, out)
    except (LawError, TypeError, ValueError) as err:
        raise ValueError(f'law parameters {", ".join(changes)}: {err}') from None


def _rebuilt(law, flat: dict, prefix: str = ''):
    """A law of ``law``'s own classes with the flat parameters ``flat``: its kind is never looked
    up again, so an edited law file is not imported again during a run (a run imports it once)."""
    cls = type(law)
    if cls.parts:                   # a law made of laws (a blend: its from_law and to_law)
        return cls(*(_rebuilt(getattr(law, f'{part}_law'), flat, f'{prefix}{part}.') for part in cls.parts))
    return cls(**{k: flat[prefix + k] for k in cls.param_specs()})


def law_timeline(commands: dict, law, n_agents: int) -> dict:
    """{step: [(agent index, law, changes)]}: what the ``law`` commands among ``commands`` ({step:
    [command, ...]}, `read_commands`) make of each agent's law (all start with ``law``), in
    step order: from that step on the agent's u comes from its new law.  ValueError names the
    step of a bad one (`law_with`)."""
    current, out = {}, {}
    for step in sorted(commands):
        for cmd in commands[step]:
            if cmd.get('command') != 'law':
                continue
            k = _agent_index(cmd.get('agent'), 'law', n_agents)
            try:
                current[k] = law_with(current.get(k, law), cmd['parameters'])
            except ValueError as err:
                raise ValueError(f'law command at step {step}: {err}') from None
            out.setdefault(step, []).append((k, current[k], dict(cmd['parameters'])))
    return out


# ---------------------------------------------------------------- steering programs s_k


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


class Decided(NamedTuple):
    """One decision of the plan (`CommandPlan.decide`): what a step message carries."""
    lam: float
    flags: np.ndarray          # (N,) bool: the leaders
    steering: np.ndarray       # (N,) s_k of the leaders, 0 elsewhere
    slots: np.ndarray          # (N,) int: each agent's leader slot, -1 for none
    rendezvous: object         # `CommandPlan.rendezvous_now`
    events: list               # `CommandPlan.events` of this decision (agent indices)


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

    Beyond the paper (see `swarm_core.faults.agents`): ``failover_timeout`` (None: off) replaces a
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
    #: the shape of one leader's s_k: () planar, (2,) in 3D (s_u, s_v)
    steering_shape: tuple = ()

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
        elif cmd['command'] == 'steer':
            self.leaders[cmd['agent']] = ConstantSteering(cmd['value'])
        else:
            raise ValueError(f'command {cmd["command"]}: an agent\'s, not the plan\'s (`law_timeline`)')
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
        steering = np.zeros((n, *self.steering_shape))
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

    def decide(self, t: float, pos, cos_t, sin_t, heard=None, commands=()) -> Decided:
        """`update`, as flags, steering and leader slots per agent: the commander's decision of
        a step (realtime) and the world's (lockstep) are this one call."""
        lam, leaders, steering = self.update(t, pos, cos_t, sin_t, heard=heard, commands=commands)
        n = len(cos_t)
        flags = np.zeros(n, bool)
        flags[leaders] = True
        slots = np.full(n, -1)
        for sl, i in self.slots.items():
            slots[i] = sl
        return Decided(lam, flags, steering, slots, self.rendezvous_now, list(self.events))

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


#: longest line of an events file (an event is a few hundred characters)
MAX_EVENT_CHARS = 65536


def read_commands(lines, names) -> dict:
    """{step: [command, ...]} of the ``command`` events among JSON lines (a run's
    ``events.jsonl``, or ``/swarm/events`` messages), agent names turned into indices.
    ValueError names the line of a bad event (no step, unknown agent, bad value)."""
    row = {nm: i for i, nm in enumerate(names)}
    out: dict[int, list] = {}
    for k, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            ev = json_value(line, MAX_EVENT_CHARS)
        except ValueError as err:
            raise ValueError(f'line {k}: not a JSON event ({err})') from None
        if not isinstance(ev, dict) or ev.get('kind') != 'command':
            continue
        step = ev.get('step')
        if isinstance(step, bool) or not isinstance(step, int) or step < 0:
            raise ValueError(f'line {k}: command without a step ≥ 0 (step={step!r})')
        cmd = {key: v for key, v in ev.items() if key not in ('t', 'kind', 'step', 'node')}
        if cmd.get('command') in ('steer', 'law'):
            if not isinstance(cmd.get('agent'), str) or cmd['agent'] not in row:
                raise ValueError(f'line {k}: {cmd["command"]} command for unknown agent {cmd.get("agent")!r}')
            cmd['agent'] = row[cmd['agent']]
        try:
            out.setdefault(step, []).append(check_command(cmd, len(names)))
        except ValueError as err:
            raise ValueError(f'line {k}: {err}') from None
    return out


def recorded_law_hashes(lines) -> list[str]:
    """The hashes of a user's law file that a run's events record (``events.jsonl``: the
    world's ``law`` line, an agent's ``law`` command), in order, each once; [] for a run of a
    shipped law.  Lines that are not JSON objects are left to `read_commands`."""
    out = []
    for line in lines:
        try:
            ev = json_value(line, MAX_EVENT_CHARS) if line.strip() else None
        except ValueError:
            continue
        h = ev.get('law_hash') if isinstance(ev, dict) else None
        if isinstance(h, str) and h and h not in out:
            out.append(h)
    return out
