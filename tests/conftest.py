"""Shared fixtures, and the `ros` marker by folder.

DDS isolation: every test that touches ROS gets its own ROS_DOMAIN_ID (``ros_domain``),
discovery stays on localhost, and every process a test starts is ended by the test
(``processes``), also when it fails.

The `ros` marker (tests that use rclpy / DDS) comes from where a test lives, not from the
test: every test under a ``ros/`` folder (tests/agent/ros/, tests/tools/bags/ros/...) or under
tests/e2e/ (whole runs) is marked; a test elsewhere that is marked `ros` by hand is an error
(move it into a ros/ folder).  Helpers the tests share are in tests/helpers.py.
"""
from __future__ import annotations

import contextlib
import gc
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import PRINTED, refused_summaries

# A suite started as a background job of a script (`bash .ci/run &`) inherits SIGINT ignored,
# and every process it starts would ignore the Ctrl-C that the tests send them: undo that here.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

TESTS = Path(__file__).resolve().parent
VENV_BIN = Path(sys.executable).parent


def pytest_addoption(parser):
    parser.addoption('--shard', default=None, metavar='I/K[:W1,...,WK]', help=(
        'run only shard I of K (1-based): the selected tests\' files dealt out by their measured '
        'time (tests/durations.json; a file not there at the mean per test), the longest first, each '
        'to the shard with the least for its weight W (default: all 1; scripts/test.sh runs the ROS '
        'tests as three shards; each test claims its own ROS_DOMAIN_ID, so shards run side by side)'))


def ros_by_folder(path: Path) -> bool | None:
    """Whether the tests of ``path`` use ROS, by their folder: a ``ros`` folder anywhere under
    tests/, or tests/e2e/.  None for a file outside tests/ (another suite in the same run)."""
    try:
        folders = Path(path).resolve().relative_to(TESTS).parts[:-1]
    except ValueError:
        return None
    return 'ros' in folders or folders[:1] == ('e2e',)


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_collection_modifyitems(config, items):
    # before every other implementation, so before `-m` deselects (the mark plugin's): the
    # marker by folder; a test marked `ros` by hand outside a ros/ folder is an error
    misplaced = set()
    for item in items:
        by_folder = ros_by_folder(item.path)
        if by_folder:
            item.add_marker(pytest.mark.ros)
        elif by_folder is not None and item.get_closest_marker('ros'):
            misplaced.add(str(Path(item.path).resolve().relative_to(TESTS.parent)))
    if misplaced:
        raise pytest.UsageError('marked `ros` outside a ros/ folder (the marker comes from the folder: '
                                'move the tests into one, e.g. tests/agent/ros/): ' + ', '.join(sorted(misplaced)))
    yield
    # after the others, so after -m / -k have deselected: this run's shard
    take_shard(config, items)


def take_shard(config, items):
    """Keep only the items of shard I of K (``--shard I/K``), the others deselected."""
    shard = config.getoption('shard')
    if not shard:
        return
    try:
        which, _, weights = shard.partition(':')
        i, k = (int(v) for v in which.split('/'))
        weight = [float(w) for w in weights.split(',')] if weights else [1.0] * k
        assert 1 <= i <= k and len(weight) == k and min(weight) > 0
    except (ValueError, AssertionError):
        raise pytest.UsageError(f'--shard {shard}: want I/K with 1 <= I <= K, then optionally :W1,...,WK '
                                '(K positive weights)') from None
    cost = file_costs(items)
    load, mine = [0.0] * k, set()
    for path in sorted(cost, key=lambda f: (-cost[f], str(f))):
        j = min(range(k), key=lambda s: ((load[s] + cost[path]) / weight[s], s))
        load[j] += cost[path]
        if j == i - 1:
            mine.add(path)
    keep = [it for it in items if it.path in mine]
    config.hook.pytest_deselected(items=[it for it in items if it.path not in mine])
    items[:] = keep


#: measured wall seconds per ROS test file (scripts/test_durations.py writes it)
DURATIONS = TESTS / 'durations.json'


