"""``swarm view``: a running swarm's topics, live, over the Foxglove WebSocket protocol.

A live view for users without RViz: open ``ws://HOST:PORT`` in the Foxglove app and import
the shipped layout (`LAYOUT_FILE`).  ``swarm run ... --foxglove [PORT]`` starts this bridge as a
process of the run; ``swarm view`` starts it next to a swarm that already runs.

Built on the ``foxglove-sdk`` WebSocket server:

* every ROS topic with a publisher is a channel: message encoding ``cdr`` (the ROS 2 bytes as
  they came), schema ``ros2msg`` named ``pkg/msg/Type`` holding the full definition with its
  dependencies, built by the recorder's `swarm_tools.bags.msgdefs.message_definition` (what rosbag2 and
  foxglove_bridge send);
* a topic is read from ROS only while a client subscribes to its channel (as foxglove_bridge
  does), with the QoS its publishers offer (`swarm_tools.bags.record.request_qos`);
* each message is logged at sim time: its own stamp (``header.stamp``, or the time that opens a
  ``rosgraph_msgs/Clock``) if its type has one, else the newest sim time seen; the server also
  sends that time to clients (capability ``time``);
* ``/world/metrics`` (string values) is also served as numbers on `METRICS_CHANNEL` (JSON), so
  that the Plot panel can draw clusters and polarisation;
* clients may publish (capability ``clientPublish``, encodings ``cdr`` and ``json``) on
  `client_topic` topics only: ``/swarm/lambda`` and the agents' ``/<agent>/steering``, as
  ``std_msgs/msg/Float64``.  Each value is republished on ROS as a user's
  ``ros2 topic pub`` would (`publish_client_value`), if its `Bound` (λ or steering) takes it;
  the commander checks it too.

No writer ends the view: a topic is served with one type (the project's own for its topics,
as the recorder does, `record.Recorder.topic_type`), a writer of another type is not served,
and a message or a look at the graph that fails is counted and logged once (`reject`).
"""
from __future__ import annotations

import argparse
import json
import queue
import re
import sys
import time
from pathlib import Path
from types import SimpleNamespace

from swarm_core.checks import LAMBDA_BOUND, STEERING_BOUND
from swarm_core.files import write_atomic
from swarm_ros import protocol as P
from swarm_ros.msg_checks import RejectLog, guard_subscriptions
from swarm_ros.rosutil import make_executor, stop_on_signals
from swarm_tools.bags.mcap_io import parse_float64
from swarm_tools.bags.msgdefs import DefinitionNotFound, has_leading_stamp, leading_stamp_ns, message_definition
from swarm_tools.bags.record import message_class, offered_profiles, request_qos, swarm_type

DEFAULT_PORT = 8765
#: where the shipped layout lives (regenerate it with ``swarm view --write-layout FILE``)
LAYOUT_FILE = Path(__file__).with_name('foxglove_layout.json')
LAMBDA_TOPIC = '/swarm/lambda'
METRICS_TOPIC = '/world/metrics'
METRICS_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
#: numbers of ``/world/metrics`` as a JSON channel (the Plot panel needs numbers, not strings)
METRICS_CHANNEL = '/foxglove/metrics'
METRICS_KEYS = ('t', 'lambda', 'clusters', 'polarisation', 'min_distance')
#: the only type clients may publish, by the names clients use for it
CLIENT_TYPES = ('std_msgs/msg/Float64', 'std_msgs/Float64')
#: client message encodings, in the order foxglove_bridge lists them
CLIENT_ENCODINGS = ['cdr', 'json']
_STEERING = re.compile(r'/[A-Za-z_][A-Za-z0-9_]*/steering')
#: the ROS graph is polled this often for new topics (wall seconds)
POLL_PERIOD = 1.0
#: the server's time is sent to clients at most this often (wall seconds)
TIME_PERIOD = 0.05


class ClientMessageError(ValueError):
    pass


def client_topic(topic: str) -> bool:
    """Whether a Foxglove client may publish on ``topic``: λ and the agents' steering."""
    return topic == LAMBDA_TOPIC or bool(_STEERING.fullmatch(topic))


