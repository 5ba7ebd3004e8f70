"""MCAP bags in the form rosbag2 writes them (no rclpy import here).

What `ros2 bag record -s mcap` (rosbag2_storage_mcap, Jazzy) writes and this module copies:

* header profile ``ros2``; chunked, zstd-compressed, with message indexes and a summary;
* one schema per message type: name ``pkg/msg/Type``, encoding ``ros2msg``, data = the full
  definition: the type's ``.msg`` text, then for each dependency (sorted, depth first, each once)
  ``"\\n" + "=" * 80 + "\\n" + "MSG: pkg/Type\\n"`` and its text (`message_definition`);
* one channel per topic: message encoding ``cdr``, metadata ``offered_qos_profiles`` (a YAML
  list of the publishers' QoS, rosbag2 metadata version 9 spelling, `qos_yaml`) and
  ``topic_type_hash`` (left empty, as rosbag2 does when the hash is unknown);
* messages: log time = receive time, publish time = send time, both wall time (the rmw's
  ``received_timestamp`` and ``source_timestamp``: rosbag2_transport ``recorder.cpp`` without
  ``--use-sim-time``; ``mcap_storage.cpp`` writes them as ``logTime`` / ``publishTime``).  Sim time
  stays in the messages' header stamps;
* a metadata record ``rosbag2`` with ``serialized_metadata`` at the end.

A bag DIRECTORY is rosbag2's layout: ``DIR/DIR_0.mcap`` and ``DIR/metadata.yaml`` (the same
version 9 metadata, written when the file is closed), so ``ros2 bag info DIR`` and rosbags'
``Reader`` open it (`bag_paths`, `resolve_bag`).

Crash safety: chunks are small and `BagWriter.maybe_flush` closes the open chunk every
``flush_interval`` seconds, so a writer killed with SIGKILL leaves every finished chunk readable
by a streaming reader (`iter_records_tolerant`); `BagWriter.close` writes the summary and index.
"""
from __future__ import annotations

import os
import struct
import time
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path

import yaml
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from swarm_core.files import open_regular, write_atomic
from swarm_core.scenario.placement import AGENT_NAME
from swarm_ros.protocol import RUN, cdr_byte_order, cdr_string, cdr_to_odometry_full
from swarm_ros.runinfo import describe, parse_run
from swarm_tools.bags.msgdefs import has_leading_stamp, message_definition

PROFILE = 'ros2'
SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
MCAP_MAGIC = b'\x89MCAP0\r\n'
LIBRARY = 'homotopy-swarm swarm_tools (rosbag2_storage_mcap layout)'


