"""``swarm report BAG.mcap``: metrics and figures from a recorded run, from the bag alone
(a run directory without a bag, or a trajectory.npz: `run_report`).

The trajectory is rebuilt from ``/swarm/states`` (``nav_msgs/Odometry``: ``child_frame_id`` =
agent, stamp = sim time, pose = position + planar quaternion, ``twist.angular.z`` = the u held
over the step that ENDED at that stamp (see `swarm_ros.protocol`), so the u applied from the
state of t_n on is read from the state of t_(n+1); the newest state's u is not known yet (NaN)),
λ from ``/swarm/lambda`` and the leaders from ``/swarm/leaders`` where the bag has them (each
message belongs to the newest step whose states were received before it, and holds until the
next), the target and barrier from ``/world/target`` / ``/world/barrier``.  Writes
``trajectory.npz`` (as `Trajectory.save`), ``metrics.json`` (time series + summary), a figure
like the paper's and, with ``--animate``, a GIF.  Bags cut short (a killed recorder) are read up
to their last complete chunk.

A 3D run (the ``/swarm/run`` announcement's ``dim``: `swarm_tools.bags.report3d`) is rebuilt in
3D: r (T, N, 3), the frames x, y, z from the quaternions, u = angular.z and v = −angular.y,
with a 3D figure (a 3D view, top and side views) and no GIF; its ground is the one the
announcement tells, else the agents' ``ground`` parameter on ``/parameter_events`` (a bag of an
older run), else the report says in one line that the bag does not tell it (`report3d.bag_ground`).
"""
from __future__ import annotations

import argparse
import json
import re
import struct
import sys
from pathlib import Path

import numpy as np

from swarm_core.analysis import outputs as analysis
from swarm_core.analysis.plots import plot_run
from swarm_core.checks import LAMBDA_BOUND
from swarm_core.engine.trajectory import Trajectory
from swarm_core.laws import Law
from swarm_core.model.frenet import yaw_from_quaternion
from swarm_core.scenario.loader import BarrierSpec
from swarm_core.scenario.placement import AGENT_NAME
from swarm_ros.runinfo import parse_run
from swarm_tools.bags.animate import animate
from swarm_tools.bags.mcap_io import (
    announced_roster,
    iter_messages,
    parse_float64,
    parse_string,
    resolve_bag,
)
from swarm_tools.bags.report3d import bad_row_3d, bag_ground, geometry_3d, ground_of, run_dim, states_on_3d
from swarm_tools.bags.run_report import report_run, run_trajectory
from swarm_tools.odometry3d import cdr_to_odometry_3d

STATES = '/swarm/states'
LAMBDA = '/swarm/lambda'
LEADERS = '/swarm/leaders'
TARGET = '/world/target'
BARRIER = '/world/barrier'
METRICS = '/world/metrics'
EVENTS = '/swarm/events'
RUN = '/swarm/run'
PARAMETERS = '/parameter_events'


def natural_key(name: str):
    return [int(p) if p.isdigit() else p for p in re.split(r'(\d+)', name)]


class _Decoder:
    """mcap_ros2's dynamic CDR decoder, one per schema (for the few non-state messages)."""

    def __init__(self):
        from mcap_ros2.decoder import DecoderFactory
        self._factory = DecoderFactory()
        self._cache = {}

    def __call__(self, m):
        key = m.schema.id
        if key not in self._cache:
            self._cache[key] = self._factory.decoder_for('cdr', m.schema)
        return self._cache[key](m.data)


def _strings(obj, depth=0):
    """Every string inside a decoded message (depth-limited walk)."""
    if depth > 6:
        return
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _strings(v, depth + 1)
    elif hasattr(obj, '__slots__') or hasattr(obj, '__dict__'):
        names = getattr(obj, '__slots__', None) or list(vars(obj))
        for n in names:
            yield from _strings(getattr(obj, n, None), depth + 1)


def leader_names(msg, known) -> list[str]:
    """Agent names mentioned in a leaders message, whatever standard type carries them
    (``std_msgs/String`` "agent_0,agent_5" or JSON, a string array, diagnostics, …)."""
    found = []
    for s in _strings(msg):
        for tok in re.findall(r'[A-Za-z_][A-Za-z0-9_]*', s):
            if tok in known and tok not in found:
                found.append(tok)
    return found