def file_costs(items) -> dict:
    """{file path: its expected seconds}: tests/durations.json, and for a file not there its
    number of tests times the mean per test of the files there (1 s each without the table)."""
    import json
    count = {}
    for item in items:
        count[item.path] = count.get(item.path, 0) + 1
    try:
        known = {TESTS.parent / f: float(v) for f, v in json.loads(DURATIONS.read_text()).items()}
    except (OSError, ValueError, AttributeError):
        known = {}
    seen = [p for p in count if p in known]
    per_test = sum(known[p] for p in seen) / sum(count[p] for p in seen) if seen else 1.0
    return {p: known.get(p, n * per_test) for p, n in count.items()}


# ``ros_domain`` (a ROS_DOMAIN_ID of the test's own) and ``swarm`` come from the project's pytest
# plugin, swarm_tools.pytest_plugin (entry point pytest11), which users' tests get too.


@pytest.fixture
def rclpy_context(ros_domain):
    """An initialised rclpy Context of its own on the test's domain; afterwards every node made
    on it is destroyed and it is shut down.  (A shutdown alone leaves the nodes' DDS entities
    alive: a later test on this domain would still be served their transient-local messages.)"""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    ctx = Context()
    rclpy.init(context=ctx, domain_id=ros_domain)
    try:
        yield ctx
    finally:
        gc.collect()
        for node in [o for o in gc.get_objects() if isinstance(o, Node) and o.context is ctx]:
            with contextlib.suppress(Exception):     # already destroyed by the test
                node.destroy_node()
        if ctx.ok():
            rclpy.shutdown(context=ctx)
        ctx.destroy()


class ProcessGroup:
    """Starts child processes in their own process groups and ends them all at teardown."""

    def __init__(self):
        self.procs: list[subprocess.Popen] = []

    def start(self, args, **kw) -> subprocess.Popen:
        kw.setdefault('start_new_session', True)
        kw.setdefault('env', os.environ.copy())
        p = subprocess.Popen([str(a) for a in args], **kw)
        self.procs.append(p)
        return p

    def communicate(self, p: subprocess.Popen, timeout: float) -> str:
        """``p.communicate(timeout)``'s stdout; on a timeout the child is stopped (SIGINT to its
        group) and the test fails with everything it printed."""
        try:
            out = p.communicate(timeout=timeout)[0]
            PRINTED.append((out or '').splitlines())
            return out
        except subprocess.TimeoutExpired:
            try:
                os.killpg(p.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
            try:
                out = p.communicate(timeout=15)[0]
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                out = p.communicate()[0]
            pytest.fail(f'no exit within {timeout} s; it printed:\n{(out or "")[-8000:]}')

    def stop_all(self, grace: float = 5.0):
        for p in self.procs:
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + grace
        for p in self.procs:
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
        for p in self.procs:
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                p.wait(timeout=5)


@pytest.fixture(autouse=True)
def no_refused_inputs(request):
    """A node that refused inputs says so at its end (``rejected N inputs in all: ...``): in a
    child a test started (`Lines`, `ProcessGroup.communicate`, the ``swarm`` fixture's runs) that
    line fails the test, unless the test is marked ``refuses_inputs`` (it sends bad inputs on
    purpose).  A refusal nobody expected is a bug: a check that drops good messages hides
    behind it (every lone agent's realtime state was once dropped, and the runs still passed)."""
    PRINTED.clear()
    yield
    outputs = list(PRINTED)
    start = request.node.funcargs.get('swarm')
    outputs += [run.log for run in getattr(start, 'runs', ())]
    PRINTED.clear()
    lines = refused_summaries(outputs)
    if lines and request.node.get_closest_marker('refuses_inputs') is None:
        pytest.fail('a node refused inputs this test does not send (mark it refuses_inputs if it '
                    'does):\n' + '\n'.join(lines[:20]), pytrace=False)


@pytest.fixture
def processes():
    group = ProcessGroup()
    try:
        yield group
    finally:
        group.stop_all()


@pytest.fixture
def swarm_cmd():
    """Path of the installed ``swarm`` command (the venv's console script)."""
    return str(VENV_BIN / 'swarm')
