"""Validation of incoming inputs, shared by the world, the commander and the agents (no ROS
import): agent states, who may speak for an agent, polygons, processes that may be signalled,
the rate-limited one-line-per-kind rejection log, and the guard that keeps any message from
ending a node (`guard_subscriptions`)."""
from __future__ import annotations

import functools
import math
import os
import secrets
import time
import traceback

import numpy as np

from swarm_ros import protocol as P
from swarm_ros.layouts import BadMessage

#: most points a /world/barrier polygon may have (more is refused: the law reads the hull each step)
MAX_BARRIER_POINTS = 1000

#: sim seconds a state's stamp may be ahead of the receiver's clock (realtime)
FUTURE_TOLERANCE = 2.0

#: a sim time past this is none a node can take: the seconds of a ROS stamp are an int32
MAX_SIM_TIME = 2.0 ** 31


class Reason(str):
    """Why an input is rejected: the one-line text; ``kind`` is the log key (no values in it)."""
    kind = 'other'


def reason(kind: str, text: str) -> Reason:
    r = Reason(text)
    r.kind = kind
    return r


def check_step_time(s):
    """Why a decoded /lockstep/step (`layouts.Step`) must be rejected (a `Reason`): its time is
    no sim time a stamp can hold (NaN, negative, past `MAX_SIM_TIME`); or None."""
    if 0.0 <= s.t < MAX_SIM_TIME:
        return None
    return reason('step-time', f'/lockstep/step for step {s.n}: t={s.t!r} is not a sim time in [0, {MAX_SIM_TIME:g}) s')


def check_decision_time(d, now, tolerance=FUTURE_TOLERANCE):
    """Why a decoded /swarm/decision (`layouts.RealtimeDecision`) must be rejected (a `Reason`):
    its time is no sim time (NaN, negative, past `MAX_SIM_TIME`), or it is more than
    ``tolerance`` sim s ahead of the receiver's clock ``now``: a decision from the future, which
    the commander of the run never sends (a peer's, with the run id copied); or None."""
    if not 0.0 <= d.t < MAX_SIM_TIME:
        return reason('decision-time', f'{P.DECISION} of step {d.n}: t={d.t!r} is not a sim time in '
                      f'[0, {MAX_SIM_TIME:g}) s')
    if d.t > now + tolerance:
        return reason('decision-future', f'{P.DECISION} stamped t={d.t:.3f}, ahead of this clock t={now:.3f} '
                      f'by more than {tolerance:g} s (a decision from the future)')
    return None


def check_state(msg, row, newest, now=None, tolerance=FUTURE_TOLERANCE):
    """Why a /swarm/states message must be rejected (a `Reason`), 'repeat' for an exact repeat
    of the newest accepted state of that agent, or None to accept it.

    Rejected: an unknown agent name; a non-finite pose or twist; a pose that is not a planar
    unit quaternion; a stamp older than the newest one of that agent (a stamp from the past);
    a stamp more than ``tolerance`` s ahead of the receiver's clock ``now`` (a stamp from the
    future: it would make every true state after it look old); a different state with the
    same stamp as the newest one of that agent (two publishers using one name)."""
    p = msg.pose.pose
    o = p.orientation
    return check_values(msg.child_frame_id, P.stamp_to_time(msg.header.stamp),
                        (p.position.x, p.position.y, o.x, o.y, o.z, o.w), msg.twist.twist.angular.z,
                        row, newest, now, tolerance)


def _future_text(name, t, now, tolerance):
    return (f'state of {name!r} stamped t={t:.3f}, ahead of this clock t={now:.3f} by more than '
            f'{tolerance:g} s (a stamp from the future)')


def _past_text(name, t, t0):
    return f'state of {name!r} stamped t={t:.3f}, older than its newest t={t0:.3f} (a stamp from the past)'


def _duplicate_text(name, t):
    return f'second, different state of {name!r} for t={t:.3f}: duplicate agent name (two publishers?)'