# --------------------------------------------------------------------------- QoS metadata
_HISTORY = {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'}
_RELIABILITY = {0: 'system_default', 1: 'reliable', 2: 'best_effort', 3: 'unknown',
                4: 'best_available'}
_DURABILITY = {0: 'system_default', 1: 'transient_local', 2: 'volatile', 3: 'unknown',
               4: 'best_available'}
_LIVELINESS = {0: 'system_default', 1: 'automatic', 2: 'manual_by_node', 3: 'manual_by_topic',
               4: 'unknown', 5: 'best_available'}
INFINITE_NS = 2 ** 63 - 1


def _duration(ns: int) -> dict:
    ns = int(ns)
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def qos_dict(*, history=3, depth=0, reliability=1, durability=2, deadline_ns=INFINITE_NS,
             lifespan_ns=INFINITE_NS, liveliness=1, liveliness_lease_ns=INFINITE_NS,
             avoid_ros_namespace_conventions=False) -> dict:
    """One offered QoS profile in rosbag2's (metadata version 9) form; policies as the rmw
    enum values (ints) or their names."""
    def name(table, v):
        return v if isinstance(v, str) else table.get(int(v), 'unknown')
    return {'history': name(_HISTORY, history), 'depth': int(depth),
            'reliability': name(_RELIABILITY, reliability),
            'durability': name(_DURABILITY, durability),
            'deadline': _duration(deadline_ns), 'lifespan': _duration(lifespan_ns),
            'liveliness': name(_LIVELINESS, liveliness),
            'liveliness_lease_duration': _duration(liveliness_lease_ns),
            'avoid_ros_namespace_conventions': bool(avoid_ros_namespace_conventions)}


def qos_yaml(profiles: list[dict]) -> str:
    """The ``offered_qos_profiles`` string, laid out as yaml-cpp's ``YAML::Dump`` does."""
    if not profiles:
        return ''
    lines = []
    for p in profiles:
        first = True
        for key in ('history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
                    'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions'):
            v = p[key]
            lead = '- ' if first else '  '
            first = False
            if isinstance(v, dict):
                lines.append(f'{lead}{key}:')
                lines.append(f'    sec: {v["sec"]}')
                lines.append(f'    nsec: {v["nsec"]}')
            elif isinstance(v, bool):
                lines.append(f'{lead}{key}: {"true" if v else "false"}')
            else:
                lines.append(f'{lead}{key}: {v}')
    return '\n'.join(lines)


def parse_qos_yaml(text: str) -> list[dict]:
    if not text:
        return []
    data = yaml.safe_load(text)
    return list(data) if isinstance(data, list) else []


def replay_qos(profiles: list[dict]) -> dict:
    """The QoS to offer on replay, as rosbag2 adapts it: the recorded one if all publishers
    agreed on reliability/durability (keeping the recorded depth for latched topics), else
    reliable + volatile.  Volatile topics get a deep queue (1000) so a busy subscriber loses
    nothing a recorded run had.  Returns {'reliability', 'durability', 'depth'}."""
    rel = {p.get('reliability') for p in profiles}
    dur = {p.get('durability') for p in profiles}
    out = {'reliability': 'reliable', 'durability': 'volatile', 'depth': 1000}
    if len(rel) == 1 and len(dur) == 1:
        r, d = rel.pop(), dur.pop()
        out['reliability'] = r if r in ('reliable', 'best_effort') else 'reliable'
        out['durability'] = d if d in ('volatile', 'transient_local') else 'volatile'
    if out['durability'] == 'transient_local':
        out['depth'] = max([1] + [int(p.get('depth') or 0) for p in profiles])
    return out


# --------------------------------------------------------------------------- writer
@dataclass
class TopicInfo:
    name: str
    type: str
    channel_id: int
    stamped: bool
    qos: list = field(default_factory=list)
    written: int = 0


class BagWriter:
    """Writes one MCAP file in rosbag2's layout; not thread safe (one writer thread)."""

    def __init__(self, path, *, chunk_size: int = 64 * 1024, flush_interval: float = 0.5,
                 compression: str = 'zstd', metadata_yaml=None):
        self.path = Path(path)
        self.metadata_yaml = Path(metadata_yaml) if metadata_yaml is not None else None
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = open_regular(self.path, 'wb')
        comp = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}[compression]
        self._w = Writer(self._fh, chunk_size=chunk_size, compression=comp)
        self._w.start(profile=PROFILE, library=LIBRARY)
        self._fh.flush()            # a full disk shows here, before anything is recorded
        self._schemas: dict[str, int] = {}
        self._defs: dict[str, str] = {}
        self.topics: dict[str, TopicInfo] = {}
        self.flush_interval = flush_interval
        self._last_flush = time.monotonic()
        self._seq = 0
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self.closed = False

    def definition(self, type_name: str) -> str:
        if type_name not in self._defs:
            self._defs[type_name] = message_definition(type_name)
        return self._defs[type_name]

    def add_topic(self, topic: str, type_name: str, qos_profiles: list[dict] = (),
                  definition: str | None = None) -> TopicInfo:
        """Register a topic (schema once per type, channel once per topic)."""
        if topic in self.topics:
            return self.topics[topic]
        text = definition if definition is not None else self.definition(type_name)
        if type_name not in self._schemas:
            self._schemas[type_name] = self._w.register_schema(
                name=type_name, encoding=SCHEMA_ENCODING, data=text.encode())
        cid = self._w.register_channel(
            topic=topic, message_encoding=MESSAGE_ENCODING, schema_id=self._schemas[type_name],
            metadata={'offered_qos_profiles': qos_yaml(list(qos_profiles)),
                      'topic_type_hash': ''})
        info = TopicInfo(topic, type_name, cid, has_leading_stamp(text, type_name),
                         list(qos_profiles))
        self.topics[topic] = info
        return info

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None):
        """Write one serialized message: log time = receive time, publish time = send time
        (both wall time); without a send time, the receive time (as rosbag2 does)."""
        info = self.topics[topic]
        if not publish_time_ns or publish_time_ns < 0:
            publish_time_ns = log_time_ns
        self._w.add_message(channel_id=info.channel_id, log_time=int(log_time_ns),
                            data=bytes(data), publish_time=int(publish_time_ns),
                            sequence=self._seq & 0xFFFFFFFF)
        self._seq += 1
        info.written += 1
        self.start_ns = log_time_ns if self.start_ns is None else min(self.start_ns, log_time_ns)
        self.end_ns = log_time_ns if self.end_ns is None else max(self.end_ns, log_time_ns)
        self.maybe_flush()

    def maybe_flush(self, force: bool = False):
        """Close the open chunk and push it to the file if ``flush_interval`` has passed."""
        now = time.monotonic()
        if force or now - self._last_flush >= self.flush_interval:
            self._w.flush()
            self._last_flush = now

    def rosbag2_metadata(self) -> str:
        """rosbag2's ``metadata.yaml`` content for this file (version 9)."""
        start = self.start_ns or 0
        dur = (self.end_ns - start) if self.end_ns is not None else 0
        topics = []
        for t in self.topics.values():
            topics.append({'topic_metadata': {
                'name': t.name, 'type': t.type, 'serialization_format': MESSAGE_ENCODING,
                'offered_qos_profiles': list(t.qos), 'type_description_hash': ''},
                'message_count': t.written})
        meta = {'rosbag2_bagfile_information': {
            'version': 9, 'storage_identifier': 'mcap',
            'duration': {'nanoseconds': dur}, 'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': sum(t.written for t in self.topics.values()),
            'topics_with_message_count': topics, 'compression_format': '',
            'compression_mode': '', 'relative_file_paths': [self.path.name],
            'files': [{'path': self.path.name, 'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': dur},
                       'message_count': sum(t.written for t in self.topics.values())}],
            'custom_data': {}, 'ros_distro': 'jazzy'}}
        return yaml.safe_dump(meta, sort_keys=False)

    def close(self):
        if self.closed:
            return
        self.closed = True
        meta = self.rosbag2_metadata()
        self._w.add_metadata('rosbag2', {'serialized_metadata': meta})
        self._w.finish()
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._fh.close()
        if self.metadata_yaml is not None:
            write_atomic(self.metadata_yaml, meta)

    def abort(self):
        """Close the file as it is, without the summary (the disk is full or gone): what was
        written reads as a cut bag (`iter_records_tolerant`, `swarm bag recover`)."""
        self.closed = True
        try:
            self._fh.close()
        except OSError:
            pass                 # the buffered tail could not be written either

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# --------------------------------------------------------------------------- layout
def bag_complete(path) -> bool:
    """Whether an MCAP file ends as a finished one does (its closing magic after the footer):
    False for a bag whose recorder died or stopped at a full disk."""
    try:
        with open(path, 'rb') as f:
            if os.fstat(f.fileno()).st_size < 2 * len(MCAP_MAGIC):
                return False
            f.seek(-len(MCAP_MAGIC), os.SEEK_END)
            return f.read() == MCAP_MAGIC
    except OSError:
        return False


