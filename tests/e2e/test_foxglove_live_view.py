"""The live view of a run (``swarm run --foxglove``) seen by an independent client.

The client is a plain WebSocket client (the ``websockets`` package) that speaks the Foxglove
WebSocket protocol as published in github.com/foxglove/ws-protocol ``docs/spec.md``
(subprotocol ``foxglove.websocket.v1``, which foxglove-sdk serves under the name
``foxglove.sdk.v1``; JSON ops ``serverInfo``, ``advertise``, ``subscribe``,
client ``advertise``; binary server opcode 1 = message data ``u32 subscription id, u64 log
time, payload``, opcode 2 = time ``u64``; binary client opcode 1 = ``u32 client channel id,
payload``).  Messages are decoded with rosbags' own CDR deserializer from the ``ros2msg``
schema text the server advertises (not with the project's parsers), and the client's λ is
serialised by rosbags too.
"""
from __future__ import annotations

import json
import struct
import time

from tests.helpers import Lines, short_homotopy

#: what the Foxglove app offers; foxglove-sdk >= 0.1x accepts only the first (the same wire
#: protocol as ws-protocol's v1 under a new name), so the server must pick it
SUBPROTOCOLS = ['foxglove.sdk.v1', 'foxglove.websocket.v1']


# ------------------------------------------------------------------ live
class Client:
    """A Foxglove WebSocket protocol client after docs/spec.md (no Foxglove library)."""

    def __init__(self, ws):
        self.ws = ws
        assert ws.subprotocol in SUBPROTOCOLS
        self.info = None
        self.channels = {}          # topic -> advertised channel
        self.statuses = []
        self.times = []
        self.messages = {}          # subscription id -> [(log time, payload)]

    def pump(self, timeout=0.2):
        from websockets.exceptions import ConnectionClosed
        try:
            msg = self.ws.recv(timeout=timeout)
        except TimeoutError:
            return
        except ConnectionClosed:
            raise AssertionError('the server closed the connection') from None
        if isinstance(msg, str):
            m = json.loads(msg)
            if m['op'] == 'serverInfo':
                self.info = m
            elif m['op'] == 'advertise':
                for ch in m['channels']:
                    self.channels[ch['topic']] = ch
            elif m['op'] == 'status':
                self.statuses.append(m)
        elif msg[0] == 1:
            sub, t = struct.unpack_from('<IQ', msg, 1)
            self.messages.setdefault(sub, []).append((t, bytes(msg[13:])))
        elif msg[0] == 2:
            self.times.append(struct.unpack_from('<Q', msg, 1)[0])

    def until(self, cond, timeout, what):
        end = time.monotonic() + timeout
        while not cond():
            assert time.monotonic() < end, f'timed out waiting for {what}'
            self.pump()

    def send(self, obj):
        self.ws.send(json.dumps(obj))


