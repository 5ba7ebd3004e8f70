"""The radio model: what each agent's radio delivers, and what it believes (no ROS).

A state message is sent by every agent j at every step n (its state of t_n: x, y, the planar
quaternion (qz, qw) and u, the curvature it held over the step that ended at t_n).  Receiver k
gets it, or not, according to the model in force at step n (the send step):

- ``radio_range``  R: delivered only if |r_k − r_j| ≤ R at t_n (None: unlimited; the law's own
  cutoff w still applies inside `swarm_control`);
- ``loss``         p: lost with probability p (per link overrides; a burst ``drop`` b
  composes as 1 − (1 − p)(1 − b));
- ``latency`` L, ``jitter`` J (sim seconds): delay L + U·J, U uniform in [0, 1), quantised up
  to whole steps: the message is usable from step n + ceil((L + U·J)/dt) on (0: the same step);
- ``partition``: groups of agent names; no message crosses from one group to another (agents
  in no group form one more group).  Partitions and loss are decided at the send step.

**Deterministic, without shared state.**  The fate of the message j → k of step n is a pure
function of (seed, n, k, j): two uniforms from a counter-based hash (`link_uniforms`,
splitmix64 finaliser over the four numbers), so the batch engine, which decides every link of
a step at once, and each agent process, which decides only its own incoming links, draw the
very same fates.  All arithmetic is elementwise, so the results are bit-identical.

**Beliefs.**  Each receiver keeps, per sender, the newest state it has received (by stamp; a
late older message never replaces a newer one).  Senders whose newest state is older than
``timeout`` are forgotten (left out of the table).  With ``dead_reckoning`` the state of t_m is
predicted to t_n on the exact arc of unit speed with the sender's known heading and u
(the arc of `integrate.zoh_step` with dt = t_n − t_m, by angle sums: `dead_reckon`).
`step.belief_controls` gives u_k of every receiver from its own state and its beliefs with
THE law, in one call over the believed (receiver, sender) pairs.

Changes in time: ``events`` at sim times (``loss``/``latency``/``jitter`` set the base values,
``drop`` + ``duration`` a burst loss, ``partition`` new groups, ``[]`` heals), applied from the
first step n with n·dt ≥ at; at runtime the same events arrive as JSON (see
docs/ros-graph.md) and are applied with `CommModel.apply`.

The model is configured by a plain mapping (the scenario's ``comms`` section, validated by
`scenario.CommsSpec`; agents get it as JSON), so this module needs neither pydantic nor ROS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from swarm_core.model.frenet import frame_from_quaternion

DEFAULTS = dict(seed=None, radio_range=None, loss=0.0, latency=0.0, jitter=0.0, timeout=2.0,
                dead_reckoning=True, links=(), partition=(), events=())

MIX_M1 = np.uint64(0xBF58476D1CE4E5B9)
MIX_M2 = np.uint64(0x94D049BB133111EB)
GOLDEN = np.uint64(0x9E3779B97F4A7C15)
SHIFT_30, SHIFT_27, SHIFT_31, SHIFT_11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
#: the two draws of a link and step
STREAM_LOSS, STREAM_DELAY = 0, 1
#: above this many believed pairs, each message is dead-reckoned once (`Beliefs.known_pairs`)
MESSAGES_ONCE = 256
#: fates of links × steps drawn at once (`CommModel._uniforms`)
FATE_BLOCK = 16384


def splitmix(z):
    """splitmix64 finaliser (a bijection of uint64; arrays, wrapping arithmetic)."""
    z = (z ^ (z >> SHIFT_30)) * MIX_M1
    z = (z ^ (z >> SHIFT_27)) * MIX_M2
    return z ^ (z >> SHIFT_31)


def link_uniforms(seed, step, receiver, sender, stream=STREAM_LOSS):
    """Uniforms in [0, 1), a pure function of (seed, step, receiver, sender, stream);
    arguments broadcast like numpy arrays (non-negative integers)."""
    h = np.full(np.broadcast_shapes(np.shape(seed), np.shape(step), np.shape(receiver),
                                    np.shape(sender), np.shape(stream)), GOLDEN, dtype=np.uint64)
    with np.errstate(over='ignore'):
        for key in (seed, step, receiver, sender, stream):
            h = splitmix(h ^ splitmix(np.asarray(key, dtype=np.uint64) + GOLDEN))
    return (h >> SHIFT_11).astype(np.float64) * (1.0 / 9007199254740992.0)


def event_step(at: float, dt: float) -> int:
    """The first step n with n·dt ≥ at."""
    return max(0, int(math.ceil(at / dt - 1e-9)))


def _names(v):
    if v is None:
        return None
    return [v] if isinstance(v, str) else list(v)


@dataclass
class CommModel:
    """The radio of a swarm with agents ``names`` (table order), steps of ``dt``; see module doc."""

    names: list
    dt: float
    seed: int = 0
    radio_range: float | None = None
    loss: float = 0.0
    latency: float = 0.0
    jitter: float = 0.0
    timeout: float = 2.0
    dead_reckoning: bool = True
    links: tuple = ()
    partition: tuple = ()
    events: tuple = ()
    # state in force (changed by events)
    burst: tuple = field(default=(0.0, 0, None), repr=False)      # (b, first step, end step or None)
    labels: np.ndarray = field(default=None, repr=False)

    @classmethod
    def from_config(cls, cfg: dict | None, names, dt: float, seed: int = 0) -> 'CommModel':
        """From the scenario's ``comms`` mapping (None: the perfect radio); unknown agent names
        raise ValueError naming them."""
        c = dict(DEFAULTS)
        c.update({k: v for k, v in (cfg or {}).items() if v is not None or k == 'radio_range'})
        unknown = set(c) - set(DEFAULTS)
        if unknown:
            raise ValueError(f'comms: unknown field {sorted(unknown)[0]!r}')
        m = cls(names=list(names), dt=float(dt), seed=int(seed if c['seed'] is None else c['seed']),
                radio_range=None if c['radio_range'] is None else float(c['radio_range']),
                loss=float(c['loss']), latency=float(c['latency']), jitter=float(c['jitter']),
                timeout=float(c['timeout']), dead_reckoning=bool(c['dead_reckoning']),
                links=tuple(dict(x) for x in c['links']),
                partition=tuple(tuple(g) for g in c['partition']),
                events=tuple(sorted((dict(e) for e in c['events']), key=lambda e: float(e['at']))))
        m._build()
        return m

    # ------------------------------------------------------------ set-up
    def _index(self, names, where):
        row = {nm: i for i, nm in enumerate(self.names)}
        bad = [nm for nm in names if nm not in row]
        if bad:
            raise ValueError(f'comms: {where}: unknown agent {bad[0]!r}')
        return [row[nm] for nm in names]

    def _build(self):
        n = len(self.names)
        # per-link overrides (n × n, NaN = the base value): only the keys some link sets, so a
        # radio without links costs no n² memory (a 30,000-agent swarm: 3 × 7 GB otherwise)
        self._ovr = {key: np.full((n, n), np.nan) for key in ('loss', 'latency', 'jitter')
                     if any(link.get(key) is not None for link in self.links)}
        for i, link in enumerate(self.links):
            recv = _names(link.get('receiver'))
            send = _names(link.get('sender'))
            rk = np.arange(n) if recv is None else np.array(self._index(recv, f'links.{i}.receiver'), int)
            sj = np.arange(n) if send is None else np.array(self._index(send, f'links.{i}.sender'), int)
            for key in ('loss', 'latency', 'jitter'):
                if link.get(key) is not None:
                    self._ovr[key][np.ix_(rk, sj)] = float(link[key])
        self.set_partition(self.partition)
        for i, e in enumerate(self.events):
            if e.get('partition'):
                for g in e['partition']:
                    self._index(g, f'events.{i}.partition')
        self._pending_events = [(event_step(float(e['at']), self.dt), e) for e in self.events]
        self._fates = {}                    # stream -> (key, first step, uniforms (steps, K, J))

    def set_partition(self, groups):
        """Groups of agent names that cannot hear each other ([] or None: no partition)."""
        n = len(self.names)
        groups = [list(g) for g in (groups or []) if len(g)]
        labels = np.full(n, len(groups), dtype=np.intp)        # the rest: one more group
        for gi, g in enumerate(groups):
            labels[self._index(g, 'partition')] = gi
        self.labels = labels
        self.partition = tuple(tuple(g) for g in groups)

    @property
    def perfect(self) -> bool:
        """True if every message arrives in its own step: the model changes nothing."""
        ovr = any(np.nan_to_num(a, nan=0.0).any() for a in self._ovr.values())
        return (self.radio_range is None and self.loss == 0.0 and self.latency == 0.0 and self.jitter == 0.0
                and not ovr and not self.partition and not self.events)

    # ------------------------------------------------------------ changes in time
    def apply(self, event: dict, step: int):
        """Apply one change (an ``events`` entry or a runtime event) from ``step`` on.

        Fields: loss, latency, jitter (base values), drop (burst loss, with optional duration in
        sim s; drop 0 ends a burst), partition (list of groups; [] heals)."""
        for key in ('loss', 'latency', 'jitter'):
            if event.get(key) is not None:
                setattr(self, key, float(event[key]))
        if event.get('drop') is not None:
            b = float(event['drop'])
            dur = event.get('duration')
            end = None if dur is None else step + max(1, int(round(float(dur) / self.dt)))
            self.burst = (b, int(step), end)
        if event.get('partition') is not None:
            self.set_partition(event['partition'])
        if event.get('heal'):
            self.set_partition([])

    def advance_to(self, step: int):
        """Apply the scheduled events due at or before ``step`` (steps never go back)."""
        while self._pending_events and self._pending_events[0][0] <= step:
            s, e = self._pending_events.pop(0)
            self.apply(e, s)

    def burst_at(self, step: int) -> float:
        b, start, end = self.burst
        return b if (b > 0.0 and step >= start and (end is None or step < end)) else 0.0

    def _param(self, key, recv, send):
        """The value of ``key`` on the links (K, J): the base value (a number) where no link
        overrides it, else an array."""
        base = getattr(self, key)
        if key not in self._ovr:
            return base
        o = self._ovr[key][np.ix_(recv, send)]
        return np.where(np.isnan(o), base, o)

    # ------------------------------------------------------------ fates
    def decide(self, step: int, recv, recv_xy, send, send_xy) -> np.ndarray:
        """Arrival step of the messages of ``step`` from senders ``send`` (J,) to receivers
        ``recv`` (K,): an int array (K, J), −1 where lost.  recv_xy (K, 2), send_xy (J, 2):
        positions at t_step (for the radio range; (K, 3), (J, 3) in 3D).  A receiver always has its own message."""
        self.advance_to(step)
        recv = np.asarray(recv, dtype=np.intp)
        send = np.asarray(send, dtype=np.intp)
        rk, sj = recv[:, None], send[None, :]
        p = self._param('loss', recv, send)
        b = self.burst_at(step)
        if b > 0.0:
            p = 1.0 - (1.0 - p) * (1.0 - b)
        ok = self._uniforms(step, recv, send, STREAM_LOSS) >= p
        if self.partition:
            ok &= self.labels[rk] == self.labels[sj]
        if self.radio_range is not None:
            rx, sx = np.asarray(recv_xy, float), np.asarray(send_xy, float)
            dx = rx[:, 0][:, None] - sx[:, 0][None, :]
            dy = rx[:, 1][:, None] - sx[:, 1][None, :]
            d2 = dx * dx + dy * dy
            if rx.shape[1] == 3:                    # in 3D: the distance in space
                dz = rx[:, 2][:, None] - sx[:, 2][None, :]
                d2 = d2 + dz * dz
            ok &= d2 <= self.radio_range * self.radio_range
        delay_t = self._param('latency', recv, send)
        jit = self._param('jitter', recv, send)
        if np.ndim(delay_t) == 0 and np.ndim(jit) == 0 and jit == 0.0:     # one delay for all links
            delay = max(0, math.ceil(delay_t / self.dt - 1e-9))
        else:
            if np.any(jit > 0.0):
                delay_t = delay_t + jit * self._uniforms(step, recv, send, STREAM_DELAY)
            delay = np.maximum(np.ceil(np.divide(delay_t, self.dt) - 1e-9), 0.0).astype(np.int64)
        arrival = np.where(ok, step + delay, -1)
        arrival[rk == sj] = step
        return arrival

    def _uniforms(self, step, recv, send, stream):
        """`link_uniforms` (K, J) of a step, taken from a block of the next steps drawn at once
        (about FATE_BLOCK numbers; the same numbers, since each is a pure function of its
        key): a step's hashing costs numpy's per-call overhead, not arithmetic, on small
        swarms.  The block is kept per stream for the last (receivers, senders) asked."""
        rk, sj = recv[:, None], send[None, :]
        size = recv.size * send.size
        if send.size < 2 or size * 2 > FATE_BLOCK:       # one link (a realtime agent), or large
            return link_uniforms(self.seed, step, rk, sj, stream)
        key = (recv.tobytes(), send.tobytes())
        cached = self._fates.get(stream)
        if cached is not None and cached[0] == key and cached[1] <= step < cached[1] + len(cached[2]):
            return cached[2][step - cached[1]]
        start, steps = step, np.arange(step, step + FATE_BLOCK // size)[:, None, None]
        block = link_uniforms(self.seed, steps, rk, sj, stream)
        self._fates[stream] = (key, start, block)
        return block[step - start]

    def max_age_steps(self) -> int:
        """Beliefs older than this many steps are forgotten (timeout)."""
        return int(math.floor(self.timeout / self.dt + 1e-9))


class Beliefs:
    """Newest received state per (receiver, sender) for receivers ``recv`` (K,) of N agents."""

    #: the numbers of one state message: x, y, qz, qw, u
    FIELDS = 5

    def __init__(self, recv, n_agents: int):
        self.recv = np.asarray(recv, dtype=np.intp)
        K, N = self.recv.size, int(n_agents)
        self.stamp = np.full((K, N), -1, dtype=np.int64)       # step of the newest state held
        self.state = np.zeros((self.FIELDS, K, N))             # x, y, qz, qw, u
        self.pending = []                                      # (step, arrival (K, N), state (5, N))
        self.other = self.recv[:, None] != np.arange(N)[None, :]
        # statistics of what the radio did (links j ≠ k): counts and delays in steps
        self.sent = np.zeros((K, N), dtype=np.int64)
        self.delivered = np.zeros((K, N), dtype=np.int64)
        self.delay_counts = np.zeros(1, dtype=np.int64)       # histogram of delays (steps) of delivered messages

    def receive(self, step: int, arrival, x, y, qz, qw, u, alive=None):
        """Take the fates of step ``step`` (from `CommModel.decide`) and the states sent then;
        fold every message due by ``step`` into the beliefs, newest stamp winning.

        alive (N,) bool, faults: agents out of the table (dead, frozen) neither send nor listen
        at this step; their links carry nothing and are not counted as sent."""
        self.receive_states(step, arrival, np.array([x, y, qz, qw, u], dtype=float), alive)

    def receive_states(self, step: int, arrival, states, alive=None):
        """`receive` with the states sent at ``step`` as one array (FIELDS, N)."""
        arrival = np.asarray(arrival, dtype=np.int64)
        links = self.other
        if alive is not None and not np.all(alive):
            alive = np.asarray(alive, bool)
            on = alive[self.recv][:, None] & alive[None, :]
            arrival = np.where(on, arrival, -1)
            links = links & on
        got = (arrival >= 0) & self.other
        self.sent += links
        self.delivered += got
        d = np.bincount((arrival - step)[got])
        if d.size > self.delay_counts.size:
            d[:self.delay_counts.size] += self.delay_counts
            self.delay_counts = d
        else:
            self.delay_counts[:d.size] += d
        self.pending.append((step, arrival, states))
        keep = []
        for m, arr, st in self.pending:
            due = (arr >= 0) & (arr <= step) & (m > self.stamp)
            if due.any():
                np.copyto(self.stamp, m, where=due)
                np.copyto(self.state, st[:, None, :], where=due)
            if np.any(arr > step):
                keep.append((m, arr, st))
        self.pending = keep

    def known_pairs(self, step: int, model: CommModel, active=None):
        """What the receivers at positions ``active`` (default: all) believe at ``step``: the
        pairs (a, j), a the position in ``active``, j a sender row ≠ the receiver, heard within
        the timeout, sorted by (a, j); and the senders' (x, y, cos θ, sin θ) of each pair,
        dead-reckoned to t_step if the model says so (elementwise, so a receiver's pairs do
        not depend on which other receivers are asked for)."""
        stamp, other = self.stamp, self.other
        if active is not None:
            stamp, other = stamp[active], other[active]
        age = step - stamp
        max_age = model.max_age_steps()
        a, j = np.nonzero((stamp >= 0) & (age <= max_age) & other)
        age = age[a, j]
        rows = active[a] if active is not None else a
        if a.size <= MESSAGES_ONCE:
            return (a, j) + self._predicted(step, model, rows, j, age)
        # every receiver of the message (j, stamp) holds the same state: predict and frame each
        # message once (N × distinct ages, not N²), elementwise, so the same bits
        msg = age * len(self.other[0]) + j
        first = np.zeros((max_age + 1) * len(self.other[0]), dtype=np.intp)
        first[msg] = np.arange(msg.size)
        seen = np.zeros(first.size, dtype=bool)
        seen[msg] = True
        one = first[seen]                                       # a pair of each message
        back = (np.cumsum(seen) - 1)[msg]                       # pair → its message's row
        return (a, j) + tuple(v[back] for v in self._predicted(step, model, rows[one], j[one], age[one]))

    def _predicted(self, step, model, rows, j, age):
        """(x, y, cos θ, sin θ) of the beliefs (rows, j) of the given ages, dead-reckoned to
        t_step if the model says so."""
        x, y, qz, qw, u = self.state[:, rows, j]
        if model.dead_reckoning and np.any(age > 0):
            pos, qz, qw = dead_reckon(np.stack([x, y], axis=1), qz, qw, u, age * model.dt, moved=age > 0)
            x, y = pos[:, 0], pos[:, 1]
        return (x, y) + frame_from_quaternion(qz, qw)

    def table(self, i: int, step: int, model: CommModel):
        """Rows (agent indices, ascending) receiver ``recv[i]`` knows at ``step``, its own row
        included, and the others' (x, y, cos θ, sin θ) (`known_pairs`)."""
        _, j, x, y, c, s = self.known_pairs(step, model, np.array([i]))
        return np.union1d(j, [self.recv[i]]), x, y, c, s