def bag_paths(out) -> tuple[Path, Path | None]:
    """Where to write: ``X.mcap`` is one file (no metadata.yaml); any other path is a rosbag2
    bag directory, ``DIR/DIR_0.mcap`` + ``DIR/metadata.yaml`` (as ``ros2 bag record -o DIR``)."""
    out = Path(out)
    if out.suffix == '.mcap':
        return out, None
    return out / f'{out.name}_0.mcap', out / 'metadata.yaml'


def resolve_bag(path) -> Path:
    """The .mcap file to read for ``path``: the file itself, or a bag directory's file (the
    first of metadata.yaml's ``relative_file_paths``, else its only ``*.mcap``)."""
    path = Path(path)
    if not path.is_dir():
        return path
    meta = path / 'metadata.yaml'
    if meta.is_file():
        try:
            info = yaml.safe_load(meta.read_text())['rosbag2_bagfile_information']
            files = [path / Path(f).name for f in info.get('relative_file_paths') or []]
            files = [f for f in files if f.suffix == '.mcap' and f.is_file()]
            if files:
                return files[0]
        except (yaml.YAMLError, KeyError, TypeError):
            pass
    found = sorted(path.glob('*.mcap'))
    if len(found) == 1:
        return found[0]
    raise FileNotFoundError(f'{path}: a directory, but not a bag with one .mcap file '
                            f'({len(found)} found)')


