"""Helpers the tests share (fixtures are in conftest.py): paths, scenarios, a child's output
lines, rclpy messages and node runs, bags written as the nodes publish them, a tiny full disk.

Test modules import these from here (``from tests.helpers import ...``), never from one
another and never from conftest."""
from __future__ import annotations

import contextlib
import copy
import os
import re
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

#: the checkout (examples/, src/, scripts/, studies/, docs/ are under it)
ROOT = Path(__file__).resolve().parents[1]
#: the stand-ins for stock tools and drivers, run as scripts by path (tests/fakes/)
FAKES = ROOT / 'tests' / 'fakes'


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
    data = copy.deepcopy(SIX_AGENTS)
    data.update(duration=duration, **{'lambda': yaml.safe_load(lam) if isinstance(lam, str) else lam})
    data['leaders'] = {'rule': 'lateral_extremes', 'at': at,
                       'programs': [{'kind': 'constant', 'curvature': c} for c in (curvature, -curvature)]}
    for key, value in overrides.items():
        data[key] = {**data[key], **value} if isinstance(data.get(key), dict) else value
    path = Path(path)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


TWO_AGENTS = """
name: two_agents
seed: 0
dt: 0.05
duration: {duration}
agents:
  positions: [[0, 0], [1, 0]]
  headings: {{rule: cone, half_width: 0.5}}
law: {{kind: homotopy, alpha: 0.02, eta: 0.02, mu: 0.02, r0: 1.5, cutoff_radius: 4.0, leader_gain: 30.0, q0: 1.0}}
lambda: {{kind: constant, value: 0.0}}
"""


def steps_done_reference(name: str, n: int):
    """The batch engine's first n states of shipped scenario ``name`` as a whole lockstep run of
    it makes them: simulated only that far, but with the pair sums its full length chose
    (`compiled_sums.run_sums`: a long run takes the compiled path), so a run stopped after n states
    can be compared bit for bit."""
    from swarm_core.engine.reference import simulate
    from swarm_core.laws.paper.compiled_sums import run_sums
    from swarm_core.scenario.loader import load
    full = load(name)
    compiled = 'on' if run_sums(len(full.names), full.steps) == 'compiled' else 'off'
    return simulate(load(name, duration=(n - 1) * full.dt), compiled=compiled)


def two_agents(path, duration):
    """Write a small scenario of two agents, λ = 0, of ``duration`` s to ``path`` (returned)."""
    path = Path(path)
    path.write_text(TWO_AGENTS.format(duration=duration))
    return path


#: wall s `Lines.wait` lets the reader drain the pipe after the exit (a grandchild that still
#: holds it open keeps it open longer: then the lines so far)
DRAIN = 5.0


#: what the children of the running test printed (`Lines`, `ProcessGroup.communicate`): lists of
#: lines, read after the test for inputs a node refused (`refused_summaries`, tests/conftest.py)
PRINTED: list[list[str]] = []

#: the line a node prints at its end when it refused inputs (`msg_checks.RejectLog.summary`)
REFUSED_SUMMARY = re.compile(r'rejected \d+ inputs in all')


def refused_summaries(outputs) -> list[str]:
    """The lines of ``outputs`` (lists of lines) in which a node says it refused inputs."""
    return [ln.rstrip() for lines in outputs for ln in list(lines) if REFUSED_SUMMARY.search(ln)]


class Lines:
    """Collects a child's stdout lines in a thread (start it with stdout=PIPE, text=True)."""

    def __init__(self, proc):
        self.lines = []
        PRINTED.append(self.lines)
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
        """proc.wait(timeout), then up to `DRAIN` s for the reader to take the last lines from
        the pipe (a line written just before the exit was once not in ``lines`` yet); on a
        timeout the test fails with everything the child printed."""
        try:
            code = proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f'no exit within {timeout} s; it printed:\n' + ''.join(self.lines[-200:]))
        self.t.join(DRAIN)
        return code


# ------------------------------------------------------------------ rclpy nodes and messages
def overrides(d):
    """rclpy Parameters from a dict (a node's parameter_overrides)."""
    from rclpy.parameter import Parameter
    return [Parameter(k, value=v) for k, v in d.items()]