def dead_reckon(pos, qz, qw, u, horizon, moved=None):
    """States (pos (R, 2), unit quaternion) predicted ``horizon`` (R,) sim seconds ahead at unit
    speed with constant u on the exact arc (`zoh_step`: θ' = θ + uh, r' = r + h sinc(uh/2)
    (cos, sin)(θ + uh/2)); rows where ``moved`` is False are returned unchanged (bit for bit).
    Returns (pos, qz, qw).

    θ enters only through the sent quaternion, by the angle-sum identities: (cos θ, sin θ) =
    `frame_from_quaternion`, and the half angle θ'/2 = θ/2 + uh/2 is the quaternion turned by
    uh/2, so sin and cos of uh/2 are the only ones evaluated (the compiled radio,
    `fast_run_kernels._dead_reckon`, does the same sums)."""
    pos, qz, qw, horizon = (np.asarray(v, float) for v in (pos, qz, qw, horizon))
    half = np.multiply(u, 0.5 * horizon)                        # uh/2
    sh, ch = np.sin(half), np.cos(half)
    zero = half == 0.0
    chord = (sh + zero) / (half + zero) * horizon               # h sinc(uh/2)
    c, s = frame_from_quaternion(qz, qw)
    p2 = np.empty((len(half), 2))
    p2[:, 0] = (c * ch - s * sh) * chord + pos[:, 0]            # cos(θ + uh/2)
    p2[:, 1] = (s * ch + c * sh) * chord + pos[:, 1]            # sin(θ + uh/2)
    qz2, qw2 = qz * ch + qw * sh, qw * ch - qz * sh
    if moved is None:
        return p2, qz2, qw2
    m = np.asarray(moved, bool)
    return (np.where(m[:, None], p2, pos), np.where(m, qz2, qz), np.where(m, qw2, qw))