#: states with a stamp beyond this (sim seconds) are absurd and left out
MAX_STAMP_S = 1e7
#: |x|, |y| beyond this are absurd (a scenario's coordinates are at most 1e6)
MAX_COORD = 1e9
#: without a roster, a name with fewer states than this fraction of the median agent's (and
#: not named in /swarm/events) is not one of the run's agents (a spoofed or stray publisher)
MIN_SHARE = 0.1


def check_states(per_agent: dict, events=(), agents=None, warn=None, dim=2) -> dict:
    """``per_agent`` without what cannot be a state of the run: non-finite or absurd values
    (in 3D: z, the frame and v too),
    negative or absurd stamps, names that are not agent names, and (``agents`` given) names
    not in the roster, or (no roster) names with few states that no event mentions.  ``warn``
    gets one line per kind of problem, with counts."""
    warn = warn or (lambda line: print(f'swarm report: {line}', file=sys.stderr))
    bad_values = bad_stamps = 0
    out = {}
    for name, rows in per_agent.items():
        keep = []
        for row in rows:
            stamp, _, x, y, qz, qw, wz = row[:7]
            if not (np.isfinite([x, y, qz, qw]).all() and abs(x) <= MAX_COORD and abs(y) <= MAX_COORD
                    and not np.isinf(wz)) or (dim == 3 and bad_row_3d(row, MAX_COORD)):
                bad_values += 1
            elif not 0 <= stamp <= MAX_STAMP_S * 1e9:
                bad_stamps += 1
            else:
                keep.append(row)
        if keep:
            out[name] = keep
    if bad_values:
        warn(f'left out {bad_values} states with non-finite or absurd values')
    if bad_stamps:
        warn(f'left out {bad_stamps} states with stamps outside 0..{MAX_STAMP_S:g} s')
    named = {ev.get('agent') for ev in events}
    if agents is not None:
        roster = set(agents)
        unknown = sorted(n for n in out if n not in roster)
        why = 'not in the run\'s roster'
    else:
        med = float(np.median([len(v) for v in out.values()])) if out else 0.0
        unknown = sorted(n for n, v in out.items()
                         if not AGENT_NAME.fullmatch(n) or (len(v) < MIN_SHARE * med and n not in named))
        why = f'not an agent name, or fewer than {MIN_SHARE:.0%} of the states of the others'
    if unknown:
        shown = ', '.join(repr(n) for n in unknown[:5]) + (', ...' if len(unknown) > 5 else '')
        warn(f'left out {sum(len(out[n]) for n in unknown)} states of {len(unknown)} unknown '
             f'sender{"s" if len(unknown) > 1 else ""} ({why}): {shown}')
        for n in unknown:
            del out[n]
    return out


class _Undecodable(Exception):
    """A message whose bytes do not parse (counted, left out)."""


def _parsed(parse, data):
    try:
        return parse(data)
    except (struct.error, IndexError, ValueError):
        raise _Undecodable from None


class _Reading:
    """What `read_run` has read of a bag so far; each topic's reader adds to it."""

    def __init__(self, cutoff_radius):
        self.decode = _Decoder()
        self.per_agent: dict[str, list] = {}
        self.lam_events, self.leader_msgs, self.events = [], [], []
        self.target = self.barrier = None
        self.target3, self.points3 = None, []   # the world's geometry read as 3D
        self.w = cutoff_radius              # given, else the first found on /world/metrics
        self.undecodable = 0
        self.bad_geometry, self.bad_target3 = [], []
        self.announced = None               # the first /swarm/run announcement
        self.param_ground = None            # the first (True, floor) on /parameter_events


def _read_state(r: _Reading, m):
    name, sec, nsec, (x, y, z), (qx, qy, qz, qw), wy, wz, _ = _parsed(cdr_to_odometry_3d, m.data)
    r.per_agent.setdefault(name, []).append(
        (sec * 1_000_000_000 + nsec, m.log_time, x, y, qz, qw, wz, z, qx, qy, wy))


def _read_lambda(r: _Reading, m):
    v = _parsed(parse_float64, m.data)
    if LAMBDA_BOUND.ok(v):
        r.lam_events.append((m.log_time, v))


def _read_event(r: _Reading, m):
    try:
        ev = json.loads(parse_string(m.data))
    except ValueError:
        return
    if isinstance(ev, dict) and isinstance(ev.get('t'), (int, float)):
        r.events.append(ev)


