"""The realtime world's schedule, without ROS: as the clock passes step k, the scheduled
radio events and faults that are due, and when to refresh the view.

Returns actions in the lockstep barrier's vocabulary (`swarm_world.lockstep`):
``('comms', k, event)``, ``('event', ev)`` and ``('signal', i, what)``.  Also the wall period of
the world's tick (`clock_tick`)."""
from __future__ import annotations

import math

import numpy as np

from swarm_core.faults.agents import track_slots
from swarm_core.model.frenet import yaw_from_quaternion

SIGNAL_OF = {'kill': 'kill', 'freeze': 'stop', 'resume': 'cont'}   # fault event → signal
#: the realtime world ticks (and publishes /clock) at least this often, wall s ...
CLOCK_TICK_MAX = 0.01
#: ... and at most this often (a clock at 10 kHz would cost every reader more than it serves)
CLOCK_TICK_MIN = 0.005


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


class RealtimeSchedule:
    """``faults`` a `FaultTimeline`, ``slots`` the fixed leader slots (slot → index), then
    the commander's; ``comms_events`` (step, event) sorted by step."""

    def __init__(self, names, faults, slots, comms_events=(), view_every=0):
        self.row = {nm: i for i, nm in enumerate(names)}
        self.faults = faults
        self.slots = dict(slots)
        self.comms = list(comms_events)
        self.view_every = view_every
        self.fault_step = -1           # faults applied up to this step
        self.view_bucket = -1

    def comms_due(self, k):
        """The scheduled radio events of every step up to k not sent yet."""
        acts = []
        while self.comms and self.comms[0][0] <= k:
            acts.append(('comms', k, self.comms.pop(0)[1]))
        return acts

    def faults_due(self, k):
        """The faults of every step up to k ('leader:i' resolved with the slots known now)."""
        acts = []
        while self.fault_step < k:
            self.fault_step += 1
            for ev in self.faults.apply(self.fault_step, dict(self.slots)):
                acts.append(('event', ev))
                if ev['kind'] in SIGNAL_OF:
                    acts.append(('signal', self.row.get(ev['agent']), SIGNAL_OF[ev['kind']]))
        return acts

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


def newest_view(heard):
    """Positions (m, 2) and headings (m,) of the agents heard (``heard``: a
    `msg_checks.NewestStates`), in roster order."""
    have = np.isfinite(heard.t)
    return heard.state[have, :2], yaw_from_quaternion(heard.state[have, 2], heard.state[have, 3])