def delay_stats(delay_counts, dt: float) -> dict:
    """Mean/max measured delay (sim s) from a histogram of delays in steps."""
    tot = int(delay_counts.sum())
    if tot == 0:
        return dict(messages=0, mean_delay=None, max_delay=None)
    steps = np.arange(delay_counts.size)
    return dict(messages=tot, mean_delay=float((steps * delay_counts).sum() / tot * dt),
                max_delay=float(steps[delay_counts > 0].max() * dt))


# ---------------------------------------------------------------- runtime events, realtime radio

RADIO_EVENT_KINDS = ('drop', 'partition', 'comms')


def change_from_event(ev) -> dict | None:
    """The radio change of a ``/swarm/events`` object (docs/ros-graph.md), None if the
    event is not for the radio (other kinds, or the scenario's own scheduled events, which
    agents apply from their copy); ValueError naming the field if it is malformed."""
    if not isinstance(ev, dict):
        raise ValueError('an event is a JSON object')
    kind = ev.get('kind')
    if kind not in RADIO_EVENT_KINDS or ev.get('source') == 'scenario':
        return None
    if kind == 'drop':
        change = dict(drop=ev.get('loss'), duration=ev.get('duration'))
        if change['drop'] is None:
            raise ValueError('drop event without loss')
    elif kind == 'partition':
        groups = ev.get('groups') or []
        if not isinstance(groups, list) or not all(isinstance(g, list) and all(isinstance(s, str) for s in g)
                                                   for g in groups):
            raise ValueError('partition groups must be lists of agent names')
        change = dict(partition=groups)
    else:
        change = {k: ev.get(k) for k in ('loss', 'latency', 'jitter')}
    for key in ('drop', 'loss', 'latency', 'jitter'):
        v = change.get(key)
        if v is None:
            continue
        v = float(v)
        if not (math.isfinite(v) and v >= 0.0 and (key in ('latency', 'jitter') or v <= 1.0)):
            raise ValueError(f'{key}={change[key]!r} out of range')
    dur = change.get('duration')
    if dur is not None and not (math.isfinite(float(dur)) and float(dur) > 0.0):
        raise ValueError(f'duration={dur!r} must be > 0')
    return change