def _read_leaders(r: _Reading, m):
    r.leader_msgs.append((m.log_time, r.decode(m)))


def _read_target(r: _Reading, m):
    p = r.decode(m).point
    if np.isfinite([p.x, p.y]).all() and max(abs(p.x), abs(p.y)) <= MAX_COORD:
        r.target = (float(p.x), float(p.y))
    else:
        r.bad_geometry.append(f'target ({p.x}, {p.y})')
    if np.isfinite([p.x, p.y, p.z]).all() and max(abs(p.x), abs(p.y), abs(p.z)) <= MAX_COORD:
        r.target3 = (float(p.x), float(p.y), float(p.z))
    else:
        r.bad_target3.append(f'target ({p.x}, {p.y}, {p.z})')


def _read_barrier(r: _Reading, m):
    r.points3 = [(float(p.x), float(p.y), float(p.z)) for p in r.decode(m).polygon.points]
    pts = [q[:2] for q in r.points3]
    r.barrier = None
    if pts:
        try:
            r.barrier = [tuple(q) for q in BarrierSpec(points=pts).points]
        except ValueError as err:
            r.bad_geometry.append(f'barrier of {len(pts)} points ({" ".join(str(err).split())[:120]})')


def _read_announcement(r: _Reading, m):
    if r.announced is None:
        r.announced = parse_run(_parsed(parse_string, m.data))


def _read_parameters(r: _Reading, m):
    if r.param_ground is None and b'ground' in m.data:
        try:
            said = ground_of(r.decode(m))
        except Exception:       # a message the dynamic decoder cannot read: no floor from it
            return
        if said[0]:
            r.param_ground = said


def _read_metrics(r: _Reading, m):
    if r.w is not None:
        return
    try:
        for st in r.decode(m).status:
            for kv in st.values:
                if kv.key == 'cutoff_radius':
                    r.w = float(kv.value)
    except (AttributeError, ValueError):
        pass


#: the reader of each topic `read_run` uses
READERS = {STATES: _read_state, LAMBDA: _read_lambda, EVENTS: _read_event, LEADERS: _read_leaders,
           TARGET: _read_target, BARRIER: _read_barrier, METRICS: _read_metrics, RUN: _read_announcement,
           PARAMETERS: _read_parameters}


def read_run(path, *, cutoff_radius=None, agents=None, warn=None) -> dict:
    """Everything the report needs from a bag: per-agent state lists, λ / leader events,
    target, barrier, and whether the file was cut short.  States are checked
    (`check_states`; ``agents``: the run's roster, if known).  A 3D run's ``ground``
    (`report3d.bag_ground`); ``no_ground``: the line to say where the bag does not tell it."""
    r = _Reading(cutoff_radius)
    stats: dict = {}
    for m in iter_messages(path, stats=stats):
        read = READERS.get(m.topic)
        if read is None:
            continue
        try:
            read(r, m)
        except _Undecodable:
            r.undecodable += 1
    say = warn or (lambda line: print(f'swarm report: {line}', file=sys.stderr))
    dim = run_dim(r.announced, r.per_agent)
    target, barrier, bad, ground, no_ground = r.target, r.barrier, r.bad_geometry, None, None
    if dim == 3:                # the world's geometry and floor in space
        bad = list(r.bad_target3)
        (target, barrier), (ground, no_ground) = (geometry_3d(r.target3, r.points3, bad),
                                                  bag_ground(r.announced, r.param_ground))
    if r.undecodable:
        say(f'left out {r.undecodable} messages that could not be decoded')
    if stats.get('damaged'):
        say(f'skipped {stats["damaged"]} damaged chunks of the bag (first: {stats["damage"]})')
    if bad:
        say(f'ignored {len(bad)} unusable world messages: {bad[0]}')
    per_agent = check_states(r.per_agent, r.events, agents, warn, dim)
    return dict(per_agent=per_agent, lam_events=r.lam_events, leader_msgs=r.leader_msgs, events=r.events,
                target=target, barrier=barrier, truncated=stats.get('truncated', False), w=r.w, dim=dim,
                ground=ground, no_ground=no_ground)