def client_bound(topic: str):
    """The `Bound` of a client's value on ``topic`` (a `client_topic`): λ or a steering s_k."""
    return LAMBDA_BOUND if topic == LAMBDA_TOPIC else STEERING_BOUND


def client_float64(encoding: str, data: bytes) -> float:
    """The value of a client's ``std_msgs/msg/Float64`` message, JSON (``{"data": 1.0}``) or CDR."""
    if encoding == 'json':
        try:
            obj = json.loads(bytes(data).decode('utf-8'))
        except (UnicodeDecodeError, ValueError) as err:
            raise ClientMessageError(f'not JSON: {err}') from None
        v = obj.get('data') if isinstance(obj, dict) else None
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ClientMessageError(f'JSON {obj!r}: want {{"data": number}}')
        return float(v)
    if encoding == 'cdr':
        data = bytes(data)
        if len(data) < 12 or data[0] != 0 or data[1] not in (0, 1):
            raise ClientMessageError(f'{len(data)} bytes: not a CDR std_msgs/msg/Float64')
        return parse_float64(data)
    raise ClientMessageError(f'encoding {encoding!r}: want one of {", ".join(CLIENT_ENCODINGS)}')


def metrics_numbers(values: dict) -> dict:
    """The numeric entries of a ``/world/metrics`` status (key -> string) as floats."""
    out = {}
    for k in METRICS_KEYS:
        try:
            out[k] = float(values[k])
        except (KeyError, TypeError, ValueError):
            continue
    return out


def layout_json() -> str:
    """The shipped Foxglove layout, in the form the app exports and imports (``configById`` +
    a mosaic ``layout``): markers in 3D (seen from above), λ, clusters and polarisation over
    time, and a Publish panel for λ."""
    def plot(value, label):
        return {'paths': [{'value': value, 'enabled': True, 'label': label,
                           'timestampMethod': 'receiveTime'}],
                'showLegend': True, 'legendDisplay': 'floating', 'showXAxisLabels': True,
                'showYAxisLabels': True, 'isSynced': True, 'xAxisVal': 'timestamp',
                'foxglovePanelTitle': label}
    config = {
        '3D!swarm': {
            'followTf': 'world', 'followMode': 'follow-none',
            'cameraState': {'perspective': False, 'distance': 80.0, 'phi': 0.0, 'thetaOffset': 0.0,
                            'target': [0, 0, 0], 'targetOffset': [0, 0, 0],
                            'targetOrientation': [0, 0, 0, 1], 'fovy': 45, 'near': 0.5, 'far': 5000},
            'scene': {}, 'transforms': {}, 'layers': {},
            'topics': {'/world/markers': {'visible': True}},
            'foxglovePanelTitle': 'swarm (/world/markers)'},
        'Plot!lambda': plot(f'{LAMBDA_TOPIC}.data', 'λ'),
        'Plot!clusters': plot(f'{METRICS_CHANNEL}.clusters', 'clusters'),
        'Plot!polarisation': plot(f'{METRICS_CHANNEL}.polarisation', 'polarisation'),
        'Publish!lambda': {'topicName': LAMBDA_TOPIC, 'datatype': 'std_msgs/msg/Float64',
                           'buttonText': 'Publish λ', 'buttonTooltip': 'set λ (the commander ramps to it)',
                           'advancedView': True, 'value': '{"data": 1.0}',
                           'foxglovePanelTitle': 'set λ'},
    }
    right = {'direction': 'column', 'splitPercentage': 25, 'first': 'Plot!lambda',
             'second': {'direction': 'column', 'splitPercentage': 33, 'first': 'Plot!clusters',
                        'second': {'direction': 'column', 'splitPercentage': 50,
                                   'first': 'Plot!polarisation', 'second': 'Publish!lambda'}}}
    doc = {'configById': config, 'globalVariables': {}, 'userNodes': {},
           'playbackConfig': {'speed': 1},
           'layout': {'direction': 'row', 'splitPercentage': 62, 'first': '3D!swarm', 'second': right}}
    return json.dumps(doc, indent=2, ensure_ascii=False) + '\n'