class StreamRadio:
    """The receive side of one realtime agent (row ``index``): states arrive one by one with
    their stamp t; the fate of each is `CommModel.decide` for step round(t/dt), so a state is
    lost or held in flight until t + delay exactly as in the batch engine (DDS delays come on
    top).  `table(now)` gives the newest delivered state of every sender heard within the
    timeout, dead-reckoned to ``now``.  A state is (t, x, y, qz, qw, u); in 3D
    (`natural_radio.NaturalStreamRadio`) (t, r, x, y, z, u, v)."""

    #: where a state holds the sender's position, and how many controls end it
    POSITION, CONTROLS = slice(1, 3), 1

    def __init__(self, model: CommModel, index: int):
        self.model = model
        self.index = int(index)
        n = len(model.names)
        self.newest = {}                      # sender row -> its newest state delivered
        self.in_flight = []                   # (release time, sender row, state)
        self.heard = np.zeros(n, dtype=np.int64)
        self.delivered = np.zeros(n, dtype=np.int64)

    def hear(self, j: int, state, own_xy) -> bool:
        """A state of sender row j arrives (``own_xy``: this agent's position); True if the radio
        delivers it."""
        t = float(state[0])
        m = int(round(t / self.model.dt))
        self.heard[j] += 1
        arr = int(self.model.decide(m, [self.index], np.reshape(np.asarray(own_xy, float), (1, -1)),
                                    [j], [state[self.POSITION]])[0, 0])
        if arr < 0:
            return False
        self.delivered[j] += 1
        self.in_flight.append((t + (arr - m) * self.model.dt, int(j), tuple(float(v) for v in state)))
        return True

    def release(self, now: float):
        """Deliver what is due by ``now`` (newest stamp wins)."""
        keep = []
        for rel, j, st in self.in_flight:
            if rel <= now + 1e-9:
                if j not in self.newest or st[0] > self.newest[j][0]:
                    self.newest[j] = st
            else:
                keep.append((rel, j, st))
        self.in_flight = keep

    def table(self, now: float, own_state):
        """(rows, states (R, 4) of x, y, qz, qw): the senders known at ``now`` and this agent's
        own row (own_state = x, y, qz, qw), in agent-index order, dead-reckoned to now (3D:
        states (R, 12) of r, x, y, z)."""
        self.model.advance_to(int(round(now / self.model.dt)))
        self.release(now)
        rows = sorted([j for j, st in self.newest.items()
                       if now - st[0] <= self.model.timeout + 1e-9 and j != self.index] + [self.index])
        own = (now, *own_state) + (0.0,) * self.CONTROLS
        st = np.array([self.newest[j] if j != self.index else own for j in rows], dtype=float)
        age = now - st[:, 0]
        if self.model.dead_reckoning:
            self._dead_reckon(st, np.maximum(age, 0.0), (age > 0) & (np.array(rows) != self.index))
        return np.array(rows, dtype=np.intp), st[:, 1:-self.CONTROLS]

    def _dead_reckon(self, st, age, moved):
        """The states ``st`` (rows of `newest`) predicted ``age`` ahead where ``moved``, in place."""
        pos, qz, qw = dead_reckon(st[:, 1:3], st[:, 3], st[:, 4], st[:, 5], age, moved)
        st[:, 1:3], st[:, 3], st[:, 4] = pos, qz, qw
