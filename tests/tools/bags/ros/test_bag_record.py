"""The recorder (`swarm record`) against small publisher nodes of the test's own.

A known sequence of Odometry states (several agents, lockstep-like: every agent's state of a
step, then the next step), λ values, a /clock and latched target / barrier messages are
published; the recorder, a separate process, is stopped with SIGINT (or SIGKILL) and the bag
is read back with two independent readers.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np

N_AGENTS = 4
STEPS = 60


def _wait(pred, timeout, spin=None):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if pred():
            return True
        if spin is not None:
            spin()
        else:
            time.sleep(0.05)
    return pred()


class Publishers:
    """The test's publishers: states, λ, clock (volatile) and target, barrier (latched)."""

    def __init__(self, ctx):
        import rclpy
        from geometry_msgs.msg import Point32, PointStamped, PolygonStamped
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import Float64

        self.node = rclpy.create_node('bag_test_pub', context=ctx)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)
        deep = QoSProfile(depth=2000, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.states = self.node.create_publisher(Odometry, '/swarm/states', deep)
        self.lam = self.node.create_publisher(Float64, '/swarm/lambda', deep)
        self.clock = self.node.create_publisher(Clock, '/clock', deep)
        self.target = self.node.create_publisher(PointStamped, '/world/target', latched)
        self.barrier = self.node.create_publisher(PolygonStamped, '/world/barrier', latched)
        self.Odometry, self.Float64, self.Clock = Odometry, Float64, Clock
        # latched messages go out before any recorder exists
        t = PointStamped()
        t.header.frame_id = 'world'
        t.point.x, t.point.y = 12.5, -3.25
        self.target.publish(t)
        b = PolygonStamped()
        b.header.frame_id = 'world'
        b.polygon.points = [Point32(x=float(x), y=float(y)) for x, y in [(5, 5), (6, 5), (6, 6)]]
        self.barrier.publish(b)
        self.volatile = [self.states, self.lam, self.clock]

    def spin(self):
        self.ex.spin_once(timeout_sec=0.02)

    def matched(self):
        return all(p.get_subscription_count() >= 1 for p in self.volatile)

    def state(self, k, i, dt=0.05):
        m = self.Odometry()
        t_ns = int(round(k * dt * 1e9))
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
        m.header.frame_id = 'world'
        m.child_frame_id = f'agent_{i}'
        th = 0.1 * i + 0.01 * k
        m.pose.pose.position.x = float(i + 0.5 * k)
        m.pose.pose.position.y = float(np.sin(0.1 * k + i))
        m.pose.pose.orientation.z = float(np.sin(th / 2))
        m.pose.pose.orientation.w = float(np.cos(th / 2))
        m.twist.twist.linear.x = 1.0
        m.twist.twist.angular.z = float(0.001 * k - 0.01 * i)
        return m

    def publish_run(self, steps, pace=0.0, until=None):
        """Publish ``steps`` steps, or fewer once ``until()`` is true; returns the steps published."""
        for k in range(steps):
            if until is not None and until():
                return k
            c = self.Clock()
            t_ns = int(round(k * 0.05 * 1e9))
            c.clock.sec, c.clock.nanosec = divmod(t_ns, 1_000_000_000)
            self.clock.publish(c)
            self.lam.publish(self.Float64(data=k / steps))
            for i in range(N_AGENTS):
                self.states.publish(self.state(k, i))
            self.spin()
            if pace:
                time.sleep(pace)
        return steps

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()


def _on_disk(out, want, counts=False):
    """True once the (possibly unfinished) file at ``out`` holds ``want`` {topic: count}."""
    from collections import Counter

    from swarm_tools.bags.mcap_io import iter_messages
    got = Counter()
    path = out / f'{out.name}_0.mcap' if out.is_dir() else out     # --out DIR: DIR/DIR_0.mcap
    if path.is_file():
        got.update(m.topic for m in iter_messages(path, stats={}))
    if counts:
        return dict(got)
    return all(got[t] >= n for t, n in want.items())


def _start_recorder(processes, swarm_cmd, out, *extra):
    return processes.start([swarm_cmd, 'record', '--out', out, *extra],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _record(rclpy_context, processes, swarm_cmd, out, steps, *, stop_signal=signal.SIGINT,
            pace=0.0, extra=()):
    pubs = Publishers(rclpy_context)
    try:
        rec = _start_recorder(processes, swarm_cmd, out, *extra)
        if not _wait(pubs.matched, 30, pubs.spin):
            os.killpg(rec.pid, signal.SIGINT)
            said = rec.communicate(timeout=30)
            raise AssertionError(f'recorder never subscribed (readers of states, λ, clock: '
                                 f'{[p.get_subscription_count() for p in pubs.volatile]}); it said: {said}')
        # the recorder has subscribed to the volatile topics: the run starts
        pubs.publish_run(steps, pace)
        # stop only once everything published is in the file (chunks are closed every 0.5 s)
        want = {'/swarm/states': steps * N_AGENTS, '/swarm/lambda': steps, '/clock': steps}
        assert _wait(lambda: _on_disk(out, want), 60, pubs.spin), \
            f'the recorder never wrote {want}: {_on_disk(out, want, counts=True)}'
        os.killpg(rec.pid, stop_signal)
        out_text, err_text = rec.communicate(timeout=30)
        return rec.returncode, out_text, err_text, pubs
    finally:
        pubs.close()


def _expected_states(pubs, steps):
    return [pubs.state(k, i) for k in range(steps) for i in range(N_AGENTS)]


def test_recorded_run_reads_back_with_two_readers(rclpy_context, processes, swarm_cmd, tmp_path):
    from mcap_ros2.reader import read_ros2_messages
    from rclpy.serialization import serialize_message
    from rosbags.highlevel import AnyReader

    from swarm_tools.bags.mcap_io import parse_odometry

    out = tmp_path / 'run.mcap'
    t_start = time.time_ns()
    rc, stdout, stderr, pubs = _record(rclpy_context, processes, swarm_cmd, out, STEPS)
    t_end = time.time_ns()
    assert rc == 0, stderr + stdout
    assert 'lost: 0' in stdout, stdout
    assert f'/swarm/states: {N_AGENTS} agents, {STEPS}..{STEPS} states each, missing between ' \
           'first and last: 0' in stdout, stdout
    expected = _expected_states(pubs, STEPS)
    counts = {'/swarm/states': STEPS * N_AGENTS, '/swarm/lambda': STEPS, '/clock': STEPS,
              '/world/target': 1, '/world/barrier': 1}

    # reader 1: rosbags (its own CDR deserializer, from the bag's message definitions)
    with AnyReader([out]) as reader:
        got = {}
        states = []
        for conn, _t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            got[conn.topic] = got.get(conn.topic, 0) + 1
            if conn.topic == '/swarm/states':
                states.append(msg)
            if conn.topic == '/world/target':
                assert (msg.point.x, msg.point.y) == (12.5, -3.25)
        for topic, n in counts.items():
            assert got.get(topic) == n, (topic, got)
        assert len(states) == len(expected)
        for m, e in zip(states, expected):
            assert m.child_frame_id == e.child_frame_id
            assert (m.header.stamp.sec, m.header.stamp.nanosec) == (e.header.stamp.sec,
                                                                    e.header.stamp.nanosec)
            assert m.pose.pose.position.x == e.pose.pose.position.x
            assert m.pose.pose.position.y == e.pose.pose.position.y
            assert m.pose.pose.orientation.z == e.pose.pose.orientation.z
            assert m.twist.twist.angular.z == e.twist.twist.angular.z

    # reader 2: mcap_ros2's decoder; raw bytes equal the publisher's serialization too
    got2 = {}
    odo = []
    for m in read_ros2_messages(str(out)):
        got2[m.channel.topic] = got2.get(m.channel.topic, 0) + 1
        assert m.channel.message_encoding == 'cdr'
        assert m.schema.encoding == 'ros2msg'
        if m.channel.topic == '/swarm/states':
            odo.append(m)
            # as rosbag2: publish time = send time, log time = receive time, both wall time
            # (this test's run is at sim t = 0..3 s); sim time is in the header stamp
            st = m.ros_msg.header.stamp
            assert st.sec * 1_000_000_000 + st.nanosec < 10 * 1_000_000_000
        if m.channel.topic in ('/swarm/states', '/swarm/lambda', '/clock'):
            assert t_start <= m.publish_time_ns <= m.log_time_ns <= t_end, m.channel.topic
    assert {t: got2.get(t) for t in counts} == counts
    for m, e in zip(odo, expected):
        assert m.ros_msg.child_frame_id == e.child_frame_id
        assert m.ros_msg.pose.pose.position.x == e.pose.pose.position.x
        assert m.ros_msg.twist.twist.angular.z == e.twist.twist.angular.z

    # the raw CDR equals what the publisher serialised; the report's own parser agrees
    from mcap.reader import make_reader
    with open(out, 'rb') as f:
        raws = [msg.data for _s, ch, msg in make_reader(f).iter_messages(topics=['/swarm/states'])]
    assert raws == [serialize_message(e) for e in expected]
    p = parse_odometry(raws[5])
    assert (p['child_frame_id'], p['x'], p['wz']) == (expected[5].child_frame_id,
                                                      expected[5].pose.pose.position.x,
                                                      expected[5].twist.twist.angular.z)


def test_bag_metadata_as_rosbag2_writes_it(rclpy_context, processes, swarm_cmd, tmp_path):
    from mcap.reader import make_reader

    from swarm_tools.bags.mcap_io import parse_qos_yaml
    from swarm_tools.bags.msgdefs import SEPARATOR

    out = tmp_path / 'meta.mcap'
    rc, stdout, stderr, _ = _record(rclpy_context, processes, swarm_cmd, out, 5,
                                    extra=('--exclude', '/rosout', '/parameter_events'))
    assert rc == 0, stderr
    with open(out, 'rb') as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert header.profile == 'ros2'
    assert summary is not None and summary.chunk_indexes, 'no chunk index: not a finished file'
    assert all(ci.compression == 'zstd' for ci in summary.chunk_indexes)
    topics = {ch.topic: ch for ch in summary.channels.values()}
    assert '/rosout' not in topics and '/parameter_events' not in topics
    schemas = {s.name: s for s in summary.schemas.values()}
    odo = schemas['nav_msgs/msg/Odometry']
    text = odo.data.decode()
    # top-level text first, then each dependency once, depth first
    assert text.startswith(Path(_share('nav_msgs', 'Odometry')).read_text())
    heads = [line for line in text.splitlines() if line.startswith('MSG: ')]
    assert len(heads) == len(set(heads))
    assert {'MSG: std_msgs/Header', 'MSG: builtin_interfaces/Time', 'MSG: geometry_msgs/Pose',
            'MSG: geometry_msgs/Vector3'} <= set(heads)
    assert f'\n{SEPARATOR}\nMSG: std_msgs/Header\n' in text
    # depth first: Header's own dependency (Time) comes right after Header
    assert heads.index('MSG: builtin_interfaces/Time') == heads.index('MSG: std_msgs/Header') + 1
    # offered QoS: latched topics recorded as transient_local, the others volatile
    target_qos = parse_qos_yaml(topics['/world/target'].metadata['offered_qos_profiles'])
    states_qos = parse_qos_yaml(topics['/swarm/states'].metadata['offered_qos_profiles'])
    assert [q['durability'] for q in target_qos] == ['transient_local']
    assert [q['durability'] for q in states_qos] == ['volatile']
    assert states_qos[0]['reliability'] == 'reliable'
    assert set(states_qos[0]) >= {'history', 'depth', 'deadline', 'lifespan', 'liveliness',
                                  'liveliness_lease_duration', 'avoid_ros_namespace_conventions'}
    # rosbag2's own metadata record (version 9): topics, types, counts, QoS as a list
    import yaml
    info = yaml.safe_load(metadata['rosbag2']['serialized_metadata'])['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    meta_topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    counts = summary.statistics.channel_message_counts
    for cid, ch in summary.channels.items():
        assert meta_topics[ch.topic]['message_count'] == counts.get(cid, 0)
        assert meta_topics[ch.topic]['topic_metadata']['type'] == summary.schemas[ch.schema_id].name
    assert meta_topics['/world/target']['topic_metadata']['offered_qos_profiles'] == target_qos
    assert info['message_count'] == summary.statistics.message_count


def test_bag_directory_as_rosbag2_lays_it_out(rclpy_context, processes, swarm_cmd, tmp_path):
    """``--out DIR``: DIR/DIR_0.mcap + DIR/metadata.yaml (rosbag2 metadata version 9); rosbags'
    Reader opens the directory (it needs metadata.yaml), swarm report reads it too."""
    import yaml
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader

    from swarm_tools.bags import report
    from swarm_tools.bags.mcap_io import resolve_bag

    out = tmp_path / 'dirbag'
    steps = 20
    rc, stdout, stderr, _ = _record(rclpy_context, processes, swarm_cmd, out, steps,
                                    extra=('--exclude', '/rosout', '/parameter_events'))
    assert rc == 0, stderr
    assert sorted(p.name for p in out.iterdir()) == ['dirbag_0.mcap', 'metadata.yaml']
    info = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['relative_file_paths'] == ['dirbag_0.mcap']
    assert [f['path'] for f in info['files']] == ['dirbag_0.mcap']
    assert resolve_bag(out) == out / 'dirbag_0.mcap'
    with Reader(out) as r:
        counts = {c.topic: c.msgcount for c in r.connections}
        assert r.message_count == info['message_count']
        assert r.duration > 0
    assert counts['/swarm/states'] == steps * N_AGENTS and counts['/swarm/lambda'] == steps
    with AnyReader([out]) as r:
        conn = [c for c in r.connections if c.topic == '/swarm/states']
        stamps = [r.deserialize(raw, c.msgtype).header.stamp.sec for c, _t, raw in r.messages(conn)]
    assert len(stamps) == steps * N_AGENTS
    assert report.main([str(out), '--out', str(tmp_path / 'rep'), '--no-figure']) == 0
    summary = json.loads((tmp_path / 'rep' / 'metrics.json').read_text())['summary']
    assert summary['agents'] == N_AGENTS and summary['steps'] == steps - 1


def _share(pkg, name):
    from swarm_tools.bags.msgdefs import share_dirs
    for d in share_dirs():
        f = d / pkg / 'msg' / f'{name}.msg'
        if f.is_file():
            return f
    raise FileNotFoundError(name)


def test_sigkill_leaves_finished_chunks(rclpy_context, processes, swarm_cmd, tmp_path):
    """A recorder killed with SIGKILL: no summary, but every chunk it finished reads."""
    from swarm_tools.bags.mcap_io import iter_messages

    out = tmp_path / 'killed.mcap'
    steps = 40
    rc, _stdout, _stderr, pubs = _record(rclpy_context, processes, swarm_cmd, out, steps,
                                         stop_signal=signal.SIGKILL, pace=0.02)
    assert rc == -signal.SIGKILL
    assert out.stat().st_size > 0
    data = out.read_bytes()              # no footer / summary: not a finished file
    assert not data.endswith(b'\x89MCAP0\r\n')
    stats = {}
    states = [m for m in iter_messages(out, stats=stats) if m.topic == '/swarm/states']
    # the run ended ≥ 1 s before the kill and chunks are closed every 0.5 s: all of it is there
    assert len(states) == steps * N_AGENTS, stats
    from rclpy.serialization import serialize_message
    assert [m.data for m in states] == [serialize_message(e) for e in _expected_states(pubs, steps)]


def test_sigint_mid_run_gives_complete_indexed_file(rclpy_context, processes, swarm_cmd,
                                                    tmp_path):
    """SIGINT while messages are still flowing: a complete, indexed file both readers open,
    and what was received was written."""
    import threading

    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    out = tmp_path / 'interrupted.mcap'
    pubs = Publishers(rclpy_context)
    try:
        rec = _start_recorder(processes, swarm_cmd, out)
        assert _wait(pubs.matched, 30, pubs.spin)
        done, sent = threading.Event(), []

        def stop_once_writing():
            # SIGINT once some states are in the file, while the test is still publishing
            if _wait(lambda: _on_disk(out, {'/swarm/states': 1}), 60):
                os.killpg(rec.pid, signal.SIGINT)
                sent.append(True)
            done.set()
        threading.Thread(target=stop_once_writing, daemon=True).start()
        # publishing goes on until the SIGINT was sent, so it lands in the middle of the run
        published = pubs.publish_run(100000, pace=0.01, until=done.is_set)
        assert sent, 'no state reached the file in 60 s'
        stdout, stderr = rec.communicate(timeout=30)
        assert done.is_set() and published < 100000
    finally:
        pubs.close()
    assert rec.returncode == 0, stderr
    assert 'lost: 0' in stdout
    with open(out, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        n_states = sum(1 for _ in reader.iter_messages(topics=['/swarm/states']))
    assert summary is not None and summary.statistics.message_count > 0
    assert 0 < n_states <= published * N_AGENTS
    with Reader(out) as r:
        counts = {c.topic: c.msgcount for c in r.connections}
    assert counts['/swarm/states'] == n_states
    line = next(s for s in stdout.splitlines() if s.strip().startswith('/swarm/states'))
    assert line.split()[1:] == [str(n_states), str(n_states)]


def test_recorder_started_before_the_run(rclpy_context, processes, swarm_cmd, tmp_path):
    """The recorder first (as `swarm run --record` starts it), the publishers after: the
    swarm's volatile topics are subscribed ahead, a best-effort publisher (incompatible with
    the ahead-of-time reliable subscription) gets a subscription made again, and nothing
    published after matching is missed."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosbags.highlevel import AnyReader
    from std_msgs.msg import Float64

    from swarm_tools.bags.mcap_io import parse_qos_yaml

    out = tmp_path / 'first.mcap'
    rec = _start_recorder(processes, swarm_cmd, out)
    assert 'ready' in rec.stderr.readline()
    node = rclpy.create_node('late_pub', context=rclpy_context)
    ex = SingleThreadedExecutor(context=rclpy_context)
    ex.add_node(node)
    try:
        lam = node.create_publisher(Float64, '/swarm/lambda',
                                    QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT))
        pubs = Publishers(rclpy_context)
        assert _wait(lambda: pubs.matched() and lam.get_subscription_count() >= 1, 30,
                     lambda: (pubs.spin(), ex.spin_once(timeout_sec=0.02)))
        for k in range(10):
            lam.publish(Float64(data=k * 0.1))
            pubs.states.publish(pubs.state(k, 0))
            ex.spin_once(timeout_sec=0.01)
        _wait(lambda: False, 1.0, pubs.spin)
        os.killpg(rec.pid, signal.SIGINT)
        stdout, stderr = rec.communicate(timeout=30)
        pubs.close()
    finally:
        ex.shutdown()
        node.destroy_node()
    assert rec.returncode == 0, stderr
    with AnyReader([out]) as reader:
        conns = {c.topic: c for c in reader.connections}
        lam_vals = [reader.deserialize(raw, c.msgtype).data for c, _, raw in
                    reader.messages(connections=[conns['/swarm/lambda']])]
        n_states = sum(1 for _ in reader.messages(connections=[conns['/swarm/states']]))
    assert lam_vals == [k * 0.1 for k in range(10)]
    assert n_states == 10
    # the channel keeps the offers known when the recorder first saw a writer of /swarm/lambda, as
    # rosbag2 does: this test's best-effort one, and Publishers' reliable one when it was known by
    # then (created just after it; on a loaded machine the recorder's look came between the two)
    qos = parse_qos_yaml(_channel_qos(out, '/swarm/lambda'))
    assert sorted(q['reliability'] for q in qos) in (['best_effort'], ['best_effort', 'reliable']), qos


def _channel_qos(path, topic):
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        for ch in make_reader(f).get_summary().channels.values():
            if ch.topic == topic:
                return ch.metadata['offered_qos_profiles']
    return ''


def test_state_gap_count():
    """The recorder's count of states DDS never delivered (no ROS needed)."""
    from swarm_tools.bags.record import Recorder

    rec = Recorder.__new__(Recorder)
    dt = 50_000_000
    rec.states = {'agent_0': {k * dt for k in range(10)},
                  'agent_1': {k * dt for k in range(10) if k not in (3, 7)}}
    assert rec.state_gaps() == {'agent_0': (10, 0), 'agent_1': (8, 2)}


def test_recorder_that_falls_behind_loses_no_state(rclpy_context, tmp_path):
    """A recorder starved of CPU while many agents publish (a realtime run at a high rtf):
    its reader holds every state the agents' publishers still hold (their depth,
    protocol.STATES_DEPTH), so none is lost when it catches up.  Here its callbacks do not run
    while 30 agents publish 100 states each (3000, more than a depth of 1000 held)."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor

    from swarm_ros import protocol as P
    from swarm_tools.bags.mcap_io import BagWriter
    from swarm_tools.bags.record import SWARM_TOPICS, Recorder, TopicFilter

    agents, states = 30, P.STATES_DEPTH
    rec_node = rclpy.create_node('swarm_recorder', context=rclpy_context)
    writer = BagWriter(tmp_path / 'behind.mcap')
    rec = Recorder(rec_node, writer, TopicFilter(['/swarm/states']), presubscribe=SWARM_TOPICS)
    rec_ex = SingleThreadedExecutor(context=rclpy_context)
    rec_ex.add_node(rec_node)
    node = rclpy.create_node('agents', context=rclpy_context)
    pubs = [node.create_publisher(Odometry, P.STATES, P.qos_latched(P.STATES_DEPTH)) for _ in range(agents)]
    try:
        assert _wait(lambda: all(p.get_subscription_count() >= 1 for p in pubs), 30)
        m = Odometry()
        m.pose.pose.orientation.w = 1.0
        for k in range(states):
            m.header.stamp.nanosec = k
            for i, p in enumerate(pubs):
                m.child_frame_id = f'agent_{i}'
                p.publish(m)
        time.sleep(1.0)             # delivered to the recorder's reader, not yet taken
        total = agents * states
        _wait(lambda: rec.received.get('/swarm/states', 0) >= total, 20,
              lambda: rec_ex.spin_once(timeout_sec=0.05))
        _wait(lambda: False, 0.5, lambda: rec_ex.spin_once(timeout_sec=0.05))
        assert rec.received['/swarm/states'] == total
        assert sum(m for _, m in rec.state_gaps().values()) == 0
    finally:
        rec_ex.shutdown()
        node.destroy_node()
        rec_node.destroy_node()
        writer.close()


def test_recorder_recheck_asks_for_the_offers_only_when_a_publisher_is_unmatched(rclpy_context, tmp_path):
    """Once a second the recorder rechecks its topics for a publisher that joined with an
    offer its subscription cannot match.  While every publisher is matched it asks no
    publisher infos (two counts); a best-effort publisher that joins is found and the topic
    subscribed again."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    from swarm_tools.bags.mcap_io import BagWriter
    from swarm_tools.bags.record import Recorder, TopicFilter

    rec_node = rclpy.create_node('swarm_recorder', context=rclpy_context)
    writer = BagWriter(tmp_path / 'recheck.mcap')
    rec = Recorder(rec_node, writer, TopicFilter(['/recheck']))
    node = rclpy.create_node('pubs', context=rclpy_context)
    node.create_publisher(Float64, '/recheck', QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE))
    asked = []
    infos = rec_node.get_publishers_info_by_topic
    rec_node.get_publishers_info_by_topic = lambda topic: asked.append(topic) or infos(topic)
    try:
        assert _wait(lambda: '/recheck' in rec.subs and '/recheck' in writer.topics
                     and rec.subs['/recheck'].get_publisher_count() == 1, 20, rec.poll)
        first = rec.subs['/recheck']
        asked.clear()
        for _ in range(10):                     # two rechecks
            rec.poll()
        assert asked == [] and rec.subs['/recheck'] is first
        node.create_publisher(Float64, '/recheck', QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT))
        assert _wait(lambda: rec_node.count_publishers('/recheck') == 2, 20)
        for _ in range(5):
            rec.poll()
        assert '/recheck' in asked and rec.subs['/recheck'] is not first
        assert rec.subs['/recheck'].qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
    finally:
        node.destroy_node()
        rec_node.destroy_node()
        writer.close()


def test_recorder_presubscribes_the_agents_steering_topics(rclpy_context, tmp_path):
    """``swarm record --agents`` (what ``swarm run`` passes) subscribes to each agent's steering
    topic at start-up, as the commander will offer it (latched): found mid-run, a hundred of them
    cost one poll 80-180 ms of CPU.  The commander's writer then matches the subscription as
    it is (it is not made again)."""
    import rclpy
    from std_msgs.msg import Float64

    from swarm_ros import protocol as P
    from swarm_tools.bags.mcap_io import BagWriter
    from swarm_tools.bags.record import SWARM_TOPICS, Recorder, TopicFilter, parse_args, presubscribed

    assert parse_args(['--out', 'x.mcap', '--agents', 'agent_0', 'agent_1']).agents == ['agent_0', 'agent_1']
    topics = presubscribed(['agent_0', 'agent_1'])
    assert topics['/agent_1/steering'] == ('std_msgs/msg/Float64', 1)
    assert SWARM_TOPICS.items() <= topics.items() and presubscribed() == SWARM_TOPICS
    rec_node = rclpy.create_node('swarm_recorder', context=rclpy_context)
    writer = BagWriter(tmp_path / 'steering.mcap')
    rec = Recorder(rec_node, writer, TopicFilter(['/agent_0/steering', '/agent_1/steering']), presubscribe=topics)
    node = rclpy.create_node('commander', context=rclpy_context)
    try:
        assert set(rec.subs) == {'/agent_0/steering', '/agent_1/steering'}      # before any publisher
        first = rec.subs['/agent_0/steering']
        node.create_publisher(Float64, P.steering_topic('agent_0'), P.qos_latched(P.STEP_DEPTH))
        assert _wait(lambda: '/agent_0/steering' in writer.topics, 20, rec.poll)
        assert rec.subs['/agent_0/steering'] is first
    finally:
        node.destroy_node()
        rec_node.destroy_node()
        writer.close()
