"""The lockstep world's wall-clock decisions, without ROS: when to start, when to drop the
agents whose state has not come, when to give up on a step, and when to repeat the last
message."""
from __future__ import annotations


class StartWatch:
    """Start once every agent's state of step 0 is held, the ``n`` relay readers and one more
    (the commander) are matched and the commander said it takes part; with
    ``wait_for_recorder`` also one /clock reader more than the agents and the commander (a
    late recorder would lose the first, volatile /clock messages), for at most
    ``recorder_wait`` s."""

    def __init__(self, now, n, *, start_timeout, wait_for_recorder=False, recorder_wait=0.0,
                 relay_want=0, clock_want=0):
        self.n = n
        self.relay_want = relay_want or n          # agent containers: one relay reader per process
        self.clock_want = clock_want or 1          # the recorder (lockstep agents, commander: time from the steps)
        self.start_timeout = start_timeout
        self.wait_for_recorder = wait_for_recorder
        self.recorder_wait = recorder_wait
        self.wall_start = now
        self.recorder_wait_from = None     # when everyone but the recorder was matched

    def decide(self, now, *, states, relay_readers, commander_ready, clock_readers):
        """``'start'``, ``'start_without_recorder'`` (waited ``recorder_wait`` in vain),
        ``'time_out'`` (not started within ``start_timeout``) or None (wait).  ``states``: every
        state of step 0 is held."""
        ok = states and relay_readers >= self.relay_want + 1 and commander_ready
        if ok and self.wait_for_recorder and clock_readers < self.clock_want:
            if self.recorder_wait_from is None:
                self.recorder_wait_from = now
            if now - self.recorder_wait_from >= self.recorder_wait:
                return 'start_without_recorder'
            ok = False
        if ok:
            return 'start'
        return 'time_out' if now - self.wall_start > self.start_timeout else None


class StallWatch:
    """Wall seconds since the step began (``stepped``) and since the last progress
    (``progressed``: a state or decision taken, or a message repeated)."""

    def __init__(self, now, *, missing_timeout, step_timeout, stall_timeout):
        self.missing_timeout = missing_timeout
        self.stall_timeout = stall_timeout
        # never give up before the missing agents are dropped and the drop had time to work
        self.give_up_after = max(step_timeout, missing_timeout + 10 * stall_timeout)
        self.step_wall = now
        self.last_progress = now

    def stepped(self, now):
        self.step_wall = now

    def progressed(self, now):
        self.last_progress = now

    def decide(self, now, *, complete, can_repeat):
        """``'drop'`` (agents missing too long), ``'give_up'`` (the step too long),
        ``'repeat'`` (no progress for ``stall_timeout``; counts as progress) or None.
        ``complete``: every state of the step is here; ``can_repeat``: a message has gone out."""
        waited = now - self.step_wall
        if not complete and waited > self.missing_timeout:
            return 'drop'
        if waited > self.give_up_after:
            return 'give_up'
        if can_repeat and now - self.last_progress > self.stall_timeout:
            self.last_progress = now
            return 'repeat'
        return None