def _state_arrays(per_agent: dict) -> dict:
    """{agent: (stamps, log times, rows of x, y, qz, qw, u, z, qx, qy, angular.y)} sorted by
    stamp; of a repeated stamp the later state counts."""
    arrays = {}
    for name, rows in per_agent.items():
        stamps = np.array([row[0] for row in rows], dtype=np.int64)
        logs = np.array([row[1] for row in rows], dtype=np.int64)
        vals = np.array([row[2:] for row in rows], dtype=np.float64)   # x, y, qz, qw, u, z, qx, qy, wy
        order = np.argsort(stamps, kind='stable')
        stamps, logs, vals = stamps[order], logs[order], vals[order]
        keep = np.ones(len(stamps), dtype=bool)
        keep[:-1] = stamps[1:] != stamps[:-1]
        arrays[name] = (stamps[keep], logs[keep], vals[keep])
    return arrays


def _faults(events, agents) -> tuple[dict, dict]:
    """From the events: ({agent: stamp (ns) it was killed or lost}, {agent: [(from, until)
    stamps of each freeze]})."""
    gone, frozen = {}, {}
    for ev in events:
        ns = int(round(float(ev['t']) * 1e9))
        if ev.get('kind') in ('kill', 'lost') and ev.get('agent') in agents:
            gone[ev['agent']] = min(ns, gone.get(ev['agent'], ns))
        elif ev.get('kind') == 'freeze' and ev.get('agent') in agents and 'until' in ev:
            frozen.setdefault(ev['agent'], []).append((ns, int(round(float(ev['until']) * 1e9))))
    return gone, frozen


def _grid(arrays: dict, gone: dict, frozen: dict):
    """(stamps of the trajectory, alignment): the stamps every agent has (a dead or frozen
    agent's missing ones do not count) if they are nine in ten of all, 'lockstep'; else every
    stamp from the first at which all agents have reported, 'forward_filled'."""
    all_stamps = np.unique(np.concatenate([v[0] for v in arrays.values()]))
    common = all_stamps
    for name, v in arrays.items():
        covered = v[0]
        if name in gone:
            covered = np.union1d(covered, all_stamps[all_stamps >= gone[name]])
        for a, b in frozen.get(name, ()):
            covered = np.union1d(covered, all_stamps[(all_stamps > a) & (all_stamps <= b)])
        common = np.intersect1d(common, covered, assume_unique=True)
    if len(common) >= 0.9 * len(all_stamps):
        return common, 'lockstep'
    start = max(v[0][0] for v in arrays.values())
    return all_stamps[all_stamps >= start], 'forward_filled'


def _states_on(grid, names, arrays: dict, gone: dict):
    """r, theta, u of each agent at each stamp of ``grid`` (its newest state; NaN once it is
    gone), and the first log time of each stamp's states."""
    T, n = len(grid), len(names)
    r, theta, u = np.empty((T, n, 2)), np.empty((T, n)), np.empty((T, n))
    log_first = np.full(T, np.iinfo(np.int64).max, dtype=np.int64)
    for k, name in enumerate(names):
        s, logs, vals = arrays[name]
        # twist.angular.z of a state is the u held over the step that ended there: the u
        # applied from one of its states on is the next state's; the newest is unknown
        u_from = np.append(vals[1:, 4], np.nan)
        idx = np.searchsorted(s, grid, side='right') - 1
        rows = vals[idx]
        r[:, k, 0], r[:, k, 1] = rows[:, 0], rows[:, 1]
        theta[:, k] = yaw_from_quaternion(rows[:, 2], rows[:, 3])
        u[:, k] = u_from[idx]
        log_first = np.minimum(log_first, logs[idx])
        if name in gone:
            dead = grid >= gone[name]
            r[dead, k], theta[dead, k], u[dead, k] = np.nan, np.nan, np.nan
    return r, theta, u, log_first