def _typestore(channel):
    """rosbags' deserializer for an advertised ros2msg channel (from the schema text alone)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    assert channel['encoding'] == 'cdr' and channel['schemaEncoding'] == 'ros2msg', channel
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(channel['schema'], channel['schemaName']))
    return store


def test_live_view_serves_states_markers_and_takes_lambda(ros_domain, processes, swarm_cmd, tmp_path):
    """One realtime run with ``--foxglove 0``: the client subscribes to /swarm/states,
    /world/markers and /swarm/lambda, decodes them (rosbags, from the advertised schemas),
    is refused on a topic clients may not publish on, and publishes λ = 1 on /swarm/lambda
    (CDR, as Foxglove's Publish panel does on a ROS 2 server): the commander then ramps its
    published λ up from 0."""
    import subprocess
    scn = short_homotopy(tmp_path / 'view.yaml', duration=3000, lam='{kind: constant, value: 0.0}', at=1e6, dt=0.1)
    run = processes.start([swarm_cmd, 'run', scn, '--mode', 'realtime', '--foxglove', '0',
                           '--out', tmp_path / 'out', '--no-figure', '--progress-every', '1000'],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    lines = Lines(run)
    assert lines.wait_for('swarm view: serving on ws://', 120), ''.join(lines.lines)
    url = next(ln for ln in lines.lines if 'serving on ws://' in ln).split('serving on ')[1].split()[0]
    from websockets.sync.client import connect
    with connect(url, subprotocols=SUBPROTOCOLS, open_timeout=30, max_size=None) as ws:
        _talk(Client(ws))
    assert run.poll() is None, ''.join(lines.lines)
    out = ''.join(lines.lines)
    assert lines.wait_for('swarm view: client set /swarm/lambda = 1', 30), out


def _talk(c):
    c.until(lambda: c.info is not None, 30, 'serverInfo')
    assert {'clientPublish', 'time'} <= set(c.info['capabilities']), c.info
    assert 'cdr' in c.info.get('supportedEncodings', []), c.info
    wanted = ('/swarm/states', '/world/markers', '/swarm/lambda', '/agent_0/steering')
    c.until(lambda: all(t in c.channels for t in wanted + ('/foxglove/metrics',)), 120,
            f'channels {wanted}; got {sorted(c.channels)}')
    stores = {t: _typestore(c.channels[t]) for t in wanted}
    # full definitions: dependencies concatenated in the ros2msg layout
    assert 'MSG: geometry_msgs/Pose' in c.channels['/swarm/states']['schema']
    assert 'MSG: visualization_msgs/Marker' in c.channels['/world/markers']['schema']
    c.send({'op': 'subscribe', 'subscriptions': [
        {'id': i + 1, 'channelId': c.channels[t]['id']} for i, t in enumerate(wanted)]
        + [{'id': 99, 'channelId': c.channels['/foxglove/metrics']['id']}]})

    def decoded(i):
        t = wanted[i]
        return [(ts, stores[t].deserialize_cdr(raw, c.channels[t]['schemaName']))
                for ts, raw in c.messages.get(i + 1, [])]

    names, read = set(), [0]

    def state_names():
        """The agents heard on /swarm/states so far (the bridge's reader discovers their writers
        one by one: on a loaded machine the first 30 states came from two agents)."""
        got = c.messages.get(1, [])
        names.update(stores[wanted[0]].deserialize_cdr(raw, c.channels[wanted[0]]['schemaName']).child_frame_id
                     for _, raw in got[read[0]:])
        read[0] = len(got)
        return names

    c.until(lambda: len(c.messages.get(1, [])) >= 30 and len(state_names()) >= 3 and c.messages.get(2)
            and c.messages.get(3) and c.messages.get(99), 120, 'states of 3 agents, markers, λ and metrics')
    states = decoded(0)
    assert names <= {f'agent_{i}' for i in range(6)} and len(names) >= 3, names
    for ts, m in states:      # logged at sim time: the state's own stamp
        assert m.header.frame_id == 'world'
        assert ts == m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
    assert max(ts for ts, _ in states) < 3000 * 1_000_000_000        # sim time, not wall time
    ts, markers = decoded(1)[-1]
    agents = [m for m in markers.markers if m.ns == 'agents']
    assert len(agents) == 6 and all(m.header.frame_id == 'world' for m in agents)
    assert ts == agents[0].header.stamp.sec * 1_000_000_000 + agents[0].header.stamp.nanosec
    assert c.times and max(c.times) < 3000 * 1_000_000_000
    assert all(m.data == 0.0 for _, m in decoded(2)), [m.data for _, m in decoded(2)]
    assert c.channels['/foxglove/metrics']['encoding'] == 'json'
    ts, metrics = c.messages[99][-1]
    metrics = json.loads(metrics)
    assert metrics['clusters'] >= 1 and 0 <= metrics['polarisation'] <= 1 and metrics['lambda'] == 0.0
    assert abs(ts - metrics['t'] * 1e9) < 1e3, (ts, metrics)      # logged at the metrics' sim time

    # a topic clients may not publish on is refused with a status
    c.send({'op': 'advertise', 'channels': [{'id': 7, 'topic': '/swarm/states', 'encoding': 'cdr',
                                             'schemaName': 'nav_msgs/msg/Odometry'}]})
    c.until(lambda: any('/swarm/states' in s['message'] for s in c.statuses), 30, 'a refusal status')

    # λ = 1 from the client, CDR serialised by rosbags
    f64 = stores['/swarm/lambda']
    payload = f64.serialize_cdr(f64.types['std_msgs/msg/Float64'](data=1.0), 'std_msgs/msg/Float64')
    c.send({'op': 'advertise', 'channels': [{'id': 1, 'topic': '/swarm/lambda', 'encoding': 'cdr',
                                             'schemaName': 'std_msgs/msg/Float64'}]})
    c.ws.send(struct.pack('<BI', 1, 1) + bytes(payload))
    # the commander ramps from 0 to 1 (its ramp parameter): values strictly between come from it only
    c.until(lambda: any(0.001 < m.data < 0.999 for _, m in decoded(2)), 120,
            'the commander to publish a rising λ')
    # (the client's raw λ goes to the commander only: /swarm/lambda as served is the λ in force)

    # steering as JSON (Foxglove's fallback encoding): agent_0 becomes a leader, and the
    # commander publishes its new program value on every tick (the client sent it once)
    c.send({'op': 'advertise', 'channels': [{'id': 2, 'topic': '/agent_0/steering', 'encoding': 'json',
                                             'schemaName': 'std_msgs/msg/Float64'}]})
    c.ws.send(struct.pack('<BI', 1, 2) + b'{"data": 0.02}')
    c.until(lambda: sum(m.data == 0.02 for _, m in decoded(3)) >= 3, 120,
            'the commander to steer agent_0 with 0.02')