def check_values(name, t, pose, wz, row, newest, now=None, tolerance=FUTURE_TOLERANCE):
    """`check_state` on decoded values: pose = (x, y, qx, qy, qz, qw), wz = twist.angular.z."""
    if name not in row:
        return reason('unknown-agent', f'state from unknown agent {name[:40]!r}')
    x, y, qx, qy, qz, qw = pose
    vals = (x, y, qz, qw)
    isfinite = math.isfinite
    if not (isfinite(x) and isfinite(y) and isfinite(qz) and isfinite(qw) and isfinite(wz) and isfinite(t)):
        return reason('non-finite', f'state of {name!r} with a non-finite pose/twist/stamp {vals + (wz, t)}')
    if abs(qz ** 2 + qw ** 2 - 1.0) > 1e-6 or qx or qy:
        return reason('not-planar', f'state of {name!r}: orientation is not a planar unit quaternion')
    if now is not None and t > now + tolerance:
        return reason('future-stamp', _future_text(name, t, now, tolerance))
    if name in newest:
        t0 = newest[name][0]
        if t < t0:
            return reason('past-stamp', _past_text(name, t, t0))
        if t == t0:
            if tuple(newest[name][1:5]) == vals:
                return 'repeat'
            return reason('duplicate', _duplicate_text(name, t))
    return None


def decoded(cls, raw: bytes, run_id: str, reject, kind: str):
    """The lockstep message ``cls`` (a `swarm_ros.layouts` message class) in ``raw``, or None
    after logging with ``reject`` (a `RejectLog`) why it is refused: it carries another run's id
    (kind ``other-run``: a second run on the ROS_DOMAIN_ID; a node without a ``run_id`` takes
    any), a value that must be finite is not (``non-finite``), or it is malformed (``kind``)."""
    try:
        return cls.from_cdr(raw, run_id)
    except BadMessage as err:
        reject(err.kind or kind, f'{cls.LAYOUT.topic}: {err}')
        return None


def refused(reject, why) -> bool:
    """True if a state must be dropped: ``why`` is a `Reason` (logged with ``reject``, a
    `RejectLog`) or 'repeat' (an exact repeat: dropped silently)."""
    if why is None:
        return False
    if why != 'repeat':
        reject(why.kind, why)
    return True


class Senders:
    """Binds each agent name to the first sender heard for it and rejects the others.

    ``sender``: what identifies the publisher: its DDS gid where rclpy's message info has one
    (``publisher_gid``, rclpy ≥ 9.1), else the sender tag the agents put in their states
    (`protocol.SENDER_TAG_INDEX`); None = unknown (not checked)."""

    def __init__(self):
        self.bound = {}

    def check(self, name, sender):
        first = self.bound.get(name)
        if sender is None or first is None or first == sender:
            return None
        return reason('second-publisher', f'state of {name!r} from a second publisher (sender '
                      f'{_show(sender)}; the name is bound to {_show(first)}, its first)')

    def accept(self, name, sender):
        """A state of ``name`` from ``sender`` was taken: bind the name if it is not yet."""
        if sender is not None:
            self.bound.setdefault(name, sender)


#: `ProcessSenders.check`'s mask of one row taken (read-only: shared)
_ONE_TRUE = np.ones(1, bool)
_ONE_TRUE.flags.writeable = False


class ProcessSenders:
    """Lockstep: binds each agent (row) to the first agent process whose
    ``/lockstep/agent_states`` carried it (its sender tag), as `Senders` does per name."""

    def __init__(self, n):
        self.tag = np.full(int(n), np.nan)

    def check(self, index, tag):
        """(rows to take: a bool mask over ``index``, a `Reason` for the others or None)."""
        if index.size == 1:                              # a lone agent: no array work
            bound = self.tag[index[0]]
            if bound != bound or bound == tag:
                return _ONE_TRUE, None
        bound = self.tag[index]
        ok = (bound != bound) | (bound == tag)           # unbound (NaN) or this sender
        if ok.all():
            return ok, None
        return ok, reason('second-publisher', f'/lockstep/agent_states from a second process (sender '
                          f'{_show(float(tag))}) for {int((~ok).sum())} agents bound to another one')

    def accept(self, index, tag):
        if index.size == 1:
            if self.tag[index[0]] != self.tag[index[0]]:
                self.tag[index[0]] = tag
            return
        unbound = self.tag[index] != self.tag[index]
        self.tag[index[unbound]] = tag