def _inputs_on(run: dict, names, log_first):
    """λ and leaders at each stamp: a message belongs to the newest step whose states came
    before it (in lockstep the commander decides step n's inputs from step n's states), and
    holds until the next one; before the first message: the first one (λ), none (leaders)."""
    T = len(log_first)
    next_first = np.append(log_first[1:], np.iinfo(np.int64).max)
    lam = np.full(T, np.nan)
    if run['lam_events']:
        ev = sorted(run['lam_events'])
        ev_t = np.array([e[0] for e in ev], dtype=np.int64)
        ev_v = np.array([e[1] for e in ev])
        j = np.searchsorted(ev_t, next_first, side='left') - 1
        lam = ev_v[np.clip(j, 0, None)]
    leader = np.zeros((T, len(names)), dtype=bool)
    if run['leader_msgs']:
        ev = sorted(run['leader_msgs'], key=lambda e: e[0])
        ev_t = np.array([e[0] for e in ev], dtype=np.int64)
        sets = [np.isin(names, leader_names(msg, set(names))) for _, msg in ev]
        j = np.searchsorted(ev_t, next_first, side='left') - 1
        for i in range(T):
            if j[i] >= 0:
                leader[i] = sets[j[i]]
    return lam, leader


def rebuild_trajectory(run: dict):
    """A `swarm_core.engine.reference.Trajectory` from the states in a bag.

    Lockstep runs (every agent has a state at every stamp) are taken as they are; otherwise
    each agent's newest state at each stamp is used (forward fill) from the first stamp at
    which every agent has reported.

    Faults (``/swarm/events``): an agent killed or lost has NaN rows from that time on and its
    missing stamps do not count against lockstep alignment; a frozen agent holds its state
    over the freeze (its stamps there are not missing either).  A 3D run (``run['dim']``)
    gives r (T, N, 3), the frames x, y, z and the controls u and v."""

    names = sorted(run['per_agent'], key=natural_key)
    if not names:
        raise ValueError(f'no {STATES} messages in the bag')
    arrays = _state_arrays(run['per_agent'])
    gone, frozen = _faults(run.get('events', ()), arrays)
    grid, mode = _grid(arrays, gone, frozen)
    frames = {}
    if run.get('dim', 2) == 3:
        r, (fx, fy, fz), u, v, log_first = states_on_3d(grid, names, arrays, gone)
        theta, frames = None, dict(x=fx, y=fy, z=fz, v=v)
    else:
        r, theta, u, log_first = _states_on(grid, names, arrays, gone)
    lam, leader = _inputs_on(run, names, log_first)
    t = grid.astype(np.float64) * 1e-9
    T = len(grid)
    meta = dict(source='bag', alignment=mode, steps=T - 1,
                dt=float(np.median(np.diff(t))) if T > 1 else 0.0,
                states=sum(len(v) for v in run['per_agent'].values()),
                truncated_bag=bool(run['truncated']),
                has_lambda=bool(run['lam_events']), has_leaders=bool(run['leader_msgs']))
    return Trajectory(names, t, r, theta, u, lam, leader, meta, **frames)


def report_summary(traj, series, w) -> dict:
    """`swarm_core.analysis.outputs.run_summary` with what the bag tells: names, start, step, cutoff
    radius, leaders, alignment."""
    return dict(analysis.run_summary(traj, series), names=list(traj.names),
                t_start=float(traj.t[0]), dt=traj.meta.get('dt') or 1.0, cutoff_radius=w,
                one_leader_per_cluster_fraction=float(np.mean(series['one_leader_per_cluster']))
                if traj.leader.any() else None,
                leaders_seen=[traj.names[k] for k in np.flatnonzero(traj.leader.any(axis=0))],
                **{k: traj.meta[k] for k in ('alignment', 'truncated_bag', 'has_lambda',
                                             'has_leaders')})


def plot(traj, series, path, *, title, w, target, barrier, ground=None):
    """The run's figure (`swarm_core.analysis.plots.plot_run`; a 3D run: 3D, top and side views)."""
    return plot_run(traj, series, path, title=title, w=w, target=target, barrier=barrier, ground=ground)


def _warn(line):
    print(f'swarm report: {line}', file=sys.stderr)


