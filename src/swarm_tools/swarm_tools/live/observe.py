"""What `swarm_tools.api.Swarm` hears of a live run: ``/world/metrics``, ``/swarm/states`` and
``/swarm/events``.  A 3D run's states (the run's ``/swarm/run`` announcement says ``dim: 3``)
are read with their position, frame and (u, v) (`swarm_tools.odometry3d`)."""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from swarm_core.model.frenet import yaw_from_quaternion
from swarm_ros import protocol as P
from swarm_ros.msg_checks import Senders, check_values, refused
from swarm_ros.run_control import EventRefused, run_event
from swarm_tools.live.view import metrics_numbers
from swarm_tools.odometry3d import States3D, cdr_to_odometry_3d, check_values_3d, states_3d


@dataclass
class States:
    """The newest state of each agent heard on ``/swarm/states`` (rows in the run's order)."""
    names: list
    t: np.ndarray           # sim time of each row's state
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray       # heading
    u: np.ndarray           # the curvature held over the step that ended at t


class Observer:
    """``/world/metrics``, ``/swarm/states`` and ``/swarm/events`` heard on a client's node.
    Each message is read defensively: one that cannot be read (malformed, a state that
    `msg_checks.check_values` refuses, a second publisher of a name, an agent not in the run,
    JSON that is too long or too deep) is counted in the client's ``reject`` log (one line per
    kind, rate-limited) and dropped; the reader goes on."""

    def __init__(self, client, swarm):
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.msg import Odometry
        from std_msgs.msg import String
        node, self.lock = client.node, client.lock
        self.client = client
        self.reject = client.reject
        self.swarm = swarm                       # its roster (`Swarm.agents`), once known
        self.metrics, self.states, self.events = None, {}, []
        self.newest = {}                         # name → (t, x, y, qz, qw): `check_values`' table
        self.states3, self.newest3 = {}, {}      # a 3D run's: name → (t, r, q, u, v), (t, *r, *q)
        self.senders = Senders()
        node.create_subscription(DiagnosticArray, P.METRICS, self._on_metrics, 10)
        node.create_subscription(Odometry, P.STATES, self._on_state, P.qos_latched(P.STATES_DEPTH), raw=True)
        node.create_subscription(String, P.EVENTS, self._on_event, P.qos_latched(100))

    @property
    def dim(self):
        """The run's dimension (2 or 3), from its announcement; None while none is known."""
        run = self.swarm.run
        if not run:
            runs = self.client.runs
            run = next(iter(runs.values())) if len(runs) == 1 else {}
        return run.get('dim', 2) if run else None

    def _on_metrics(self, msg):
        for st in msg.status:
            m = metrics_numbers({kv.key: kv.value for kv in st.values})
            if 'clusters' in m:
                if not np.isfinite(m['clusters']):
                    self.reject('metrics', f'{P.METRICS}: clusters={m["clusters"]!r}')
                    continue
                m['clusters'] = int(m['clusters'])
            with self.lock:
                self.metrics = m

    def _on_state(self, raw):
        dim = self.dim
        if dim == 3 or (dim is None and _tilted(raw)):
            return self._on_state_3d(raw)
        try:
            _, name, sec, nsec, pose, _, wz, tag = P.cdr_to_odometry_full(raw)
        except (struct.error, IndexError, ValueError) as err:
            self.reject('state-decode', f'{P.STATES}: a malformed message ({len(raw)} bytes: {err})')
            return
        t = sec + nsec * 1e-9
        roster = self.swarm.agents
        why = check_values(name, t, pose, wz, roster if roster else (name,), self.newest)
        if why is None:
            why = self.senders.check(name, tag)
        if refused(self.reject, why):
            return
        self.senders.accept(name, tag)
        x, y, _, _, qz, qw = pose
        self.newest[name] = (t, x, y, qz, qw)
        with self.lock:
            self.states[name] = (t, x, y, float(yaw_from_quaternion(qz, qw)), wz)

    def _on_state_3d(self, raw):
        """A 3D state: position, the quaternion of its frame, u = angular.z, v = −angular.y."""
        try:
            name, sec, nsec, pos, q, wy, wz, tag = cdr_to_odometry_3d(raw)
        except (struct.error, IndexError, ValueError) as err:
            self.reject('state-decode', f'{P.STATES}: a malformed message ({len(raw)} bytes: {err})')
            return
        t = sec + nsec * 1e-9
        roster = self.swarm.agents
        why = check_values_3d(name, t, pos, q, (wy, wz), roster if roster else (name,), self.newest3)
        if why is None:
            why = self.senders.check(name, tag)
        if refused(self.reject, why):
            return
        self.senders.accept(name, tag)
        self.newest3[name] = (t, *pos, *q)
        with self.lock:
            self.states3[name] = (t, pos, q, wz, -wy)

    def snapshot(self, agents):
        """The newest `States` (a 3D run: `States3D`), rows in the order of ``agents`` and then
        the others; None before the first state."""
        three = self.dim == 3
        with self.lock:
            got = dict(self.states3 if three else self.states)
        if not got:
            return None
        order = [nm for nm in agents if nm in got] + sorted(set(got) - set(agents))
        if three:
            return states_3d(order, got)
        cols = np.array([got[nm] for nm in order], dtype=float).T
        return States(order, *cols)

    def _on_event(self, msg):
        """An event of this run (`run_control.run_event`: a forged one without the run's id
        cannot satisfy a command's wait); others are counted."""
        try:
            ev = run_event(msg.data, self.swarm.run_id)
        except EventRefused as err:
            self.reject(err.kind, str(err))
            return
        with self.lock:
            self.events.append(ev)


def _tilted(raw) -> bool:
    """A state that is not planar (a z, a tilted frame or a v): a 3D run's, before its
    announcement is heard."""
    try:
        _, _, _, (_, _, z), (qx, qy, _, _), wy, _, _ = cdr_to_odometry_3d(raw)
    except (struct.error, IndexError, ValueError):
        return False
    return any(c != 0 for c in (z, qx, qy, wy))


__all__ = ['Observer', 'States', 'States3D']