def check_agent_states(index, vals, n, topic=P.LOCK_AGENT_STATES):
    """Why a decoded ``/lockstep/agent_states`` (`layouts.AgentStates`) or, ``topic``,
    ``/swarm/agent_states`` (`layouts.ProcessStates`), whose decoders check that every value is
    finite, must be rejected as a whole (a `Reason`), or None: an agent index outside the roster
    or twice, an orientation that is not a planar unit quaternion."""
    if index.size == 0:
        return None
    if index.size == 1:                                  # a lone agent's state: plain floats, no array work
        top, qz, qw = index.item(0), vals.item(2, 0), vals.item(3, 0)
        off = abs(qz * qz + qw * qw - 1.0)
    else:
        top, off = int(index.max()), np.abs(vals[2] * vals[2] + vals[3] * vals[3] - 1.0).max()
    if top >= n:
        return reason('unknown-agent', f'{topic} with agent index {top} (the roster has {n})')
    if index.size > 1 and np.unique(index).size != index.size:
        return reason('duplicate', f'{topic} names an agent twice')
    if off > 1e-6:
        return reason('not-planar', f'{topic}: an orientation is not a planar unit quaternion')
    return None


def batch_ok(msg, roster, own_tag, reject) -> bool:
    """Is a decoded ``/swarm/agent_states`` message (`layouts.ProcessStates`, whose decoder
    checked the run id and that every value is finite) one to read?  Not the reader's own
    process's (``own_tag``), nor, logged with ``reject``, one naming an agent outside
    ``roster`` or twice, or with an orientation that is not planar.  Its states are then
    checked at once, each as one /swarm/states message is (`NewestStates.take`)."""
    check = check_agent_states if len(msg.pose) == 4 else check_natural_pose
    return msg.tag != own_tag and not refused(reject, check(msg.index, msg.pose, len(roster), P.AGENT_STATES))


_EYE = np.eye(3)


def check_natural_pose(index, pose, n, topic=P.AGENT_STATES):
    """`check_agent_states` of a 3D run's states (``pose`` (12, K): r, x, y, z): an agent index
    outside the roster or twice, a frame [x y z] that is not orthonormal (1e-6)."""
    if index.size == 0:
        return None
    if int(index.max()) >= n:
        return reason('unknown-agent', f'{topic} with agent index {int(index.max())} (the roster has {n})')
    if index.size > 1 and np.unique(index).size != index.size:
        return reason('duplicate', f'{topic} names an agent twice')
    f = pose[3:].T.reshape(-1, 3, 3)                                 # (K, 3, 3): rows x, y, z
    if len(f) == 1:                                                  # one state: plain floats are cheaper
        (a, b, c), (d, e, g), (h, i, j) = f[0].tolist()
        off = max(abs(a * a + b * b + c * c - 1.0), abs(d * d + e * e + g * g - 1.0), abs(h * h + i * i + j * j - 1.0),
                  abs(a * d + b * e + c * g), abs(a * h + b * i + c * j), abs(d * h + e * i + g * j))
    else:
        gram = f @ f.transpose(0, 2, 1)
        gram -= _EYE
        off = np.abs(gram).max()
    if not off <= 1e-6:                                              # (NaN too; the decoder refuses it first)
        return reason('not-a-frame', f'{topic}: a frame [x y z] is not orthonormal')
    return None


def _show(sender):
    if isinstance(sender, (bytes, bytearray)):
        return bytes(sender).hex()[:12] + '…'
    if isinstance(sender, float) and sender.is_integer():
        return str(int(sender))
    return repr(sender)


def new_sender_tag() -> float:
    """A random sender tag (an integer 1..2^31 as a float: exact in a float64)."""
    return float(secrets.randbits(31) + 1)


def check_barrier(points):
    """Why a /world/barrier polygon must be rejected (a `Reason`), or None."""
    if len(points) > MAX_BARRIER_POINTS:
        return reason('barrier-size', f'{P.BARRIER} with {len(points)} points (at most {MAX_BARRIER_POINTS})')
    if not all(math.isfinite(v) for q in points for v in q):
        return reason('barrier-finite', f'{P.BARRIER}: a point is not finite')
    return None


# ------------------------------------------------------------------ rejection log