class Bridge:
    """The ROS side of the view: channels from the graph, ROS readers while clients read,
    client publications to ROS.  The server's callbacks (its own thread) only queue work;
    `step` does it on the ROS thread."""

    def __init__(self, node, server_factory, log=print):
        import foxglove
        self.fg = foxglove
        self.node = node
        self.log = log
        #: what could not be served (a message, a reader, a look at the graph), counted
        self.reject = RejectLog(SimpleNamespace(warning=lambda line: log(f'swarm view: {line}')))
        self.work: queue.Queue = queue.Queue()
        self.channels: dict[str, object] = {}      # topic -> foxglove Channel
        self.types: dict[str, str] = {}
        self.stamped: dict[str, bool] = {}
        self.subs: dict[str, object] = {}          # topic -> ROS subscription (while read)
        self.pubs: dict[str, object] = {}          # client topic -> ROS publisher
        self.client_channels: dict[tuple, tuple] = {}   # (client, channel) -> (topic, encoding)
        self.skipped: set[str] = set()
        self.sim_ns = 0
        self.sent_ns = 0
        self.last_time = 0.0
        self.published = 0
        self.metrics = foxglove.Channel(METRICS_CHANNEL, schema={
            'type': 'object', 'properties': {k: {'type': 'number'} for k in METRICS_KEYS}})
        self.server = server_factory(_Listener(self))
        self.port = self.server.port
        self._client_publisher(LAMBDA_TOPIC)
        self._advertise(METRICS_TOPIC, METRICS_TYPE)     # read always: numbers and sim time
        self._read(METRICS_TOPIC)
        self.poll()

    # ---------------------------------------------------------------- graph
    def _own(self, info):
        return info.node_name == self.node.get_name() and info.node_namespace == self.node.get_namespace()

    def poll(self):
        """Channels for new topics; publishers for new steering topics; drop idle readers.
        What fails is counted and logged (`reject`); the next poll goes on."""
        try:
            self._poll()
        except Exception as err:
            self.reject('poll', f'a look at the graph failed ({type(err).__name__}: {str(err)[:120]})')

    def _poll(self):
        try:
            names = self.node.get_topic_names_and_types()
        except Exception:       # the context is going down
            return
        for topic, types in names:
            if client_topic(topic) and topic not in self.pubs and CLIENT_TYPES[0] in types:
                self._client_publisher(topic)     # ready (and matched) before a client publishes
            if topic in self.channels or topic in self.skipped:
                continue
            infos = [i for i in self.node.get_publishers_info_by_topic(topic) if not self._own(i)]
            if infos:            # the project's type for its topics: a writer of another type is not served
                self._advertise(topic, swarm_type(topic) or infos[0].topic_type or types[0])
        for topic in list(self.subs):
            if topic != METRICS_TOPIC and not self.channels[topic].has_sinks():
                self._unread(topic)

    def _advertise(self, topic, type_name):
        try:
            text = message_definition(type_name)
        except DefinitionNotFound as err:
            self.log(f'swarm view: not serving {topic}: {err}')
            self.skipped.add(topic)
            return
        self.types[topic] = type_name
        self.stamped[topic] = has_leading_stamp(text, type_name)
        self.channels[topic] = self.fg.Channel(
            topic, message_encoding='cdr',
            schema=self.fg.Schema(name=type_name, encoding='ros2msg', data=text.encode()))

    # ---------------------------------------------------------------- ROS -> clients
    def _read(self, topic):
        """Subscribe to an advertised topic as its publishers offer (no publisher yet:
        reliable, volatile), as the recorder does."""
        if topic in self.subs or topic not in self.channels:
            return
        infos = [i for i in self.node.get_publishers_info_by_topic(topic) if not self._own(i)]
        qos = request_qos(offered_profiles([i for i in infos if i.topic_type == self.types[topic]]))
        events = None
        if client_topic(topic):
            # λ and steering: the reader of the commander's transient-local output does not
            # match a command's volatile writer (ours, ros2 topic pub's), by design: no warning
            from rclpy.event_handler import SubscriptionEventCallbacks
            events = SubscriptionEventCallbacks(incompatible_qos=lambda _status: None)
        try:
            self.subs[topic] = self.node.create_subscription(
                message_class(self.types[topic]), topic, self._callback(topic), qos, raw=True,
                event_callbacks=events)
        except Exception as err:      # a type rclpy cannot read or refuses here
            self.reject(f'subscribe:{topic}', f'{topic} ({self.types[topic]}): cannot read it ({str(err)[:120]})')
            return
        guard_subscriptions(self.node, self.reject)

    def _unread(self, topic):
        sub = self.subs.pop(topic, None)
        if sub is not None:
            self.node.destroy_subscription(sub)

    def _callback(self, topic):
        channel = self.channels[topic]
        stamped = self.stamped[topic]
        metrics = topic == METRICS_TOPIC

        def on_message(data):
            t = leading_stamp_ns(data) if stamped else None
            if t is not None and t >= 0:
                self.sim_ns = max(self.sim_ns, t)
            else:
                t = self.sim_ns
            channel.log(bytes(data), log_time=t)
            if metrics and self.metrics.has_sinks():
                self._log_metrics(data, t)
        return on_message

    def _log_metrics(self, data, t):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.serialization import deserialize_message
        try:
            msg = deserialize_message(bytes(data), DiagnosticArray)
        except Exception:
            return
        for st in msg.status:
            nums = metrics_numbers({kv.key: kv.value for kv in st.values})
            if nums:
                self.metrics.log(nums, log_time=t)

    # ---------------------------------------------------------------- clients -> ROS
    def _client_publisher(self, topic):

        # reliable, volatile, keep last 10: what `ros2 topic pub` offers
        from std_msgs.msg import Float64
        self.pubs[topic] = self.node.create_publisher(Float64, topic, P.qos_reliable(10))

    def publish_client_value(self, topic, value):
        """The one place where a client's value enters ROS: a std_msgs/Float64 on ``topic``
        (``/swarm/lambda`` or a steering topic), as ``ros2 topic pub`` would send it."""
        from std_msgs.msg import Float64
        if topic not in self.pubs:
            self._client_publisher(topic)
        pub = self.pubs[topic]
        if pub.get_subscription_count() == 0:
            self.log(f'swarm view: {topic}: no reader matched yet; {value:g} may be lost')
        pub.publish(Float64(data=float(value)))
        self.published += 1
        self.log(f'swarm view: client set {topic} = {value:g}')

    def client_advertised(self, client_id, channel):
        key = (client_id, channel.id)
        why = None
        if not client_topic(channel.topic):
            why = f'{channel.topic}: clients may publish on {LAMBDA_TOPIC} and /<agent>/steering only'
        elif channel.schema_name not in CLIENT_TYPES:
            why = f'{channel.topic}: type {channel.schema_name!r}, want std_msgs/msg/Float64'
        elif channel.encoding not in CLIENT_ENCODINGS:
            why = f'{channel.topic}: encoding {channel.encoding!r}, want cdr or json'
        if why:
            self.status(f'refused: {why}')
            return
        self.client_channels[key] = (channel.topic, channel.encoding)

    def client_message(self, client_id, channel_id, data):
        topic, encoding = self.client_channels.get((client_id, channel_id), (None, None))
        if topic is None:
            return                         # refused at advertisement (already said why)
        try:
            value = client_float64(encoding, data)
        except ClientMessageError as err:
            self.status(f'{topic}: {err}')
            return
        if not client_bound(topic).ok(value):
            self.status(f'{topic}: {client_bound(topic).error(value)}')
            return
        self.work.put(('publish', topic, value))

    def status(self, text):
        self.log(f'swarm view: {text}')
        try:
            self.server.publish_status(text, self.fg.StatusLevel.Warning)
        except Exception:
            pass

    # ---------------------------------------------------------------- main loop
    def step(self):
        """Queued work (subscriptions, client publications) and the server's time."""
        while True:
            try:
                item = self.work.get_nowait()
            except queue.Empty:
                break
            try:
                if item[0] == 'subscribe':
                    self._read(item[1])
                elif item[0] == 'publish':
                    self.publish_client_value(item[1], item[2])
            except Exception as err:      # the graph or a topic changed under it: counted, the view goes on
                self.reject(item[0], f'{item[1]}: could not {item[0]} ({type(err).__name__}: {str(err)[:120]})')
        now = time.monotonic()
        if self.sim_ns != self.sent_ns and now - self.last_time >= TIME_PERIOD:
            self.server.broadcast_time(self.sim_ns)
            self.sent_ns, self.last_time = self.sim_ns, now

    def close(self):
        for topic in list(self.subs):
            self._unread(topic)
        self.server.stop()


