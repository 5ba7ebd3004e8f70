"""Shared fixtures.

DDS isolation: every test that touches ROS gets its own ROS_DOMAIN_ID (``ros_domain``),
discovery stays on localhost, and every process a test starts is ended by the test
(``processes``), also when it fails.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

# A suite started as a background job of a script (`bash .ci/run &`) inherits SIGINT ignored,
# and every process it starts would ignore the Ctrl-C that the tests send them: undo that here.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

ROOT = Path(__file__).resolve().parents[1]
VENV_BIN = Path(sys.executable).parent


def pytest_addoption(parser):
    parser.addoption('--shard', default=None, metavar='I/K', help=(
        'run only shard I of K (1-based): the selected tests\' files dealt out by their number of '
        'tests, the largest first, each to the shard with the fewest (scripts/test.sh runs the ROS '
        'tests as two shards; each test claims its own ROS_DOMAIN_ID, so shards run side by side)'))


@pytest.hookimpl(trylast=True)          # after -m / -k have deselected
def pytest_collection_modifyitems(config, items):
    shard = config.getoption('shard')
    if not shard:
        return
    try:
        i, k = (int(v) for v in shard.split('/'))
        assert 1 <= i <= k
    except (ValueError, AssertionError):
        raise pytest.UsageError(f'--shard {shard}: want I/K with 1 <= I <= K') from None
    count = {}
    for item in items:
        count[item.path] = count.get(item.path, 0) + 1
    load, mine = [0] * k, set()
    for path in sorted(count, key=lambda f: (-count[f], str(f))):
        j = load.index(min(load))
        load[j] += count[path]
        if j == i - 1:
            mine.add(path)
    keep = [it for it in items if it.path in mine]
    config.hook.pytest_deselected(items=[it for it in items if it.path not in mine])
    items[:] = keep

# ``ros_domain`` (a ROS_DOMAIN_ID of the test's own) and ``swarm`` come from the project's pytest
# plugin, swarm_tools.pytest_plugin (entry point pytest11), which users' tests get too.


@pytest.fixture
def rclpy_context(ros_domain):
    """An initialised rclpy Context of its own on the test's domain; shut down afterwards."""
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx, domain_id=ros_domain)
    try:
        yield ctx
    finally:
        if ctx.ok():
            rclpy.shutdown(context=ctx)


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
            return p.communicate(timeout=timeout)[0]
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


#: the six agents of Figs. 3-4 under the homotopy law: the scenario of most tests
SIX_AGENTS = {
    'name': 'homotopy_short',
    'seed': 0,
    'dt': 0.05,
    'agents': {'positions': [[-1, 1], [0, 1], [1, 1], [-1, 0], [0, 0], [1, 0]],
               'headings': {'rule': 'cone', 'half_width': 0.7853981633974483}},
    'law': {'kind': 'homotopy', 'alpha': 0.02, 'eta': 0.02, 'mu': 0.02, 'r0': 1.5, 'cutoff_radius': 4.0,
            'leader_gain': 30.0, 'q0': 1.0},
}


def short_homotopy(path, *, duration, lam, at, curvature=0.01, **overrides):
    """Write `SIX_AGENTS` to ``path`` (returned) as a scenario of ``duration`` s: λ schedule
    ``lam`` (a dict or YAML text), the two lateral-extreme leaders chosen at ``at`` steering
    ±``curvature``.  ``overrides``: further top-level keys (seed=5, faults=[...]); a dict is
    merged into the base's dict of that key (law={'cutoff_radius': 5.0})."""
    import copy

    import yaml
    data = copy.deepcopy(SIX_AGENTS)
    data.update(duration=duration, **{'lambda': yaml.safe_load(lam) if isinstance(lam, str) else lam})
    data['leaders'] = {'rule': 'lateral_extremes', 'at': at,
                       'programs': [{'kind': 'constant', 'curvature': c} for c in (curvature, -curvature)]}
    for key, value in overrides.items():
        data[key] = {**data[key], **value} if isinstance(data.get(key), dict) else value
    path = Path(path)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


class Lines:
    """Collects a child's stdout lines in a thread (start it with stdout=PIPE, text=True)."""

    def __init__(self, proc):
        self.lines = []
        self.t = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self.t.start()

    def _read(self, proc):
        for line in proc.stdout:
            self.lines.append(line)

    def wait_for(self, text, timeout):
        """Whether a line holds ``text`` (or, ``text`` a function, a line makes it true) within
        ``timeout`` s."""
        hit = text if callable(text) else (lambda ln: text in ln)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if any(hit(ln) for ln in list(self.lines)):
                return True
            time.sleep(0.1)
        return False

    def wait(self, proc, timeout):
        """proc.wait(timeout); on a timeout the test fails with everything the child printed."""
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f'no exit within {timeout} s; it printed:\n' + ''.join(self.lines[-200:]))


def overrides(d):
    """rclpy Parameters from a dict (a node's parameter_overrides)."""
    from rclpy.parameter import Parameter
    return [Parameter(k, value=v) for k, v in d.items()]


def odom(name, x, y, theta, t, u=0.0):
    """An agent's state as the nodes publish it (nav_msgs/Odometry; stamp = sim time t)."""
    from nav_msgs.msg import Odometry

    from swarm_core.frenet import quaternion_from_heading
    from swarm_ros import protocol as P
    m = Odometry()
    m.header.frame_id, m.child_frame_id = 'world', name
    m.header.stamp.sec, m.header.stamp.nanosec = P.time_to_stamp(t)
    m.pose.pose.position.x, m.pose.pose.position.y = x, y
    qz, qw = quaternion_from_heading(theta)
    m.pose.pose.orientation.z, m.pose.pose.orientation.w = float(qz), float(qw)
    m.twist.twist.angular.z = u
    return m


def run_nodes(params, ctx, timeout):
    """World, commander and agents from `node_parameters`' output, in one executor on ``ctx``,
    spun until the world is done (at most ``timeout`` s); returns (done?, world, [all nodes])."""
    from swarm_tools.launch import build_nodes
    from swarm_ros.rosutil import make_executor
    world, commander, agents = build_nodes(params, ctx, log=lambda *a, **k: None)
    ex = make_executor(ctx)
    nodes = [world, commander, *agents]
    for nd in nodes:
        ex.add_node(nd)
    done = spin_for(ex, lambda: world.done, timeout)
    return done, world, nodes


def spin_for(ex, cond, timeout=10.0):
    """Spin ``ex`` until ``cond()`` or ``timeout`` s; returns cond()."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        ex.spin_once(timeout_sec=0.05)
    return cond()


def pairs_of_one(pairs, k):
    """The pairs of receiver ``k`` out of `engine.neighbour_pairs`' (k, j) arrays, as one
    receiver's (position 0, sender row) list for ``swarm_control(..., receivers=[k])``."""
    import numpy as np
    mine = pairs[0] == k
    return np.zeros(np.count_nonzero(mine), dtype=np.intp), pairs[1][mine]
