"""pytest fixtures for tests that drive a live swarm, installed as a pytest plugin (the
``pytest11`` entry point of swarm_tools): every project that installs homotopy-swarm has them.

``ros_domain``  a ROS_DOMAIN_ID of the test's own (held with a lock file, so parallel pytest
    runs on one machine never share one), localhost-only discovery, set in os.environ for the
    test (child processes inherit it); gives the id.  No other run can be on that domain, so a
    world starts without listening for one first (``SWARM_DISCOVERY_SETTLE=0``; a test of that
    refusal sets it back).  The ids it takes: ``--swarm-domains
    LO-HI``, else the environment's ``SWARM_DOMAINS=LO-HI``, else 1-100 (`DOMAINS`).
``swarm``  a function ``swarm(scenario, **options)`` that starts `swarm_tools.api.Swarm` on the
    test's domain (``out`` defaults to a directory in tmp_path); after the test, passed or
    failed, every run it started is stopped and every process of it is gone.
"""
from __future__ import annotations

import fcntl
import itertools
import os
import sys
import time
from pathlib import Path

import pytest

from swarm_ros.runinfo import MAX_DOMAIN, SETTLE_ENV

# Domain ids 1..100 are safe on Linux (ports below the ephemeral range).  A test holds an
# exclusive flock on <SWARM_DOMAIN_LOCK_DIR>/<id>.lock for as long as it uses the id.
_LOCK_DIR = Path(os.environ.get('SWARM_DOMAIN_LOCK_DIR', '/tmp/homotopy-swarm-domains'))
_start = itertools.count((os.getpid() * 7) % 1000)

#: the ids `claim_domain` takes by default (LO, HI, both included)
DOMAINS = (1, 100)
#: the environment variable that sets them (``LO-HI``; the option ``--swarm-domains`` wins)
DOMAINS_ENV = 'SWARM_DOMAINS'
_DOMAINS_KEY = pytest.StashKey()


def domain_range(text, source: str) -> tuple:
    """(LO, HI) of ``text``, ``LO-HI`` or one id; ValueError naming ``source`` (the option or
    the variable) unless 0 ≤ LO ≤ HI ≤ `MAX_DOMAIN`."""
    lo, sep, hi = str(text).strip().partition('-')
    try:
        lo, hi = int(lo), int(hi if sep else lo)
    except ValueError:
        raise ValueError(f'{source}={text!r}: want LO-HI, two ROS_DOMAIN_IDs (e.g. 1-100)') from None
    if not 0 <= lo <= hi <= MAX_DOMAIN:
        raise ValueError(f'{source}={text!r}: want 0 <= LO <= HI <= {MAX_DOMAIN}')
    return lo, hi


def domains(option=None) -> tuple:
    """The ids to take: ``option`` (the text of ``--swarm-domains``) if given, else
    `DOMAINS_ENV` if set, else `DOMAINS`."""
    if option:
        return domain_range(option, '--swarm-domains')
    env = os.environ.get(DOMAINS_ENV, '').strip()
    return domain_range(env, DOMAINS_ENV) if env else DOMAINS


def pytest_addoption(parser):
    parser.addoption('--swarm-domains', default=None, metavar='LO-HI', help=(
        f'the ROS_DOMAIN_IDs the ros_domain fixture takes, LO to HI (default: ${DOMAINS_ENV}, else '
        f'{DOMAINS[0]}-{DOMAINS[1]})'))


def pytest_configure(config):
    try:                                  # a bad range: one line, before any test
        config.stash[_DOMAINS_KEY] = domains(config.getoption('swarm_domains', None))
    except ValueError as err:
        raise pytest.UsageError(str(err)) from None


#: seconds an id rests after its last user let it go: the participants of that user's killed
#: processes stay in discovery until their lease ends, and a new user would see their endpoints
QUARANTINE = 30.0
#: seconds `claim_domain` waits for a free id before it gives up
CLAIM_WAIT = 2 * QUARANTINE


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


def claim_domain(ids=None):
    """(domain id, open lock file) of a free id among ``ids`` ((LO, HI); None: `domains`) that
    has rested `QUARANTINE` s since its last user; the id is ours until `release_domain` (or
    the file is closed).  Tries every id once a second, for up to `CLAIM_WAIT` s (a small range
    of a CI's waits for its ids to rest)."""
    lo, hi = domains() if ids is None else ids
    size = hi - lo + 1
    _LOCK_DIR.mkdir(parents=True, exist_ok=True)
    first = next(_start)
    end = time.monotonic() + CLAIM_WAIT
    for attempt in itertools.count():
        if attempt % size == 0 and attempt and time.monotonic() > end:
            break
        dom = lo + (first + attempt) % size
        f = open(_LOCK_DIR / f'{dom}.lock', 'a+')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if time.time() - _released_at(f) < QUARANTINE:
                raise OSError('resting')
        except OSError:
            f.close()
            if attempt % size == size - 1:
                time.sleep(1.0)
            continue
        return dom, f
    raise RuntimeError(f'no free ROS_DOMAIN_ID in {lo}..{hi} (locks in {_LOCK_DIR})')


@pytest.fixture
def ros_domain(monkeypatch, request):
    """A fresh ROS_DOMAIN_ID for this test (of `domains`), localhost-only discovery; returns the id."""
    dom, lock = claim_domain(request.config.stash.get(_DOMAINS_KEY, None))
    request.addfinalizer(lambda: release_domain(lock))
    monkeypatch.setenv('ROS_DOMAIN_ID', str(dom))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.delenv('ROS_STATIC_PEERS', raising=False)
    monkeypatch.setenv('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    monkeypatch.setenv(SETTLE_ENV, '0')        # the domain is this test's alone
    return dom


#: lines of each run's output shown for a failed test (`swarm`)
LOG_TAIL = 60


@pytest.fixture
def swarm(ros_domain, tmp_path):
    """``swarm(scenario, **options)``: a started `swarm_tools.api.Swarm` (options as for
    `Swarm.start`); all of them stopped, their processes gone, after the test.  The end of what
    each run printed goes to stderr then, which pytest shows only for a test that failed."""
    from swarm_tools.api import Swarm
    started = []

    def start(scenario, **options):
        options.setdefault('out', tmp_path / f'run{len(started)}')
        options.setdefault('busy_wait', 0.0)        # the domain is this test's alone (`ros_domain`)
        run = Swarm.start(scenario, domain=ros_domain, **options)
        started.append(run)
        return run

    start.runs = started              # what a test (or a conftest) may read after the runs
    yield start
    left = []
    for run in started:
        run.close()
        left += run.leftover()
        tail = run.log[-LOG_TAIL:]
        print(f'---- the last {len(tail)} lines swarm run printed ({run.out}):\n' + ''.join(tail),
              file=sys.stderr)
    assert not left, f'processes of the run still there after the test: {left}'
