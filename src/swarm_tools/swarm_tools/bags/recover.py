"""``swarm bag recover IN OUT``: rewrite a truncated MCAP file (a recorder killed mid-write)
as a complete, indexed one, as ``mcap recover`` does.

The input is read front to back (`swarm_tools.bags.mcap_io.iter_records_tolerant`: chunks
decompressed and CRC-checked; a damaged chunk is skipped and the read goes on with the next;
a file cut short ends quietly at its last complete record).  Every schema, channel, message,
attachment and metadata record read is written with the mcap ``Writer`` (chunked, zstd, with
message indexes, summary and footer), so the output opens in any MCAP reader.  The messages
of damaged chunks and after the last complete chunk are lost; the command says how many it
kept, how many chunks were damaged and where the input ended.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from swarm_core.files import atomic_open
from swarm_tools.bags.mcap_io import iter_records_tolerant


def recover(src, dst) -> dict:
    """Copy every readable record of ``src`` into a new indexed MCAP file ``dst`` (written to a
    temporary file, then renamed).  Returns counts and whether ``src`` was cut short."""
    src, dst = Path(src), Path(dst)
    stats: dict = {}
    counts = dict(schemas=0, channels=0, messages=0, attachments=0, metadata=0)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    t_first = t_last = None
    with atomic_open(dst, 'wb') as fh:
        w = Writer(fh, compression=CompressionType.ZSTD)
        started = False

        def start(profile='', library=''):
            nonlocal started
            if not started:
                w.start(profile=profile, library=library or 'swarm bag recover')
                started = True

        for rec in iter_records_tolerant(src, stats):
            if isinstance(rec, Header):
                start(rec.profile, rec.library)
                continue
            start()
            if isinstance(rec, Schema):
                if rec.id not in schema_ids:
                    schema_ids[rec.id] = w.register_schema(rec.name, rec.encoding, rec.data)
                    counts['schemas'] += 1
            elif isinstance(rec, Channel):
                if rec.id not in channel_ids:
                    channel_ids[rec.id] = w.register_channel(
                        rec.topic, rec.message_encoding, schema_ids.get(rec.schema_id, 0),
                        dict(rec.metadata))
                    counts['channels'] += 1
            elif isinstance(rec, Message):
                cid = channel_ids.get(rec.channel_id)
                if cid is None:          # a message before its channel: not readable
                    continue
                w.add_message(cid, rec.log_time, rec.data, rec.publish_time, rec.sequence)
                counts['messages'] += 1
                t_first = rec.log_time if t_first is None else min(t_first, rec.log_time)
                t_last = rec.log_time if t_last is None else max(t_last, rec.log_time)
            elif isinstance(rec, Attachment):
                w.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type, rec.data)
                counts['attachments'] += 1
            elif isinstance(rec, Metadata):
                w.add_metadata(rec.name, dict(rec.metadata))
                counts['metadata'] += 1
        start()
        w.finish()
    return dict(counts, truncated=bool(stats.get('truncated')), error=stats.get('error'),
                damaged=stats.get('damaged', 0), damage=stats.get('damage'),
                span_s=(t_last - t_first) * 1e-9 if t_first is not None else 0.0)


def _parser():
    p = argparse.ArgumentParser(prog='swarm bag', description='Bag tools.')
    sub = p.add_subparsers(dest='cmd', required=True)
    r = sub.add_parser('recover', prog='swarm bag recover', description=(
        'Rewrite a truncated MCAP bag (e.g. from a killed recorder) as a complete, indexed one '
        'that any MCAP reader opens, as `mcap recover` does. Messages after the last complete '
        'chunk are lost.'))
    r.add_argument('input', help='the damaged .mcap file')
    r.add_argument('output', help='the new .mcap file (must differ from the input)')
    r.add_argument('--force', action='store_true', help='overwrite OUTPUT if it exists')
    return p


def main(argv=None) -> int:
    a = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    src, dst = Path(a.input), Path(a.output)
    if not src.is_file():
        print(f'swarm bag recover: {src}: no such file', file=sys.stderr)
        return 2
    if dst.exists() and (dst.resolve() == src.resolve() or not a.force):
        why = 'is the input' if dst.resolve() == src.resolve() else 'exists (use --force to overwrite)'
        print(f'swarm bag recover: {dst}: {why}', file=sys.stderr)
        return 2
    try:
        res = recover(src, dst)
    except OSError as err:
        print(f'swarm bag recover: cannot write {dst}: {err.strerror or err}', file=sys.stderr)
        return 1
    if not res['messages'] and not res['channels']:
        print(f'swarm bag recover: {src}: nothing readable (not an MCAP file, or cut before its '
              f'first chunk{": " + res["error"] if res["error"] else ""})', file=sys.stderr)
        return 1
    how = (f'the input ends early ({res["error"]}); what came after its last complete chunk is lost'
           if res['truncated'] else 'the input was complete')
    if res['damaged']:
        how += (f'; {res["damaged"]} damaged chunk{"s" if res["damaged"] > 1 else ""} skipped '
                f'(first: {res["damage"]})')
    print(f'swarm bag recover: wrote {dst}: {res["messages"]} messages on {res["channels"]} channels '
          f'({res["span_s"]:.1f} s); {how}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