class RejectLog:
    """Logs rejected inputs, one line per KIND (the key: no values in it), rate-limited.

    The first rejection of a kind is logged at once; later ones of that kind at most once every
    ``interval`` s, saying how many were suppressed since.  At most ``max_kinds`` kinds are
    tracked (any further kind counts as 'other'), so memory stays bounded whatever arrives.
    ``count``: all rejections; ``lines``: the lines logged (at most 1000, for tests)."""

    def __init__(self, logger, interval=10.0, max_kinds=64, clock=time.monotonic):
        self.logger = logger
        self.interval = interval
        self.max_kinds = max_kinds
        self.clock = clock
        self.kinds = {}          # kind -> [time last logged, suppressed since, total]
        self.count = 0
        self.lines = []

    def __call__(self, kind, text):
        self.count += 1
        kind = str(kind)
        if kind not in self.kinds and len(self.kinds) >= self.max_kinds:
            kind = 'other'
        now = self.clock()
        st = self.kinds.get(kind)
        if st is None:
            self.kinds[kind] = [now, 0, 1]
            self._log(f'rejected {text}')
            return
        st[2] += 1
        if now - st[0] >= self.interval:
            self._log(f'rejected {text} ({st[1]} more of this kind in the last {now - st[0]:.0f} s)')
            st[0], st[1] = now, 0
        else:
            st[1] += 1

    def _log(self, line):
        if len(self.lines) < 1000:
            self.lines.append(line)
        self.logger.warning(line)

    def summary(self):
        """One line with the count per kind ('' if nothing was rejected)."""
        if not self.count:
            return ''
        return f'rejected {self.count} inputs in all: ' + ', '.join(
            f'{k} {st[2]}' for k, st in sorted(self.kinds.items(), key=lambda kv: -kv[1][2]))


# ------------------------------------------------------------------ no message ends a node

#: the log key of a message a callback could not read (`guarded`): this prefix and the topic
UNREADABLE = 'unreadable'


def guarded(callback, reject, topic: str, passes=()):
    """``callback`` of a subscription on ``topic``, such that no message ends the node: an
    exception it raises (a malformed message, a value a check did not foresee) is counted and
    logged with ``reject`` (a `RejectLog`; kind ``unreadable:<topic>``), and the message is
    dropped.  ``passes``: exception classes that go on to the executor (an error of the run
    itself that must stop the node, e.g. a law that failed).  The wrapper keeps the
    callback's signature: rclpy reads from it whether to pass the message info too."""
    if getattr(callback, 'guarded', False):
        return callback

    @functools.wraps(callback)
    def run(*args):
        try:
            return callback(*args)
        except passes:
            raise
        except Exception as err:
            reject(f'{UNREADABLE}:{topic}', f'{topic}: a message this node cannot read, dropped '
                   f'({type(err).__name__}: {str(err)[:120]}; raised at {_where(err)})')
            return None
    run.guarded = True
    return run


def _where(err: BaseException) -> str:
    """``module.py:LINE in function`` of the deepest frame of this project's code that ``err``
    passed through (else its deepest frame): where to look, in one line."""
    frames = traceback.extract_tb(err.__traceback__)
    ours = [f for f in frames if any(f'/{pkg}/' in f.filename for pkg in _PACKAGES)]
    f = (ours or frames or [None])[-1]
    return '?' if f is None else f'{os.path.basename(f.filename)}:{f.lineno} in {f.name}'


#: this project's packages (`_where`)
_PACKAGES = ('swarm_core', 'swarm_ros', 'swarm_agent', 'swarm_world', 'homotopy_commander', 'swarm_robots',
             'swarm_tools')


def guard_subscriptions(node, reject, passes=()) -> int:
    """Guard (`guarded`) the callback of every subscription of ``node`` (an rclpy node) not
    guarded yet, rclpy's own ``/clock`` reader included (a negative stamp raises in it);
    returns how many were guarded.  A node calls it once its readers are made, and again
    after it makes another one.  The first call also hooks a post-set parameter callback that
    guards again: ``ros2 param set NODE use_sim_time true`` makes rclpy's ``/clock`` reader then."""
    if not getattr(node, '_guard_after_sets', False):
        node._guard_after_sets = True
        node.add_post_set_parameters_callback(lambda _params: guard_subscriptions(node, reject, passes))
    count = 0
    for sub in list(node.subscriptions):
        if not getattr(sub.callback, 'guarded', False):
            sub.callback = guarded(sub.callback, reject, sub.topic_name, passes)
            count += 1
    return count


# ------------------------------------------------------------------ processes

def proc_info(pid: int, proc='/proc'):
    """(parent pid, argv list) of a live process, or None (gone, or a zombie)."""
    try:
        with open(f'{proc}/{int(pid)}/stat', 'rb') as f:
            stat = f.read().decode('utf-8', 'replace')
        with open(f'{proc}/{int(pid)}/cmdline', 'rb') as f:
            argv = [a.decode('utf-8', 'replace') for a in f.read().split(b'\0') if a]
    except (OSError, ValueError):
        return None
    fields = stat[stat.rfind(')') + 2:].split()          # after "pid (comm) "
    if not fields or fields[0] in ('Z', 'X'):
        return None
    return int(fields[1]), argv


