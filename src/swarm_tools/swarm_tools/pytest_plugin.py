"""pytest fixtures for tests that drive a live swarm, installed as a pytest plugin (the
``pytest11`` entry point of swarm_tools): every project that installs homotopy-swarm has them.

``ros_domain``  a ROS_DOMAIN_ID of the test's own (held with a lock file, so parallel pytest
    runs on one machine never share one), localhost-only discovery, set in os.environ for the
    test (child processes inherit it); gives the id.
``swarm``  a function ``swarm(scenario, **options)`` that starts `swarm_tools.api.Swarm` on the
    test's domain (``out`` defaults to a directory in tmp_path); after the test, passed or
    failed, every run it started is stopped and every process of it is gone.
"""
from __future__ import annotations

import fcntl
import itertools
import os
import time
from pathlib import Path

import pytest

# Domain ids 1..100 are safe on Linux (ports below the ephemeral range).  A test holds an
# exclusive flock on <SWARM_DOMAIN_LOCK_DIR>/<id>.lock for as long as it uses the id.
_LOCK_DIR = Path(os.environ.get('SWARM_DOMAIN_LOCK_DIR', '/tmp/homotopy-swarm-domains'))
_start = itertools.count((os.getpid() * 7) % 100)


#: seconds an id rests after its last user let it go: the participants of that user's killed
#: processes stay in discovery until their lease ends, and a new user would see their endpoints
QUARANTINE = 30.0


def _released_at(f) -> float:
    """When the id's last user let it go (0: never used)."""
    f.seek(0)
    try:
        return float(f.read().strip() or 0.0)
    except ValueError:
        return 0.0


def release_domain(f) -> None:
    """Let the id of lock file ``f`` go, noting when (`QUARANTINE`)."""
    f.seek(0)
    f.truncate()
    f.write(f'{time.time():.3f}')
    f.flush()
    f.close()


def claim_domain():
    """(domain id, open lock file) of a free id that has rested `QUARANTINE` s since its last
    user; the id is ours until `release_domain` (or the file is closed)."""
    _LOCK_DIR.mkdir(parents=True, exist_ok=True)
    first = next(_start)
    for attempt in range(3 * 100):
        dom = 1 + (first + attempt) % 100
        f = open(_LOCK_DIR / f'{dom}.lock', 'a+')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if time.time() - _released_at(f) < QUARANTINE:
                raise OSError('resting')
        except OSError:
            f.close()
            if attempt % 100 == 99:
                time.sleep(1.0)
            continue
        return dom, f
    raise RuntimeError(f'no free ROS_DOMAIN_ID in 1..100 (locks in {_LOCK_DIR})')


@pytest.fixture
def ros_domain(monkeypatch, request):
    """A fresh ROS_DOMAIN_ID for this test, localhost-only discovery; returns the id."""
    dom, lock = claim_domain()
    request.addfinalizer(lambda: release_domain(lock))
    monkeypatch.setenv('ROS_DOMAIN_ID', str(dom))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.delenv('ROS_STATIC_PEERS', raising=False)
    monkeypatch.setenv('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    return dom


@pytest.fixture
def swarm(ros_domain, tmp_path):
    """``swarm(scenario, **options)``: a started `swarm_tools.api.Swarm` (options as for
    `Swarm.start`); all of them stopped, their processes gone, after the test."""
    from swarm_tools.api import Swarm
    started = []

    def start(scenario, **options):
        options.setdefault('out', tmp_path / f'run{len(started)}')
        run = Swarm.start(scenario, domain=ros_domain, **options)
        started.append(run)
        return run

    yield start
    left = []
    for run in started:
        run.close()
        left += run.leftover()
    assert not left, f'processes of the run still there after the test: {left}'
