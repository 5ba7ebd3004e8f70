"""How late the states of a realtime run come, without ROS.

Each agent owes one state per control period dt; the state of time t is due at the world by
the time the clock passes t + dt (its deadline: before the next period starts).  `Lateness`
counts, for the states that arrive, the wall time from the state's stamp to its arrival at the
world (the clock runs at ``rtf`` sim s per wall s), and the periods an agent skipped (a starved
process catches up several periods in one state, `agent_core.catch_up`): those states never
come and count as late.  An agent that a fault killed or froze is excused its gaps.

Reported (`summary`): the share of states on time, the p50 / p99 lateness (wall ms, skipped
states counted as later than any: None where a quantile falls among them), and the achieved
real-time factor: ``rtf`` times the share of owed periods that were computed."""
from __future__ import annotations

import numpy as np

#: the histogram of lateness: bins of this many wall seconds, up to LAST_BIN bins (beyond: the last)
BIN = 0.0005
LAST_BIN = 20000
#: what the world writes into its output_dir at the end of a realtime run (`summary` and rtf)
TIMING_FILE = 'timing.json'
#: the run fell behind when fewer states than this share came on time
ON_TIME_TARGET = 0.99


class Lateness:
    """Counts of the states of ``n`` agents, each owing one per ``dt`` (clock at ``rtf``)."""

    def __init__(self, n, dt, rtf):
        self.dt = float(dt)
        self.rtf = float(rtf)
        self.last = np.full(n, -1, dtype=np.int64)      # each agent's newest step arrived
        self.excused = np.zeros(n, bool)
        self.hist = np.zeros(LAST_BIN + 1, dtype=np.int64)
        self.on_time = 0
        self.arrived = 0
        self.skipped = 0

    def excuse(self, i):
        """Agent i was killed or frozen by a fault: its gaps are not lateness."""
        self.excused[i] = True

    def arrive(self, i, step, stamp, clock):
        """Agent i's state of ``step`` (time ``stamp``) arrived with the clock at ``clock`` (sim s)."""
        if self.last[i] >= 0 and not self.excused[i]:
            self.skipped += max(0, int(step - self.last[i] - 1))
        self.last[i] = max(self.last[i], step)
        late = max(0.0, clock - stamp)
        self.arrived += 1
        self.on_time += late <= self.dt
        self.hist[min(int(late / self.rtf / BIN), LAST_BIN)] += 1

    def owed(self, step_now):
        """States owed by now and not come: each agent not excused, from its newest step to
        ``step_now`` less one period in flight."""
        seen = (self.last >= 0) & ~self.excused
        return int(np.maximum(0, step_now - self.last[seen] - 1).sum())

    def summary(self, step_now=None) -> dict:
        """on_time_share, lateness_p50_ms, lateness_p99_ms, achieved_rtf, states (owed), late,
        arrived."""
        missed = self.skipped + (self.owed(step_now) if step_now is not None else 0)
        total = self.arrived + missed
        if total == 0:
            return dict(on_time_share=None, lateness_p50_ms=None, lateness_p99_ms=None, achieved_rtf=None,
                        states=0, late=0, arrived=0)
        return dict(on_time_share=self.on_time / total, lateness_p50_ms=self._quantile(0.5, missed),
                    lateness_p99_ms=self._quantile(0.99, missed),
                    achieved_rtf=self.rtf * self.arrived / total, states=total, late=total - self.on_time,
                    arrived=self.arrived)

    def _quantile(self, q, missed):
        """Wall ms at quantile q of the arrived states' lateness (the upper edge of its bin);
        None where it falls among the missed states or beyond the histogram."""
        rank = q * (self.arrived + missed)
        if rank > self.arrived:
            return None
        k = int(np.searchsorted(np.cumsum(self.hist), max(rank, 1)))
        return round((k + 1) * BIN * 1000.0, 3) if k < LAST_BIN else None


def behind_line(s: dict, rtf: float) -> str | None:
    """One line if the run fell behind (fewer than ON_TIME_TARGET of its states on time)."""
    if s.get('on_time_share') is None or s['on_time_share'] >= ON_TIME_TARGET:
        return None
    return (f'fell behind: {s["on_time_share"]:.1%} of states on time (target {ON_TIME_TARGET:.0%}), '
            f'achieved real-time factor {s["achieved_rtf"]:.2f} of {rtf:g}')


def timing_line(s: dict) -> str:
    """The realtime timing in one line."""
    if s.get('on_time_share') is None:
        return 'timing: no states'
    ms = lambda v: 'beyond measure' if v is None else f'{v:.1f} ms'  # noqa: E731
    return (f'timing: {s["on_time_share"]:.1%} of {s["states"]} states on time, lateness p50 '
            f'{ms(s["lateness_p50_ms"])} p99 {ms(s["lateness_p99_ms"])}, achieved rtf {s["achieved_rtf"]:.2f}')
