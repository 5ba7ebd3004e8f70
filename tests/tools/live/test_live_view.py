"""The live view's pure parts (`swarm_tools.live.view`): which topics a Foxglove client may
publish on and the values it may send, the metrics it shows, and the shipped layout (the one
``swarm view --write-layout`` generates).  The live view of a run seen by an independent
client: tests/e2e/test_foxglove_live_view.py.
"""
from __future__ import annotations

import struct

import pytest


# ------------------------------------------------------------------ pure parts
def test_client_topics_and_values():
    from swarm_tools.live.view import ClientMessageError, client_float64, client_topic, metrics_numbers

    assert client_topic('/swarm/lambda') and client_topic('/agent_3/steering')
    for t in ('/swarm/states', '/world/markers', '/clock', '/a/b/steering', '/agent_0/steering/x'):
        assert not client_topic(t), t
    assert client_float64('json', b'{"data": 0.75}') == 0.75
    assert client_float64('json', b'{"data": 1}') == 1.0
    cdr = b'\x00\x01\x00\x00' + struct.pack('<d', 0.25)
    assert client_float64('cdr', cdr) == 0.25
    for enc, data in (('json', b'{"data": true}'), ('json', b'[1]'), ('json', b'nope'),
                      ('cdr', b'\x00\x01\x00\x00'), ('ros1', cdr)):
        with pytest.raises(ClientMessageError):
            client_float64(enc, data)
    assert metrics_numbers({'t': '1.5', 'clusters': '2', 'polarisation': 'x', 'leaders': 'a'}) == \
        {'t': 1.5, 'clusters': 2.0}


def test_shipped_layout_is_the_generated_one():
    from swarm_tools.live.view import LAYOUT_FILE, layout_json

    assert LAYOUT_FILE.read_text() == layout_json(), 'regenerate: swarm view --write-layout ' + str(LAYOUT_FILE)
    text = LAYOUT_FILE.read_text()
    for needle in ('"3D!swarm"', '"/world/markers"', '"Publish!lambda"', '"/swarm/lambda"',
                   '/swarm/lambda.data', '/foxglove/metrics.clusters', '/foxglove/metrics.polarisation'):
        assert needle in text, needle
