"""Agent faults, leader failover and reunion, without ROS (beyond the paper).

One place for the rules that the batch engine, the world node and the commander node share, so
that a run with agents as processes makes the same decisions as ``swarm simulate``.

Faults (`FaultTimeline`)
    A fault fires at step k0, the first step with t_k ≥ ``at``:
    - ``kill``: from t_k0 on the agent is gone: it is in nobody's table, does not move, and
      its trajectory rows are NaN from k0 on;
    - ``freeze`` for ``for`` seconds: from t_k0 until step k1 = k0 + max(1, round(for/dt))
      the agent neither moves nor is heard (nobody's table holds it); at k1 it is back with
      the state it had at t_k0 (a stopped process resumes where it stopped).
    The agent is named, or given as ``leader:i``: whichever agent holds leader slot i at that
    step (slot 0 = the rule's left leader / the first fixed leader; a successor inherits the
    slot of the leader it replaces).  A fault at a step whose agent is already dead is a no-op.
    ``alive`` (heard this step) = not dead and not frozen.

Leader failover (`CommandPlan`, command_plan.py, uses `followers_of` and `elect_successor`)
    A leader not heard for ``timeout`` seconds (first step with t − t_missing ≥ timeout) is
    lost.  Its successor is, among the agents that are heard now and are not leaders, those
    whose nearest leader l(k) (eq. 10, `pair_sums.nearest_leader`) was the lost leader at the last
    step it was heard, the one nearest to the lost leader's last heard position; ties go to
    the lower agent index; no successor if there is no such agent.  The successor takes over
    the lost leader's steering program and slot.  A lost leader that is heard again later
    is a follower.  Without failover (``timeout`` None) leaders never change.  In 3D
    (positions (N, 3)) l(k) and "nearest" are measured in space.

The table of a step (`step.alive_control`)
    Only the agents alive at a step are in the table, in index order; a receiver that is not
    alive has u = 0.  The batch engine, an agent and an agent container all compute u this way.

Reunion (`Rendezvous`, applied to the law by `reunion_law`)
    From ``at`` for ``for`` seconds either every agent also steers to a shared rendezvous
    point with the target term of eq. 15 (`laws.target_term`, gain γ = ``gain``; the point is
    given ([x, y], or [x, y, z] in 3D), or the centroid of the heard agents at the first step
    of the window; ``track``: at
    every step, a rendezvous that moves with the swarm), and/or the far-coupling weight q0 of
    the homotopy law is set to ``coupling`` (weak global coupling, eq. 12-14, the paper's own
    cohesion mechanism).  After the window only the law's own (local) coupling holds the
    reunited swarm together.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from swarm_core.checks import PAUSE_BOUND
from swarm_core.laws.paper.natural_sums import nearest_leader_3d
from swarm_core.laws.paper.pair_sums import nearest_leader

FAULT_KINDS = ('kill', 'freeze')


def step_at(t: float, dt: float) -> int:
    """The first step k with k·dt ≥ t (to rounding)."""
    return max(0, int(math.ceil(t / dt - 1e-9)))


def freeze_steps(duration: float, dt: float) -> int:
    return max(1, int(round(duration / dt)))


@dataclass
class Fault:
    at: float
    kind: str                 # 'kill' | 'freeze'
    agent: str                # agent name or 'leader:i'
    duration: float = 0.0     # freeze: seconds
    source: str = 'scenario'  # 'scenario' | 'live'

    def __post_init__(self):
        if self.kind not in FAULT_KINDS:
            raise ValueError(f'fault kind must be one of {FAULT_KINDS}, got {self.kind!r}')
        if self.kind == 'freeze':         # one check for every way in (scenario, request, study)
            PAUSE_BOUND.check(self.duration)


def leader_slot(agent: str):
    """i of 'leader:i', or None for an agent name (ValueError for 'leader:' without digits)."""
    if agent.startswith('leader:'):
        digits = agent[7:]
        if not (digits.isdigit() and len(digits) <= 6):
            raise ValueError(f'{agent!r}: leader slots are leader:0, leader:1, ...')
        return int(digits)
    return None


class FaultTimeline:
    """Which agents are dead / frozen at each step, and the events of each step.

    ``apply(k, leader_slots)`` is called once per step, in order, before the step's commands
    are decided; it returns the events of step k (dicts with t, kind, agent, ...) and updates
    ``dead``, ``frozen`` and ``alive``.  ``leader_slots``: slot → agent index (the plan's
    leaders as of the previous step), used to resolve 'leader:i'."""

    def __init__(self, faults, names, dt: float):
        self.names = list(names)
        self.row = {nm: i for i, nm in enumerate(self.names)}
        self.dt = float(dt)
        self.n = len(self.names)
        self.pending = []                      # (k0, seq, Fault)
        self.seq = 0
        self.dead = np.zeros(self.n, bool)
        self.frozen_until = np.full(self.n, -1, dtype=np.int64)   # step at which it resumes
        self.frozen_at = np.full(self.n, -1, dtype=np.int64)
        self._alive = None                     # cached ~dead & ~frozen (None: recompute)
        self._all_alive = True                 # cached _alive.all()
        for f in faults:
            self.add(f)

    def add(self, fault: Fault, not_before: int = 0):
        """Schedule a fault (a live one: at the first step ≥ max(step of ``at``, not_before))."""
        slot = leader_slot(fault.agent)
        if slot is None and fault.agent not in self.row:
            raise ValueError(f'unknown agent {fault.agent!r}')
        k0 = max(step_at(fault.at, self.dt), int(not_before))
        self.pending.append((k0, self.seq, fault))
        self.seq += 1
        self.pending.sort(key=lambda p: (p[0], p[1]))

    @property
    def frozen(self):
        return self.frozen_until >= 0

    @property
    def alive(self):
        """~dead & ~frozen (read-only; recomputed only after a change: it is read several
        times per step)."""
        if self._alive is None:
            self._alive = ~self.dead & ~self.frozen
            self._alive.flags.writeable = False
            self._all_alive = bool(self._alive.all())
        return self._alive

    @property
    def all_alive(self) -> bool:
        """Every agent is heard this step (no agent dead or frozen); cached like ``alive``."""
        if self._alive is None:
            _ = self.alive                     # the property recomputes _alive and _all_alive
        return self._all_alive

    def mark_lost(self, i: int):
        """Agent i is gone without a scheduled fault (the world gave up waiting for it)."""
        self.dead[i] = True
        self.frozen_until[i] = -1
        self._alive = None

    def apply(self, k: int, leader_slots=None) -> list:
        if not (self.pending and self.pending[0][0] <= k) and self._alive is not None \
                and self._all_alive:
            return []                          # nothing due, nobody frozen: nothing changes
        self._alive = None
        t = k * self.dt
        events = []
        for i in np.flatnonzero(self.frozen_until == k):           # resumes first
            self.frozen_until[i] = -1
            if not self.dead[i]:
                events.append(dict(t=t, step=k, kind='resume', agent=self.names[i],
                                   frozen_at=float(self.frozen_at[i] * self.dt)))
        while self.pending and self.pending[0][0] <= k:
            _, _, f = self.pending.pop(0)
            slot = leader_slot(f.agent)
            if slot is not None:
                i = (leader_slots or {}).get(slot, -1)
                if i < 0:
                    events.append(dict(t=t, step=k, kind='fault_skipped', agent=f.agent, fault=f.kind,
                                       reason=f'no leader in slot {slot}', source=f.source))
                    continue
            else:
                i = self.row[f.agent]
            if self.dead[i]:
                continue
            ev = dict(t=t, step=k, kind=f.kind, agent=self.names[i], source=f.source)
            if slot is not None:
                ev['slot'] = slot
            if f.kind == 'kill':
                self.dead[i] = True
                self.frozen_until[i] = -1
            else:
                self.frozen_at[i] = k if self.frozen_until[i] < 0 else self.frozen_at[i]
                self.frozen_until[i] = k + freeze_steps(f.duration, self.dt)
                ev['duration'] = f.duration
                ev['until'] = float(self.frozen_until[i] * self.dt)
            events.append(ev)
        return events


def event_names(ev: dict, names) -> dict:
    """A plan event with agent indices (agent, lost, leaders, slots) replaced by names."""
    out = dict(ev)
    for key in ('agent', 'lost'):
        if isinstance(out.get(key), (int, np.integer)):
            out[key] = names[out[key]]
    for key in ('leaders', 'slots'):
        if key in out:
            out[key] = [names[i] for i in out[key]]
    return out


def track_slots(slots: dict, ev: dict, row: dict) -> None:
    """Follow the commander's leader slots (slot → agent index) from its events (names, as
    published on /swarm/events): ``leaders_chosen`` (``slots`` in slot order), ``failover``
    (the successor takes the slot), ``leader_lost`` (the slot is gone).  Realtime: the world
    resolves 'leader:i' with these."""
    kind = ev.get('kind')
    if kind == 'leaders_chosen' and isinstance(ev.get('slots'), list):
        slots.clear()
        slots.update({s: row[nm] for s, nm in enumerate(ev['slots']) if nm in row})
    elif kind == 'failover' and ev.get('agent') in row and isinstance(ev.get('slot'), int):
        slots[ev['slot']] = row[ev['agent']]
    elif kind == 'leader_lost' and isinstance(ev.get('slot'), int):
        slots.pop(ev['slot'], None)


# ---------------------------------------------------------------- leader failover

def followers_of(pos, heard, leader_rows):
    """l(k) for every agent: the index of the heard leader nearest to it (eq. 10; in space
    where pos is (N, 3), as the 3D law measures it), −1 for agents not heard, leaders and when
    no leader is heard."""
    pos = np.asarray(pos, float)
    heard = np.asarray(heard, bool)
    leaders = np.array([i for i in leader_rows if heard[i]], dtype=np.intp)
    out = np.full(len(pos), -1, dtype=np.intp)
    recv = np.flatnonzero(heard)
    recv = recv[~np.isin(recv, leaders)]
    if leaders.size and recv.size:
        out[recv] = nearest_leader(pos, recv, leaders) if pos.shape[1] == 2 else nearest_leader_3d(pos, recv, leaders)
    return out


def elect_successor(lost_position, pos, eligible) -> int:
    """The successor of a lost leader: among ``eligible`` agents (bool (N,)), the one nearest
    to ``lost_position``; ties to the lower index; −1 if none is eligible."""
    eligible = np.flatnonzero(np.asarray(eligible, bool))
    if eligible.size == 0:
        return -1
    d = np.asarray(pos, float)[eligible] - np.asarray(lost_position, float)
    d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    if d.shape[1] == 3:                    # in 3D: the distance in space
        d2 = d2 + d[:, 2] * d[:, 2]
    return int(eligible[np.argmin(d2)])


@dataclass
class Failover:
    """Leader loss detection and election state (kept by `CommandPlan`)."""

    timeout: float
    missing_since: dict = field(default_factory=dict)   # leader index → t first not heard
    last_position: dict = field(default_factory=dict)   # leader index → position last heard
    followers: dict = field(default_factory=dict)       # leader index → bool (N,) l(k) == it


# ---------------------------------------------------------------- reunion

@dataclass
class Rendezvous:
    """A shared rendezvous target switched on over [at, at + duration) (see module doc)."""

    at: float
    duration: float
    point: tuple | str | None = None   # (x, y) or (x, y, z); None: the centroid at ``at``; 'none': no target
    gain: float = 0.05              # γ of eq. 15
    normalised: bool = False
    track: bool = False             # centroid: re-taken at every step (a moving rendezvous)
    coupling: float | None = None   # far-coupling weight q0 during the window (None: the law's)
    chosen: tuple | None = None     # the point in use once the window has started

    def active(self, t: float) -> bool:
        return self.at - 1e-9 <= t < self.at + self.duration - 1e-9

    def update(self, t, pos, heard):
        """(point or None, gain, normalised, coupling or None) while active at t, else None."""
        if not self.active(t):
            return None
        if isinstance(self.point, str):
            return None, 0.0, False, self.coupling
        if self.chosen is None or (self.track and self.point is None):
            if self.point is not None:
                self.chosen = tuple(float(v) for v in self.point)
            else:                              # (x, y), or (x, y, z) in 3D
                c = np.asarray(pos, float)[np.asarray(heard, bool)].mean(axis=0)
                self.chosen = tuple(float(v) for v in c)
        return self.chosen, float(self.gain), bool(self.normalised), self.coupling


def reunion_law(law, target, rdv):
    """(law, target) for a step with rendezvous ``rdv`` (`Rendezvous.update`; None: off):
    the target term of eq. 15 towards the rendezvous point, and/or the far-coupling q0."""
    if rdv is None:
        return law, target
    point, gain, normalised, coupling = rdv
    if point is not None:
        law = law.with_parameters(target_gain=gain, target_normalised=normalised)
        target = np.array(point, float)
    if coupling is not None:
        law = law.with_parameters(q0=float(coupling))
    return law, target