class _Listener:
    """foxglove-sdk ServerListener: called on the server's thread; hands work to the bridge."""

    def __init__(self, bridge: Bridge):
        self.b = bridge

    def on_subscribe(self, client, channel):
        self.b.work.put(('subscribe', channel.topic))

    def on_unsubscribe(self, client, channel):
        pass                               # `Bridge.poll` drops readers nobody reads

    def on_client_advertise(self, client, channel):
        self.b.client_advertised(client.id, channel)

    def on_client_unadvertise(self, client, client_channel_id):
        self.b.client_channels.pop((client.id, client_channel_id), None)

    def on_message_data(self, client, client_channel_id, data):
        self.b.client_message(client.id, client_channel_id, data)


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog='swarm view',
        description='Serve a running swarm live to the Foxglove app (Foxglove WebSocket protocol: '
                    'ROS 2 CDR with ros2msg schemas, sim-time stamps; clients may publish λ on '
                    f'{LAMBDA_TOPIC} and steering on /<agent>/steering). In Foxglove: Open '
                    'connection -> Foxglove WebSocket -> ws://HOST:PORT; then import the layout '
                    f'{LAYOUT_FILE.name} (see --write-layout).')
    p.add_argument('--port', type=int, default=DEFAULT_PORT,
                   help=f'TCP port (default {DEFAULT_PORT}; 0: any free port, printed at start)')
    p.add_argument('--host', default='127.0.0.1',
                   help='address to listen on (default 127.0.0.1; 0.0.0.0 for other machines)')
    p.add_argument('--write-layout', metavar='FILE',
                   help='write the Foxglove layout to FILE and exit')
    a = p.parse_args(argv)
    if not 0 <= a.port <= 65535:
        p.error(f'--port {a.port}: must be in 0..65535')
    return a


