"""Control paths belong to the run (no ROS import): the checks of the messages that can stop,
steer or drive an agent or a robot, shared by the world, the agents, the agent containers and
the MuJoCo robot world (docs/security.md).

- **Events** (``/swarm/events``): every node of a run writes its events with the run's id
  (`event_text`).  A node with a run id acts on, and the world records, only the events of its
  own run (`run_event`); a node without one takes any, as with the packed lockstep messages.
- **Robot commands** (``/<agent>/cmd_vel`` into the MuJoCo world): a robot agent's
  ``header.frame_id`` carries the run id and a sender tag of its own (`command_frame`); the
  robot world takes a robot's commands from its own run only, and from the first tag it took
  for that robot (`CommandSenders`).
- **One writer per topic** (``/lockstep/robot_states``): the reader binds the topic to the
  first sender tag it takes (`FirstSender`).
"""
from __future__ import annotations

import json

from swarm_core.checks import json_value
from swarm_core.command.plan import MAX_EVENT_CHARS
from swarm_ros import protocol as P
from swarm_ros.msg_checks import Reason, _show, reason

#: the key of an event's run id
RUN_KEY = 'run_id'


class EventRefused(ValueError):
    """A ``/swarm/events`` text not to act on; ``kind``: the log key."""

    def __init__(self, kind: str, text: str):
        super().__init__(text)
        self.kind = kind


def event_text(ev: dict, run_id: str) -> str:
    """The ``/swarm/events`` text of an event (a dict) of run ``run_id``."""
    return json.dumps(dict(ev, **{RUN_KEY: run_id}))


def run_event(text: str, run_id: str) -> dict:
    """The event (a dict, without its run id) in a ``/swarm/events`` text of run ``run_id``;
    `EventRefused` for one to ignore: not a JSON object (kind ``event-json``), or, when
    ``run_id`` is set, of another run or of none (kind ``other-run``)."""
    ev = _json_object(text, P.EVENTS, 'event-json', 'event')
    if not isinstance(ev, dict):
        raise EventRefused('event-json', f'{P.EVENTS}: an event is a JSON object, not {text[:80]!r}')
    return _of_run(ev, run_id, P.EVENTS, f'event {str(ev.get("kind"))[:40]!r}')


def _json_object(text: str, topic: str, kind: str, what: str):
    """The JSON value of a message's ``text`` (with the limits of every input); `EventRefused`
    of ``kind`` naming ``topic`` for one that is not JSON."""
    try:
        return json_value(text, MAX_EVENT_CHARS)
    except ValueError as err:
        raise EventRefused(kind, f'{topic}: not a JSON {what} ({str(err)[:80]}): {text[:80]!r}') from None


def _of_run(msg: dict, run_id: str, topic: str, what: str) -> dict:
    """``msg`` without its run id; `EventRefused` (kind ``other-run``) when ``run_id`` is set and
    the message's is another or none (``what``: the message in words)."""
    got = msg.pop(RUN_KEY, '')
    if run_id and got != run_id:
        raise EventRefused('other-run', f'{topic}: {what} of run {str(got)[:40] or "(none)"!r}, '
                           f'not this run {run_id!r}: ignored')
    return msg


class FirstSender:
    """Binds a topic that one process of the run writes to the first sender tag taken on it;
    a message with another tag is refused (`check`)."""

    def __init__(self, topic: str):
        self.topic = topic
        self.tag = None

    def check(self, tag) -> Reason | None:
        """None if ``tag`` is the bound one (the first: it binds), else the `Reason`."""
        if self.tag is None:
            self.tag = tag
        if tag == self.tag:
            return None
        return reason('second-publisher', f'{self.topic} from a second publisher (sender {_show(tag)}; the '
                      f'topic is bound to {_show(self.tag)}, its first)')