# --------------------------------------------------------------------------- reading
@dataclass
class BagMessage:
    topic: str
    type: str
    data: bytes
    log_time: int
    publish_time: int
    channel: Channel
    schema: Schema | None


def _chunk_offsets(f) -> list[int]:
    """Where the chunks start, from the file's summary (chunk indexes); [] without one (a file
    cut short has no summary) or if it does not read."""
    try:
        f.seek(0)
        summary = make_reader(f).get_summary()
    except Exception:           # a damaged or missing footer/summary: no offsets to resync by
        return []
    return sorted(ci.chunk_start_offset for ci in summary.chunk_indexes) if summary else []


_OPCODES = {int(op) for op in Opcode}


def _read_record(head: bytes, body: bytes):
    """One record parsed by mcap from its framing (opcode, length) and body; None for a kind
    of record MCAP does not define (readers skip those)."""
    if head[0] not in _OPCODES:
        return None
    return next(StreamReader(BytesIO(head + body), skip_magic=True, emit_chunks=True).records)


def iter_records_tolerant(path, stats: dict | None = None):
    """Every record of an MCAP file read front to back, chunks decompressed and CRC-checked.

    Each record is framed by its opcode and length and parsed on its own, so a damaged chunk
    (bad CRC, bad compression, bad fields) costs only that chunk: ``stats['damaged']`` counts
    them.  If the framing itself is damaged (a length past the end of the file, a record that
    does not parse), the read goes on at the next chunk the file's summary indexes; without
    a summary (a file cut short: a writer killed) it ends quietly there, as at a cut:
    ``stats['truncated']`` tells, ``stats['error']`` says why."""
    stats = {} if stats is None else stats
    stats.update(truncated=False, damaged=0)
    with open(path, 'rb') as f:
        size = os.fstat(f.fileno()).st_size
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            stats.update(truncated=True, error='not an MCAP file (no magic)')
            return
        offsets = None
        while True:
            pos = f.tell()
            head = f.read(9)
            if not head:
                stats.update(truncated=True, error='no footer')
                return
            err = None
            if len(head) < 9:
                err = 'a record cut short'
            else:
                length = struct.unpack_from('<Q', head, 1)[0]
                if length > size - pos - 9:
                    err = f'a record of {length} bytes at byte {pos}, past the end of the file'
            if err is None:
                body = f.read(length)
                try:
                    rec = _read_record(head, body)
                except (McapError, EOFError, struct.error, ValueError, UnicodeDecodeError) as exc:
                    err = f'a damaged record at byte {pos} ({type(exc).__name__}: {exc})'
            if err is not None:
                offsets = _chunk_offsets(f) if offsets is None else offsets
                later = [o for o in offsets if o > pos]
                if not later:
                    stats.update(truncated=True, error=err)
                    return
                stats['damaged'] += 1
                stats.setdefault('damage', err)
                f.seek(later[0])
                continue
            if isinstance(rec, Footer):
                return
            if isinstance(rec, Chunk):
                try:
                    inner = breakup_chunk(rec, validate_crc=True)
                except Exception as exc:   # bad CRC, compression or fields: this chunk only
                    stats['damaged'] += 1
                    stats.setdefault('damage', f'a damaged chunk at byte {pos} ({exc})')
                    continue
                yield from inner
            elif rec is not None:
                yield rec