def write_report(out, traj, series, summary, run, a, w) -> list:
    """trajectory.npz, metrics.json, the figure and (``--animate``) the GIF into ``out``
    (each written whole, never through a link: `swarm_core.files`); the names written."""
    traj.save(out / 'trajectory.npz')
    analysis.write_atomic(out / 'metrics.json', analysis.dumps(dict(summary=summary, series=series)))
    wrote = ['trajectory.npz', 'metrics.json']
    if not a.no_figure and len(traj.t) > 1:
        plot(traj, series, out / 'report.png', w=w, target=run['target'], barrier=run['barrier'],
             ground=run.get('ground'),
             title=f'{Path(summary["bag"]).name}: {len(traj.names)} agents, t = {traj.t[0]:g}..{traj.t[-1]:g}')
        wrote.append('report.png')
    if a.animate:
        if traj.dim == 3:
            _warn('--animate draws planar runs only: no animation of a 3D run')
        elif animate(traj, out / 'swarm.gif', w=w, target=run['target'], barrier=run['barrier']):
            wrote.append('swarm.gif')
        else:
            _warn('pillow is not installed: no animation')
    return wrote


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog='swarm report',
        description='Metrics (metrics.json), trajectory (trajectory.npz) and a figure like the '
                    "paper's from a recorded MCAP bag, from the bag alone.")
    p.add_argument('bag', help='an .mcap file or a bag directory written by swarm record / '
                               'swarm run --record; or a run directory (trajectory.npz, metrics.json)')
    p.add_argument('--out', default=None, help='output directory (default: BAG without .mcap + _report)')
    p.add_argument('--cutoff-radius', '-w', type=float, default=None,
                   help='cluster radius w: agents closer than w are connected (default: from '
                        'the cutoff_radius on the bag\'s /world/metrics, else the law\'s default)')
    p.add_argument('--every', type=float, default=1.0,
                   help='metric sampling interval in sim time units (default 1.0)')
    p.add_argument('--animate', action='store_true', help='also write an animation (GIF)')
    p.add_argument('--no-figure', action='store_true', help='skip the PNG figure')
    a = p.parse_args(argv)
    if a.cutoff_radius is not None and not a.cutoff_radius > 0:
        p.error('--cutoff-radius must be > 0')
    if not a.every > 0:
        p.error('--every must be > 0')
    return a


def main(argv=None) -> int:
    a = parse_args(sys.argv[1:] if argv is None else argv)
    given = Path(a.bag)
    npz = run_trajectory(given)
    if npz is not None:                   # a run directory without a bag (a 3D run: 3D views)
        return report_run(npz, a, _warn, animate)
    try:
        bag = resolve_bag(given)
    except FileNotFoundError as err:
        print(f'swarm report: {err}', file=sys.stderr)
        return 2
    if not bag.is_file():
        print(f'swarm report: {bag}: no such file', file=sys.stderr)
        return 2
    out = Path(a.out) if a.out else given.with_name(given.stem + '_report')
    err = analysis.check_output_dir(out)          # before the work, not after
    if err:
        _warn(err)
        return 2
    try:
        run = read_run(bag, cutoff_radius=a.cutoff_radius, agents=announced_roster(bag, _warn))
        traj = rebuild_trajectory(run)
    except ValueError as err:
        print(f'swarm report: {bag}: {err}', file=sys.stderr)
        return 2
    if run['no_ground']:
        _warn(f'{bag}: {run["no_ground"]}')
    w = run['w']
    if w is None:
        w = Law.cutoff_radius.default
        print(f'swarm report: {bag}: no cutoff_radius on /world/metrics; using the default '
              f'{w:g} (pass --cutoff-radius to choose)', file=sys.stderr)
    series, _ = analysis.analyse(traj, w, target=run['target'], barrier=run['barrier'],
                                 every_time=a.every, ground=run['ground'])
    summary = report_summary(traj, series, w)
    summary['bag'] = str(bag)
    if traj.dim == 3:
        summary.update(dim=3, ground=run['ground'])
    try:
        wrote = write_report(out, traj, series, summary, run, a, w)
    except OSError as err:
        print(analysis.write_failed('swarm report', out, err), file=sys.stderr)
        return 1
    changes = ', '.join(f't={t:g}: {c}' for t, c in summary['cluster_changes'][:12])
    print(f'{bag.name}: {summary["agents"]} agents{" in 3D" if traj.dim == 3 else ""}, {summary["steps"]} steps '
          f'({summary["alignment"]}), t = {summary["t_start"]:g}..{summary["t_end"]:g}, '
          f'final clusters {summary["final_clusters"]}, min distance {summary["min_distance"]:.3g}'
          + (' [bag cut short: read to its last complete chunk]' if summary['truncated_bag'] else ''))
    print(f'  clusters over time (w = {w:g}): {changes}')
    print(f'  wrote {out}/' + ', '.join(wrote))
    return 0


if __name__ == '__main__':
    sys.exit(main())