def main(argv=None) -> int:
    import foxglove
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.write_layout:
        try:
            write_atomic(args.write_layout, layout_json())
        except OSError as err:
            print(f'swarm view: cannot write {args.write_layout}: {err.strerror or err}', file=sys.stderr)
            return 2
        print(f'swarm view: wrote {args.write_layout}')
        return 0


    def factory(listener):
        return foxglove.start_server(
            name='homotopy-swarm', host=args.host, port=args.port, server_listener=listener,
            capabilities=[foxglove.Capability.ClientPublish, foxglove.Capability.Time],
            supported_encodings=list(CLIENT_ENCODINGS))

    stop, wake, restore = stop_on_signals()
    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('swarm_view', enable_rosout=False, start_parameter_services=False)
    log = lambda s: print(s, file=sys.stderr, flush=True)
    try:
        try:
            bridge = Bridge(node, factory, log=log)
        except Exception as err:      # e.g. the port is taken
            print(f'swarm view: cannot serve on {args.host}:{args.port}: {err}', file=sys.stderr)
            return 2
        print(f'swarm view: serving on ws://{args.host}:{bridge.port} (Foxglove: Open connection '
              f'-> Foxglove WebSocket; layout: {LAYOUT_FILE})', flush=True)
        ex = make_executor(node.context)
        ex.add_node(node)
        next_poll = time.monotonic() + POLL_PERIOD
        while not stop and rclpy.ok():
            ex.spin_once(timeout_sec=0.05)
            bridge.step()
            if time.monotonic() >= next_poll:
                bridge.poll()
                next_poll = time.monotonic() + POLL_PERIOD
        bridge.close()
        log(f'swarm view: stopped; {bridge.published} client message(s) published to ROS'
            + (f'; {bridge.reject.summary()}' if bridge.reject.count else ''))
        return 0
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        restore()


if __name__ == '__main__':
    sys.exit(main())
