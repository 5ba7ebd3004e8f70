"""The realtime world's schedule, without ROS: as the clock passes step k, the scheduled
radio events and faults that are due, and when to refresh the view; and which agents have
gone silent for good (`SilenceWatch`: a process killed from outside is lost, as in lockstep).

Returns actions in the lockstep barrier's vocabulary (`swarm_world.lockstep`):
``('comms', k, event)``, ``('event', ev)``, ``('signal', i, what)`` and ``('fail', why)``.
Also the wall period of the world's tick (`clock_tick`)."""
from __future__ import annotations

import math

import numpy as np

from swarm_core.checks import LAMBDA_BOUND, STEERING_BOUND
from swarm_core.faults.agents import leader_slot, step_at, track_slots
from swarm_core.model.frenet import yaw_from_quaternion
from swarm_ros import protocol as P

SIGNAL_OF = {'kill': 'kill', 'freeze': 'stop', 'resume': 'cont'}   # fault event → signal
#: the realtime world ticks (and publishes /clock) at least this often, wall s ...
CLOCK_TICK_MAX = 0.01
#: ... and at most this often (a clock at 10 kHz would cost every reader more than it serves)
CLOCK_TICK_MIN = 0.005
#: wall s a fault on 'leader:i', due once the commander must have chosen its leaders, waits for
#: that choice's event (in flight on a loaded machine) before it is skipped
LEADER_CHOICE_WAIT = 5.0


def clock_tick(dt, rtf, most=CLOCK_TICK_MAX, least=CLOCK_TICK_MIN):
    """Wall s between the realtime world's ticks: a whole fraction of a control period's wall
    time dt/rtf, at most ``most`` (a period shorter than ``least``: a whole number of periods,
    at least ``least``).  Counted from the run's start (the world restarts its timer there), a
    tick, and so a /clock message, comes just after each period boundary: the agents' timers
    (on that clock) fire as the period starts, not up to a tick later, and never half a period
    late, where `agent_core.catch_up` would round up to the next period."""
    period = dt / rtf
    if period < least:
        return period * math.ceil(least / period - 1e-9)
    return period / max(1, math.ceil(period / most - 1e-9))


def decision_valid(lam, flags, steering, n):
    """A realtime commander decision is usable: λ in [0, 1], finite steering, one flag per agent."""
    return bool(LAMBDA_BOUND.ok(lam) and np.all(np.abs(steering) <= STEERING_BOUND.hi) and len(flags) == n)


