"""How late the states of a realtime run come, without ROS.

Each agent owes one state per control period dt; the state of time t is due at the world by
the time the clock passes t + dt (its deadline: before the next period starts).  `Lateness`
counts, for the states that arrive, the wall time from the state's stamp to its arrival at the
world (the clock runs at ``rtf`` sim s per wall s), and the periods an agent skipped (a starved
process catches up several periods in one state, `agent_core.catch_up`): those states never
come and count as late.  An agent that a fault killed or froze is excused its gaps.

Reported (`summary`): the share of states on time, the p50 / p99 lateness (wall ms) and the
achieved real-time factor: ``rtf`` times the share of owed periods that were computed.  A
state that never came has a lateness too, so every quantile is a number: a skipped one (an
agent caught up over it) is as late as the state that came in its place, counted from its own
period; one still owed when the summary is made is at least as late as the clock then."""
from __future__ import annotations

import math

import numpy as np

#: the lateness histogram: bin b holds lateness up to FIRST_EDGE · GROWTH^b wall s (bin 0: up to
#: FIRST_EDGE), so a quantile is its bin's upper edge, within 1 % above the true value
FIRST_EDGE = 1e-4
GROWTH = 1.01
#: bins up to FIRST_EDGE · GROWTH^LAST_BIN (about 12 days; beyond: the last)
LAST_BIN = 2500
#: what the world writes into its output_dir at the end of a realtime run (`summary` and rtf)
TIMING_FILE = 'timing.json'
#: the run fell behind when fewer states than this share came on time
ON_TIME_TARGET = 0.99


def bins_of(late):
    """The histogram bins of lateness ``late`` (wall s, an array)."""
    late = np.maximum(np.asarray(late, float), FIRST_EDGE)
    return np.minimum(np.ceil(np.log(late / FIRST_EDGE) / _LOG_GROWTH - 1e-9), LAST_BIN).astype(np.intp)


_LOG_GROWTH = math.log(GROWTH)


def ramp(gaps):
    """0, 1, .., g-1 for each g of ``gaps`` (ints), one after the other."""
    gaps = np.asarray(gaps, np.int64)
    ends = np.cumsum(gaps)
    return np.arange(ends[-1] if len(ends) else 0) - np.repeat(ends - gaps, gaps)


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

    def start(self):
        """The clock starts with every agent's state of step 0 held (the world waits for them):
        from here on each agent owes every period, so the periods skipped by a process whose
        first ticks came late are counted, as any others."""
        self.last[:] = 0

    def excuse(self, i):
        """Agent i was killed or frozen by a fault: its gaps are not lateness."""
        self.excused[i] = True

    def arrive(self, i, step, stamp, clock):
        """The states of agents ``i`` (distinct) of steps ``step`` (times ``stamp``) arrived with
        the clock at ``clock`` (sim s); arrays or one each.  The steps an agent skipped since its
        last state are as late as the state that came, from their own periods."""
        i, step = np.atleast_1d(i), np.atleast_1d(step)
        late = np.maximum(0.0, clock - np.atleast_1d(stamp))
        last = self.last[i]
        gap = np.where((last >= 0) & ~self.excused[i], np.maximum(0, step - last - 1), 0)
        if gap.any():
            self.skipped += int(gap.sum())
            skipped = np.repeat(late, gap) + self.dt * (ramp(gap) + 1)
            np.add.at(self.hist, bins_of(skipped / self.rtf), 1)
        self.last[i] = np.maximum(last, step)
        self.arrived += len(i)
        self.on_time += int(np.count_nonzero(late <= self.dt))
        np.add.at(self.hist, bins_of(late / self.rtf), 1)

    def owed(self, step_now):
        """(m,) lateness (sim s, at least) of the states owed by now and not come: each agent not
        excused, from its newest step to ``step_now`` less one period in flight."""
        seen = (self.last >= 0) & ~self.excused
        return self.dt * (ramp(np.maximum(0, step_now - self.last[seen] - 1)) + 1)

    def summary(self, step_now=None) -> dict:
        """on_time_share, lateness_p50_ms, lateness_p99_ms, achieved_rtf, states (owed), late,
        arrived."""
        owed = self.owed(step_now) if step_now is not None else np.zeros(0)
        missed = self.skipped + len(owed)
        total = self.arrived + missed
        if total == 0:
            return dict(on_time_share=None, lateness_p50_ms=None, lateness_p99_ms=None, achieved_rtf=None,
                        states=0, late=0, arrived=0)
        hist = self.hist + np.bincount(bins_of(owed / self.rtf), minlength=LAST_BIN + 1)
        return dict(on_time_share=self.on_time / total, lateness_p50_ms=quantile_ms(hist, 0.5),
                    lateness_p99_ms=quantile_ms(hist, 0.99),
                    achieved_rtf=self.rtf * self.arrived / total, states=total, late=total - self.on_time,
                    arrived=self.arrived)


def quantile_ms(hist, q):
    """Wall ms at quantile q of the lateness histogram ``hist`` (the upper edge of its bin)."""
    k = int(np.searchsorted(np.cumsum(hist), max(q * hist.sum(), 1)))
    return round(FIRST_EDGE * GROWTH ** k * 1000.0, 3)


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
    return (f'timing: {s["on_time_share"]:.1%} of {s["states"]} states on time, lateness p50 '
            f'{s["lateness_p50_ms"]:.1f} ms p99 {s["lateness_p99_ms"]:.1f} ms, achieved rtf {s["achieved_rtf"]:.2f}')