def iter_messages(path, topics=None, stats: dict | None = None):
    """BagMessage per message in file order, from complete or cut-short files alike."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    wanted = set(topics) if topics else None
    for rec in iter_records_tolerant(path, stats):
        if isinstance(rec, Schema):
            schemas[rec.id] = rec
        elif isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, Message):
            ch = channels.get(rec.channel_id)
            if ch is None or (wanted is not None and ch.topic not in wanted):
                continue
            sc = schemas.get(ch.schema_id)
            yield BagMessage(ch.topic, sc.name if sc else '', rec.data, rec.log_time,
                             rec.publish_time, ch, sc)


def announced_roster(path, warn=None) -> list[str] | None:
    """The agents of the run a bag recorded, from the world's ``/swarm/run`` announcement
    (`swarm_ros.runinfo.run_json`); None if the bag has none.  The first announcement counts
    (the recorder starts before the run); ``warn`` hears of any other run announced."""
    first, others = None, set()
    for m in iter_messages(path, topics=[RUN]):
        try:
            run = parse_run(parse_string(m.data))
        except (struct.error, IndexError, ValueError):
            run = None
        if run is None:
            continue
        if first is None:
            first = run
        elif run['run_id'] != first['run_id'] and len(others) < 10:
            others.add(describe(run))
    if first is None:
        return None
    if others and warn:
        warn(f'the bag announces more than one run; the first, {describe(first)}, counts '
             f'(also: {"; ".join(sorted(others))})')
    return [a for a in first['agents'] if isinstance(a, str) and AGENT_NAME.fullmatch(a)]


def announced_dim(path) -> int:
    """2 or 3: the ``dim`` of the first run a bag's ``/swarm/run`` announces (2 without one)."""
    for m in iter_messages(path, topics=[RUN]):
        try:
            run = parse_run(parse_string(m.data))
        except (struct.error, IndexError, ValueError):
            continue
        if run is not None:
            return 3 if run.get('dim') == 3 else 2
    return 2


def bag_topics(path, expected=None) -> dict[str, dict]:
    """{topic: {type, definition, qos (list of dicts), count, channels, other}} of a bag
    (tolerant reader).  A topic's type is ``expected(topic)`` where that gives one (the
    project's own topics), else its first channel's; ``channels``: the ids of its channels of
    that type, ``count`` their messages, ``definition`` and ``qos`` the first one's; ``other``:
    {type: messages} on its channels of other types (a stray or hostile publisher).  A topic
    with no channel of its type has ``type`` None."""
    schemas: dict[int, Schema] = {}
    chans: dict[int, Channel] = {}
    counts: dict[int, int] = {}
    for rec in iter_records_tolerant(path):
        if isinstance(rec, Schema):
            schemas.setdefault(rec.id, rec)
        elif isinstance(rec, Channel):
            chans.setdefault(rec.id, rec)
        elif isinstance(rec, Message) and rec.channel_id in chans:
            counts[rec.channel_id] = counts.get(rec.channel_id, 0) + 1
    out: dict[str, dict] = {}
    for cid, ch in chans.items():          # in the order the channels were written
        sc = schemas.get(ch.schema_id)
        kind = sc.name if sc else ''
        info = out.setdefault(ch.topic, {
            'type': (expected(ch.topic) if expected else None) or kind, 'definition': '', 'qos': [],
            'count': 0, 'channels': set(), 'other': {}})
        if kind != info['type']:
            info['other'][kind] = info['other'].get(kind, 0) + counts.get(cid, 0)
            continue
        if not info['channels']:
            info['definition'] = sc.data.decode(errors='replace') if sc else ''
            info['qos'] = parse_qos_yaml(ch.metadata.get('offered_qos_profiles', ''))
        info['channels'].add(cid)
        info['count'] += counts.get(cid, 0)
    for info in out.values():
        if not info['channels']:
            info['type'] = None
    return out


# --------------------------------------------------------------------------- CDR helpers
def parse_odometry(data: bytes) -> dict:
    """The fields of a CDR ``nav_msgs/msg/Odometry`` the report needs, without a ROS decoder
    (`swarm_ros.protocol.cdr_to_odometry_full`): stamp_ns, frame_id, child_frame_id, x, y,
    qz, qw, vx, wz."""
    frame, child, sec, nsec, (x, y, _, _, qz, qw), vx, wz, _ = cdr_to_odometry_full(data)
    return dict(stamp_ns=sec * 1_000_000_000 + nsec, frame_id=frame, child_frame_id=child,
                x=x, y=y, qz=qz, qw=qw, vx=vx, wz=wz)


def parse_string(data: bytes) -> str:
    """``std_msgs/msg/String`` (CDR), e.g. a ``/swarm/events`` JSON object."""
    return cdr_string(data, 4, cdr_byte_order(data))[0]


def parse_float64(data: bytes) -> float:
    """``std_msgs/msg/Float64`` (CDR)."""
    return struct.unpack_from(cdr_byte_order(data) + 'd', data, 4)[0]