class RealtimeSchedule:
    """``faults`` a `FaultTimeline`, ``slots`` the fixed leader slots (slot → index), then
    the commander's; ``comms_events`` (step, event) sorted by step.  ``choose_step``: the step
    by which the commander chooses its leaders by rule (None: fixed leaders); a fault on
    'leader:i' due from then on waits up to ``choice_wait`` wall s for the commander's
    ``leaders_chosen`` event, which the world may hear after the clock has passed the fault."""

    def __init__(self, names, faults, slots, comms_events=(), view_every=0, choose_step=None,
                 choice_wait=LEADER_CHOICE_WAIT):
        self.row = {nm: i for i, nm in enumerate(names)}
        self.faults = faults
        self.slots = dict(slots)
        self.comms = list(comms_events)
        self.view_every = view_every
        self.fault_step = -1           # faults applied up to this step
        self.view_bucket = -1
        self.choose_step = choose_step
        self.choice_wait = float(choice_wait)
        self.chosen = choose_step is None     # the commander's leader choice is heard
        self.held_since = None                # wall time a fault began to wait for it

    @classmethod
    def of_plan(cls, names, faults, plan, dt, **kw):
        """The schedule of a `CommandPlan`: its fixed slots, and its rule's last choice step."""
        choose = step_at(plan.choose_at, dt) if plan.rule is not None else None
        return cls(names, faults, plan.slots, choose_step=choose, **kw)

    def comms_due(self, k):
        """The scheduled radio events of every step up to k not sent yet."""
        acts = []
        while self.comms and self.comms[0][0] <= k:
            acts.append(('comms', k, self.comms.pop(0)[1]))
        return acts

    def faults_due(self, k, now=0.0):
        """The faults of every step up to k ('leader:i' resolved with the slots known now;
        held, with the faults after it, while `waits_for_choice` at wall time ``now``)."""
        acts = []
        while self.fault_step < k:
            if self.waits_for_choice(self.fault_step + 1, now):
                break
            self.fault_step += 1
            for ev in self.faults.apply(self.fault_step, dict(self.slots)):
                acts.append(('event', ev))
                if ev['kind'] in SIGNAL_OF:
                    acts.append(('signal', self.row.get(ev['agent']), SIGNAL_OF[ev['kind']]))
        return acts

    def waits_for_choice(self, s, now) -> bool:
        """Step ``s`` has a fault on a leader slot not known yet, the commander must have chosen
        its leaders by ``s``, its event is not heard, and the wait began under ``choice_wait``
        wall s ago."""
        if self.chosen or s < self.choose_step:
            return False
        if not any(k0 <= s and (slot := leader_slot(f.agent)) is not None and slot not in self.slots
                   for k0, _, f in self.faults.pending):
            return False
        if self.held_since is None:
            self.held_since = now
        return now - self.held_since < self.choice_wait

    def view_due(self, k):
        """True once per ``view_every`` steps (never with 0)."""
        if not self.view_every or k // self.view_every == self.view_bucket:
            return False
        self.view_bucket = k // self.view_every
        return True

    def add_fault(self, fault):
        """A live fault request: applied at the next step not yet applied; that step."""
        k = self.fault_step + 1
        self.faults.add(fault, not_before=k)
        return k

    def on_event(self, ev):
        """Follow the commander's leader slots from its events."""
        track_slots(self.slots, ev, self.row)
        if ev.get('kind') == 'leaders_chosen':
            self.chosen = True

    def lose(self, gone, last_t, dt, silent_for):
        """Agents ``gone`` (rows) went silent (`SilenceWatch`): they are lost, as lockstep drops
        its missing agents (`LockstepBarrier.drop_missing`), from the step after their newest
        state (``last_t``: its sim time per row).  Returns (actions, {row: the step it is
        gone from}): one ``lost`` event each, and ``fail`` if no agent is left."""
        acts, since = [], {}
        names = list(self.row)
        for i in gone:
            i = int(i)
            k = P.step_of(float(last_t[i]), dt) + 1
            self.faults.mark_lost(i)
            since[i] = k
            acts.append(('event', dict(t=k * dt, step=k, kind='lost', agent=names[i],
                                       silent_for=round(float(silent_for), 3))))
        if len(gone) and self.faults.dead.all():
            acts.append(('fail', f'no state from {", ".join(names[int(i)] for i in gone)} for '
                                 f'{silent_for:.1f} s (lost): every agent is lost or killed: no agent is '
                                 'left, the run ends here'))
        return acts, since


class SilenceWatch:
    """Realtime: which agents have sent no state for ``timeout`` wall s (the world's
    ``missing_timeout``, lockstep's time before it drops a missing agent).  An agent not
    watched (dead, or frozen by a fault: its silence is the fault's) starts a new silence when it
    is watched again; so does every agent after a gap in the world's own ticks longer than half
    the timeout (a world that did not run cannot tell who was silent)."""

    def __init__(self, n, timeout):
        self.timeout = float(timeout)
        self.last = np.zeros(int(n))          # wall time of each agent's newest state (or restart)
        self.checked = None                   # wall time of the last `silent` call

    def start(self, now):
        """The run starts (every agent has been heard): each silence counts from ``now``."""
        self.last[:] = now
        self.checked = now

    def heard(self, i, now):
        """Agents ``i`` (rows) sent a state that was taken, at wall time ``now``."""
        self.last[i] = now

    def silent(self, now, watched):
        """(rows of the watched agents silent for more than the timeout, the longest silence
        among them in wall s).  ``watched``: (n,) bool."""
        if self.checked is None:
            return np.zeros(0, np.intp), 0.0
        before, self.checked = self.checked, now
        if now - before > self.timeout / 2:   # the world itself stood still: nobody's silence
            self.last = np.where(self.last <= before, self.last + (now - before), self.last)
        self.last[~watched] = now
        quiet = now - self.last
        gone = np.flatnonzero(watched & (quiet > self.timeout))
        return gone, float(quiet[gone].max()) if gone.size else 0.0


def newest_view(heard, keep=None):
    """Positions (m, 2) and headings (m,) of the agents heard (``heard``: a
    `msg_checks.NewestStates`) and in ``keep`` ((n,) bool, None: all: not the dead ones), in
    roster order."""
    have = np.isfinite(heard.t) if keep is None else np.isfinite(heard.t) & keep
    return heard.state[have, :2], yaw_from_quaternion(heard.state[have, 2], heard.state[have, 3])
