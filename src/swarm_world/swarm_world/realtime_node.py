"""The world in realtime mode: its inputs and its timer tick, as a part of `WorldNode`.

Realtime agents publish on their own clocks; the world records each state as it comes, from
the one message per agent process and tick (``/swarm/agent_states``), publishes the clock at the real-time factor, and checks, views and
applies faults on its tick.  The schedule itself is pure (`swarm_world.realtime`)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from rosgraph_msgs.msg import Clock

from swarm_core import metrics as M
from swarm_core.atomic import write_atomic
from swarm_core.inputs import LAMBDA_BOUND
from swarm_ros import protocol as P
from swarm_ros.layouts import ProcessStates
from swarm_ros.msg_checks import batch_ok, decoded

from .inputs import leader_flags
from .lateness import TIMING_FILE, behind_line, timing_line
from .markers import stamp
from .realtime import newest_view


class RealtimeWorld:
    """`WorldNode`'s realtime methods (a mixin: they use the node's attributes)."""

    def _on_state(self, raw):
        """Realtime: the states of one agent process (a serialized /swarm/agent_states
        message), checked at once as /swarm/states messages would be one by one
        (`msg_checks.NewestStates.take`), kept as the agents' newest and recorded, with their
        lateness (against the sim time the wall clock says, from the start on)."""
        m = decoded(ProcessStates, raw, self.run_id, self.reject, 'state-decode')
        if m is None or not batch_ok(m, self.names, None, self.reject):
            return
        ok = self.heard.take(m, self.names, self.sim_t, self.future_tolerance, self.reject)
        if not ok.any():
            return
        i, t = m.index[ok], m.t[ok]
        k = np.rint(t / self.dt).astype(np.int64)                 # protocol.step_of
        if self.started:
            self.lateness.arrive(i, k, t, (time.monotonic() - self.run_wall) * self.rtf)
        self.rec.record_realtime(i, k, m.pose[:, ok].T, m.u[ok], self.lam_now, self.leaders_now)

    @property
    def newest(self):
        """name -> (t, x, y, qz, qw, u) of the agents heard (for inspection)."""
        return self.heard.by_name(self.names)

    def _on_lambda(self, msg):
        if LAMBDA_BOUND.ok(msg.data):
            self.lam_now = msg.data

    def _on_leaders(self, msg):
        """Realtime: /swarm/leaders (comma-separated names) → the leader flags recorded."""
        self.leaders_now, unknown = leader_flags(msg.data, self.row)
        if unknown:
            self.reject('leaders', f'{P.LEADERS}: unknown agent(s) {", ".join(unknown)}')

    def rt_tick(self):
        now = time.monotonic()
        if self.other_run():
            return
        if not self.started:
            if not np.isfinite(self.heard.t).all():
                return
            self.started = True
            self.log(f'[world] realtime: {self.n} agents discovered in {now - self.wall_start:.1f} s; '
                     f'clock at rtf {self.rtf}', flush=True)
            now = self.run_wall = time.monotonic()
            self.timer.reset()          # the ticks from the start on: one just after each period boundary
            self.lateness.start()
        self.sim_t = (now - self.run_wall) * self.rtf
        self.pub_clock.publish(Clock(clock=stamp(self.sim_t)))
        k = P.step_of(self.sim_t, self.dt)
        self.act(self.rt.comms_due(k))
        if self.rt.view_due(k):
            pos, theta = newest_view(self.heard)
            t = k * self.dt
            md = M.min_distance(pos)
            line = self.obs.progress(t, pos, md, self.lam_now)
            if line:
                self.log(line, flush=True)
            self.publish_view(t, pos, theta, md, timing=self.lateness.summary(k))
        acts = self.rt.faults_due(min(k, self.steps))
        for a in acts:
            if a[0] == 'signal' and a[1] is not None and a[2] != 'cont':
                self.lateness.excuse(a[1])          # its silence is the fault's, not lateness
        self.act(acts)
        if self.sim_t >= self.scn.duration:
            self.finish()

    def rt_timing(self):
        """The realtime timing at the end (`lateness`): logged in one line (and one more if the
        run fell behind), written to ``output_dir/timing.json`` for ``swarm run``."""
        s = self.lateness.summary(min(P.step_of(self.sim_t, self.dt), self.steps))
        self.log(f'[world] {timing_line(s)}', flush=True)
        behind = behind_line(s, self.rtf)
        if behind:
            self.log(f'[world] {behind}', flush=True)
        if self.output_dir:
            write_atomic(Path(self.output_dir) / TIMING_FILE, json.dumps(dict(s, rtf=self.rtf)))
        return s