def may_signal(pid, agent: str, launcher: int, proc='/proc'):
    """Why agent ``agent``'s pid ``pid`` (from the pid file) must NOT be signalled, or None.

    Signalled are only live children of the run's launcher (``launcher``: the world's own parent
    pid) whose command line is that agent's node: the ``swarm_agent`` executable with
    ``__ns:=/<agent>``.  Anything else (a pid reused by another process, an edited pid file)
    is refused."""
    try:
        pid = int(pid)
    except (TypeError, ValueError):
        return f'pid {pid!r} of {agent} is not a number'
    if pid <= 1 or pid == launcher:
        return f'pid {pid} of {agent} is not an agent process'
    info = proc_info(pid, proc)
    if info is None:
        return f'pid {pid} of {agent} is not running'
    ppid, argv = info
    if ppid != launcher:
        return f'pid {pid} of {agent} is not a child of this run\'s launcher (pid {launcher}; its parent is {ppid})'
    exe = any(a.endswith('swarm_agent') or a.endswith('swarm_agent/agent_node.py') for a in argv[:3])
    if not exe or f'__ns:=/{agent}' not in argv:
        return f'pid {pid} is not the agent process of {agent} (command line {" ".join(argv)[:120]!r})'
    return None


class NewestStates:
    """The newest accepted state of each agent of a roster of ``n`` as arrays: ``t`` (n,) (−inf:
    none yet), ``state`` (n, 4) x, y, qz, qw, ``u`` (n,) and the process each agent is bound
    to (``tag``, NaN: none).  `take` checks a whole decoded ``/swarm/agent_states`` message at
    once, each state as `check_values` and `Senders` check one ``/swarm/states`` message (its
    decoder and `check_agent_states` did the rest); ``own`` (n,) marks the reader's own agents,
    whose states only it may send."""

    def __init__(self, n, width=4, controls=()):
        self.t = np.full(int(n), -np.inf)
        self.state = np.zeros((int(n), width))     # a 3D run's: r, x, y, z (12)
        self.u = np.zeros((int(n), *controls))     # a 3D run's: (u, v)
        self.tag = np.full(int(n), np.nan)
        self.own = np.zeros(int(n), bool)

    def put(self, i, t, state, u):
        """Agent i's state, taken (the reader's own, or checked)."""
        self.t[i] = t
        self.state[i] = state
        self.u[i] = u

    def by_name(self, roster) -> dict:
        """name -> (t, x, y, qz, qw, u) of the agents heard, in roster order."""
        return {roster[i]: (float(self.t[i]), *map(float, self.state[i]), float(self.u[i]))
                for i in np.flatnonzero(np.isfinite(self.t))}

    def take(self, msg, roster, now, tolerance, reject):
        """(K,) bool: the states of ``msg`` (`layouts.ProcessStates`) taken as the agents' newest;
        each refused one logged with ``reject`` by kind, as `check_values` words it (an exact
        repeat of the newest state is dropped silently)."""
        i, t, pose = msg.index, msg.t, msg.pose.T
        t0 = self.t[i]
        same = t == t0
        repeat = same & (pose == self.state[i]).all(axis=1)
        bound = self.tag[i]
        why = [('dup-self', self.own[i], lambda j: f'state claiming to be {roster[i[j]]!r} (an agent of this '
                'process) from another publisher: duplicate agent name'),
               ('future-stamp', t > now + tolerance, lambda j: _future_text(roster[i[j]], t[j], now, tolerance)),
               ('past-stamp', t < t0, lambda j: _past_text(roster[i[j]], t[j], t0[j])),
               (None, repeat, None),
               ('duplicate', same, lambda j: _duplicate_text(roster[i[j]], t[j])),
               ('second-publisher', (bound == bound) & (bound != msg.tag), lambda j: f'state of '
                f'{roster[i[j]]!r} from a second publisher (sender {_show(msg.tag)}; the name is bound to '
                f'{_show(float(bound[j]))}, its first)')]
        ok = np.ones(len(i), bool)
        for kind, bad, text in why:
            bad = bad & ok
            if bad.any():
                if kind is not None:
                    reject(kind, reason(kind, text(int(np.flatnonzero(bad)[0]))))
                ok &= ~bad
        take = i[ok]
        self.t[take], self.state[take], self.u[take] = t[ok], pose[ok], msg.u[ok]
        self.tag[take[self.tag[take] != self.tag[take]]] = msg.tag
        return ok