def odom(name, x, y, theta, t, u=0.0):
    """An agent's state as the nodes publish it (nav_msgs/Odometry; stamp = sim time t)."""
    from nav_msgs.msg import Odometry

    from swarm_core.model.frenet import quaternion_from_heading
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
    from swarm_ros.rosutil import make_executor
    from swarm_tools.run.launch import build_nodes
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
    """The pairs of receiver ``k`` out of `laws.paper.pair_sums.neighbour_pairs`' (k, j) arrays, as one
    receiver's (position 0, sender row) list for ``swarm_control(..., receivers=[k])``."""
    mine = pairs[0] == k
    return np.zeros(np.count_nonzero(mine), dtype=np.intp), pairs[1][mine]


# ------------------------------------------------------------------ bags
#: six agents under the global law for 8 s at dt 0.1: a small run to write into a bag
SIX_GLOBAL = """
name: six
dt: 0.1
duration: 8
agents:
  positions: [[-1, 1], [0, 1], [1, 1], [-1, 0], [0, 0], [1, 0]]
law: {kind: global}
"""


def odom_cdr(name, t_ns, x, y, qz, qw, u):
    """A serialised nav_msgs/Odometry state of agent ``name`` at ``t_ns`` (as agents publish it)."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message
    m = Odometry()
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t_ns), 1_000_000_000)
    m.header.frame_id = 'world'
    m.child_frame_id = name
    m.pose.pose.position.x, m.pose.pose.position.y = float(x), float(y)
    m.pose.pose.orientation.z, m.pose.pose.orientation.w = float(qz), float(qw)
    m.twist.twist.angular.z = float(u)
    return serialize_message(m)


def write_states_bag(traj, path, *, hostile=False, flush_every=None):
    """The run's states as the agents publish them (+ hostile extras), one per step and agent."""
    from swarm_core.model.frenet import quaternion_from_heading
    from swarm_tools.bags.mcap_io import BagWriter, qos_dict
    w = BagWriter(path, flush_interval=3600)
    w.add_topic('/swarm/states', 'nav_msgs/msg/Odometry', [qos_dict(history=1, depth=10, reliability=1, durability=2)])
    qz, qw = quaternion_from_heading(traj.theta)
    base = 1_700_000_000 * 10**9
    for s in range(len(traj.t)):
        t_ns = int(round(traj.t[s] * 1e9))
        for k, name in enumerate(traj.names):
            w.write('/swarm/states', odom_cdr(name, t_ns, traj.r[s, k, 0], traj.r[s, k, 1], qz[s, k], qw[s, k],
                                              traj.u[s, k]), base + s * 1_000_000 + k)
        if hostile and s == 10:
            log = base + s * 1_000_000 + 100
            w.write('/swarm/states', odom_cdr('agent_2', t_ns, np.nan, 0, 0, 1, 0), log)        # NaN
            w.write('/swarm/states', odom_cdr('agent_3', t_ns, np.inf, 0, 0, 1, 0), log + 1)    # inf
            w.write('/swarm/states', odom_cdr('agent_4', 10**18, 0, 0, 0, 1, 0), log + 2)      # year 2001
            w.write('/swarm/states', odom_cdr('ghost', t_ns, 500, 500, 0, 1, 0), log + 3)       # a 7th agent
            w.write('/swarm/states', odom_cdr('b/../c d', t_ns, 1, 1, 0, 1, 0), log + 4)
        if flush_every and s % flush_every == 0:
            w.maybe_flush(force=True)
    return w