def command_frame(agent: str, run_id: str, tag: float) -> str:
    """The ``header.frame_id`` of a robot agent's commands to a robot of the MuJoCo world: its
    ``base_link`` frame, the run id and the sender tag, ``agent_0/base_link run=ab12 tag=7``."""
    return f'{agent}/base_link run={run_id} tag={int(tag)}'


def command_sender(frame_id: str) -> tuple[str, int]:
    """(run id, tag) of a command's ``frame_id`` (`command_frame`); ('', 0) where it has none
    (a command from ``ros2 topic pub`` or a driver of another project)."""
    fields = dict(w.split('=', 1) for w in frame_id.split(' ')[1:] if '=' in w)
    tag = fields.get('tag', '')
    return fields.get('run', ''), int(tag) if tag.isdigit() and len(tag) <= 12 else 0


class CommandSenders:
    """The robot world's check of its robots' commands (``topics``: each robot's ``cmd_vel``):
    a command of another run, or of none while the world has a run id, is refused (kind
    ``other-run``), and so is one with another tag than the first taken for that robot."""

    def __init__(self, run_id: str, topics):
        self.run_id = run_id
        self.first = [FirstSender(t) for t in topics]

    def check(self, k: int, frame_id: str) -> Reason | None:
        run, tag = command_sender(frame_id)
        if self.run_id and run != self.run_id:
            return reason('other-run', f'{self.first[k].topic}: command of run {run[:40] or "(none)"!r}, not this '
                          f'run {self.run_id!r}')
        return self.first[k].check(tag)


def decode_command(raw: bytes, stamped: bool) -> tuple:
    """(sec, nanosec, linear.x, angular.z, frame_id) of a serialized ``TwistStamped``
    (``stamped``; else ``Twist``: stamp 0, frame '') by `protocol.cdr_to_twist`; ValueError for
    bytes that are not one."""
    try:
        sec, nsec, v, omega = P.cdr_to_twist(raw, stamped)
        frame = P.cdr_string(raw, 12, P.cdr_byte_order(raw))[0] if stamped else ''
    except Exception as err:              # struct.error, IndexError: too short, a bad length
        kind = 'TwistStamped' if stamped else 'Twist'
        raise ValueError(f'not a serialized {kind} ({len(raw)} bytes: {str(err)[:60]})') from None
    return sec, nsec, v, omega, frame


# ---------------------------------------------------------------- the commander's commands (lockstep)

#: kinds of message on ``/lockstep/command``: the commander takes part; a live command
FORWARD_KINDS = ('ready', 'command')


def forward_text(kind: str, run_id: str, tag: float, seq: int, command=None) -> str:
    """A ``/lockstep/command`` text: the lockstep commander tells the world that it takes part
    (``ready``: the recorder reads its outputs, if it waits for one) or hands it a live
    ``command`` (`swarm_core.command.plan.check_command`), numbered ``seq`` from 1, under its
    sender tag.  The world decides each step and applies the command at its next one."""
    msg = {RUN_KEY: run_id, 'tag': float(tag), 'seq': int(seq), 'kind': kind}
    if command is not None:
        msg['command'] = command
    return json.dumps(msg)


def forwarded(text: str, run_id: str) -> dict:
    """The message in a ``/lockstep/command`` text of run ``run_id`` (with ``tag``, ``seq``,
    ``kind`` and, for a command, ``command``); `EventRefused` for one to ignore: not such an
    object (kind ``command-json``), or of another run (kind ``other-run``)."""
    msg = _json_object(text, P.LOCK_COMMAND, 'command-json', 'message')
    if (not isinstance(msg, dict) or msg.get('kind') not in FORWARD_KINDS
            or not isinstance(msg.get('tag'), float) or isinstance(msg.get('seq'), bool)
            or not isinstance(msg.get('seq'), int)
            or (msg['kind'] == 'command') != isinstance(msg.get('command'), dict)):
        raise EventRefused('command-json', f'{P.LOCK_COMMAND}: not a commander message: {text[:80]!r}')
    return _of_run(msg, run_id, P.LOCK_COMMAND, 'message')