def write_run_bag(traj, path, *, leaders=True, lam=True, cut_after=None, metrics_cutoff=None,
              target=None, barrier=None):
    """The run as the ROS nodes would have published it, written with BagWriter (with
    ``metrics_cutoff``: one /world/metrics message carrying it, as the world publishes; with
    ``target`` / ``barrier``: the world's latched /world/target and /world/barrier)."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64, String

    from swarm_core.model.frenet import quaternion_from_heading
    from swarm_tools.bags.mcap_io import BagWriter, qos_dict

    vol = [qos_dict(history=1, depth=10, reliability=1, durability=2)]
    latched = [qos_dict(history=1, depth=1, reliability=1, durability=1)]
    w = BagWriter(path, flush_interval=3600)
    w.add_topic('/swarm/states', 'nav_msgs/msg/Odometry', vol)
    if metrics_cutoff is not None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        w.add_topic('/world/metrics', 'diagnostic_msgs/msg/DiagnosticArray', vol)
        st = DiagnosticStatus(name='swarm', hardware_id='world', values=[
            KeyValue(key='clusters', value='1'), KeyValue(key='cutoff_radius', value=str(metrics_cutoff))])
        w.write('/world/metrics', serialize_message(DiagnosticArray(status=[st])), 1_700_000_000 * 10**9)
    if target is not None:
        from geometry_msgs.msg import PointStamped
        w.add_topic('/world/target', 'geometry_msgs/msg/PointStamped', latched)
        m = PointStamped()
        m.point.x, m.point.y = map(float, target)
        w.write('/world/target', serialize_message(m), 1_700_000_000 * 10**9)
    if barrier is not None:
        from geometry_msgs.msg import Point32, PolygonStamped
        w.add_topic('/world/barrier', 'geometry_msgs/msg/PolygonStamped', latched)
        m = PolygonStamped()
        m.polygon.points = [Point32(x=float(x), y=float(y)) for x, y in barrier]
        w.write('/world/barrier', serialize_message(m), 1_700_000_000 * 10**9)
    if lam:
        w.add_topic('/swarm/lambda', 'std_msgs/msg/Float64', vol)
    if leaders:
        w.add_topic('/swarm/leaders', 'std_msgs/msg/String', latched)
    base = 1_700_000_000 * 10**9
    last_leaders = None
    qz, qw = quaternion_from_heading(traj.theta)
    for s in range(len(traj.t)):
        log = base + s * 1_000_000
        t_ns = int(round(traj.t[s] * 1e9))
        for k, name in enumerate(traj.names):
            m = Odometry()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
            m.header.frame_id = 'world'
            m.child_frame_id = name
            m.pose.pose.position.x = float(traj.r[s, k, 0])
            m.pose.pose.position.y = float(traj.r[s, k, 1])
            m.pose.pose.orientation.z = float(qz[s, k])
            m.pose.pose.orientation.w = float(qw[s, k])
            m.twist.twist.linear.x = 1.0
            # as agents publish it: the u held over the step that ended at this state
            m.twist.twist.angular.z = float(traj.u[s - 1, k]) if s > 0 else 0.0
            w.write('/swarm/states', serialize_message(m), log + k)
        # as the lockstep commander does: step s's inputs are decided from step s's states
        if lam:
            w.write('/swarm/lambda', serialize_message(Float64(data=float(traj.lam[s]))), log + 1000)
        who = tuple(np.array(traj.names)[traj.leader[s]])
        if leaders and who != last_leaders:
            w.write('/swarm/leaders', serialize_message(String(data=','.join(who))), log + 2000)
            last_leaders = who
        if cut_after is not None and s == cut_after:
            w.maybe_flush(force=True)
            w._fh.flush()
            return path          # like a killed recorder: no summary, no footer
    w.close()
    return path


# ------------------------------------------------------------------ disks and packages
@contextlib.contextmanager
def tiny_disk(where, *, full=True, read_only=False):
    """A 256 KiB tmpfs at ``where``: filled up (``full``) or remounted read-only."""
    where.mkdir()
    if os.geteuid() != 0 or subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=256k', 'tmpfs', str(where)],
                                           capture_output=True).returncode != 0:
        pytest.skip('cannot mount a tmpfs here')
    try:
        if full:
            with open(where / 'filler', 'wb', buffering=0) as f, contextlib.suppress(OSError):
                while True:
                    f.write(b'\0' * 4096)
        if read_only:
            subprocess.run(['mount', '-o', 'remount,ro', str(where)], check=True)
        yield where
    finally:
        subprocess.run(['umount', '-l', str(where)], check=False)


PACKAGES = ['homotopy_commander', 'swarm_agent', 'swarm_core', 'swarm_robots', 'swarm_ros', 'swarm_tools',
            'swarm_world']


def console_scripts(pkg) -> list[str]:
    """The console_scripts names a package's setup.py declares (not its other entry points,
    such as swarm_robots' engine in the group swarm_core.engines)."""
    import ast
    tree = ast.parse((ROOT / 'src' / pkg / 'setup.py').read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == 'entry_points':
            groups = ast.literal_eval(node.value)
            return sorted(spec.split('=')[0].strip() for spec in groups.get('console_scripts', []))
    return []



# ------------------------------------------------------------------ the graph as stock tools see it
def node_inputs(full_name, want, timeout=30.0):
    """The topics ``ros2 node info FULL_NAME`` lists under Subscribers (the faithful stand-in,
    `tests.fakes.ros2cli_verbs.node_info`: a fresh participant, 0.5 s of discovery, one look),
    run again as a user would until it lists ``want`` (a set) or ``timeout`` s passed; the last
    listing (a node not found yet: an empty set)."""
    from tests.fakes.ros2cli_verbs import NodeNotFound, node_info
    end = time.monotonic() + timeout
    seen = set()
    while time.monotonic() < end:
        try:
            seen = set(node_info(full_name)['subscribers'])
        except NodeNotFound:
            seen = set()
        if seen == set(want):
            break
    return seen


# ------------------------------------------------------------------ users' laws that fail
#: a user's law file with a law for each way a law can fail during a run (after t = 5, so that the
#: scenario's check at t = 0 passes and the run has steps to save), and a class that is no law
FAULTY_LAWS = '''\
import sys
import threading

import numpy as np

from swarm_core.laws import Law, param


class Raises(Law):
    gain = param(0.1, lo=0.0, hi=1.0, doc='a gain')

    def control(self, view):
        if view.t > 5:
            raise RuntimeError('boom after t = 5')
        return np.zeros(view.receivers.size)


class WrongShape(Law):
    def control(self, view):
        return np.zeros(view.receivers.size + (view.t > 5))


class NotFinite(Law):
    def control(self, view):
        return np.full(view.receivers.size, np.nan if view.t > 5 else 0.0)


class Exits(Law):
    def control(self, view):
        if view.t > 5:
            sys.exit(3)
        return np.zeros(view.receivers.size)


class OwnInterrupt(Law):
    def control(self, view):
        if view.t > 5:
            raise KeyboardInterrupt
        return np.zeros(view.receivers.size)


class ClosesGenerator(Law):
    def control(self, view):
        if view.t > 5:
            raise GeneratorExit('closed')
        return np.zeros(view.receivers.size)


class BadArray(Law):
    def control(self, view):
        class Reads:
            def __array__(self, dtype=None, copy=None):
                raise RuntimeError('cannot be read')
        return Reads() if view.t > 5 else np.zeros(view.receivers.size)


class ComplexU(Law):
    def control(self, view):
        return np.zeros(view.receivers.size) + (1j if view.t > 5 else 0)


class LeavesThread(Law):
    def control(self, view):
        if view.t > 5:
            threading.Thread(target=threading.Event().wait, name='never-ends').start()
        return np.zeros(view.receivers.size)


class NotALaw:
    pass
'''


def faulty_law_scenario(where, kind, duration=10.0, **law):
    """A six-agent scenario file in directory ``where`` whose law is ``kind`` (``faulty.py:Raises``...:
    `FAULTY_LAWS` is written next to it as faulty.py); ``law``: further law parameters."""
    where = Path(where)
    (where / 'faulty.py').write_text(FAULTY_LAWS)
    path = where / 'faulty.yaml'
    path.write_text(yaml.safe_dump({'name': 'faulty', 'seed': 0, 'dt': 0.1, 'duration': duration,
                                    'agents': {'count': 6}, 'law': {'kind': kind, **law}}, sort_keys=False))
    return path
