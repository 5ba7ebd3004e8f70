"""``swarm report RUN``: metrics and figures from a run directory without a bag.

RUN is a directory that ``swarm simulate`` or ``swarm run`` wrote (its trajectory.npz, and its
metrics.json for the scenario's cutoff radius, target, barrier and ground), or a
trajectory.npz.  The report writes what a bag's report writes: trajectory.npz, metrics.json,
report.png (a 3D run: a 3D view, a top view and a side view) and, with ``--animate``, a GIF
(planar runs only).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from swarm_core.analysis import outputs as analysis
from swarm_core.analysis.plots import plot_run
from swarm_core.engine.trajectory import Trajectory
from swarm_core.laws import Law

TRAJECTORY = 'trajectory.npz'
METRICS = 'metrics.json'


def run_trajectory(path) -> Path | None:
    """The trajectory.npz to report for ``path``: the file itself, or a directory's own when the
    directory holds no bag (.mcap); None for anything else (a bag)."""
    path = Path(path)
    if path.is_file() and path.suffix == '.npz':
        return path
    if path.is_dir() and (path / TRAJECTORY).is_file() and not any(path.glob('*.mcap')):
        return path / TRAJECTORY
    return None


def run_world(npz: Path, warn) -> dict:
    """The scenario the run's metrics.json holds, next to ``npz``: its name, cutoff radius w,
    target, barrier points and ground (None where it has none, or has no metrics.json)."""
    world = dict(scenario=None, w=None, target=None, barrier=None, ground=None)
    try:
        params = json.loads((npz.parent / METRICS).read_text()).get('parameters') or {}
    except FileNotFoundError:
        return world
    except (OSError, ValueError, AttributeError) as err:
        warn(f'{npz.parent / METRICS}: unreadable ({err}); no target, barrier or ground')
        return world
    law, target, barrier = params.get('law') or {}, params.get('target') or {}, params.get('barrier') or {}
    world.update(scenario=params.get('name'), w=law.get('cutoff_radius'), target=target.get('position'),
                 barrier=barrier.get('points') or None, ground=barrier.get('ground'))
    return world


def report_run(npz: Path, a, warn, animate) -> int:
    """The report of a run's ``npz`` into ``a.out`` (default: the run's path + _report);
    the exit code.  ``animate``: the bag report's GIF writer."""
    given = Path(a.bag)
    out = Path(a.out) if a.out else given.with_name(given.stem + '_report')
    err = analysis.check_output_dir(out)
    if err:
        warn(err)
        return 2
    try:
        traj = Trajectory.load(npz)
    except (OSError, ValueError, KeyError) as err:
        warn(f'{npz}: not a trajectory.npz ({err})')
        return 2
    if len(traj.t) < 1:
        warn(f'{npz}: no samples')
        return 2
    world = run_world(npz, warn)
    w = a.cutoff_radius if a.cutoff_radius is not None else world['w']
    if w is None:
        w = Law.cutoff_radius.default
        warn(f'{npz}: no cutoff_radius in the run\'s metrics.json; using the default {w:g} '
             '(pass --cutoff-radius to choose)')
    dt = float(np.median(np.diff(traj.t))) if len(traj.t) > 1 else 1.0
    series, _ = analysis.analyse(traj, w, target=world['target'], barrier=world['barrier'], dt=dt,
                                 every_time=a.every, ground=world['ground'])
    summary = dict(analysis.run_summary(traj, series), names=list(traj.names), t_start=float(traj.t[0]),
                   dt=dt, cutoff_radius=w, dim=traj.dim, run=str(npz), scenario=world['scenario'])
    try:
        wrote = _write(out, traj, series, summary, world, a, w, warn, animate)
    except OSError as err:
        warn(analysis.write_failed('swarm report', out, err).removeprefix('swarm report: '))
        return 1
    print(f'{npz}: {summary["agents"]} agents in {traj.dim}D, {summary["steps"]} steps, '
          f't = {summary["t_start"]:g}..{summary["t_end"]:g}, final clusters {summary["final_clusters"]}, '
          f'min distance {summary["min_distance"]:.3g}')
    print(f'  wrote {out}/' + ', '.join(wrote))
    return 0


def _write(out, traj, series, summary, world, a, w, warn, animate) -> list:
    """trajectory.npz, metrics.json, report.png and (``--animate``, planar) swarm.gif into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    traj.save(out / TRAJECTORY)
    analysis.write_atomic(out / METRICS, analysis.dumps(dict(summary=summary, series=series)))
    wrote = [TRAJECTORY, METRICS]
    if not a.no_figure and len(traj.t) > 1:
        name = world['scenario'] or Path(summary['run']).parent.name
        plot_run(traj, series, out / 'report.png', w=w, target=world['target'], barrier=world['barrier'],
                 ground=world['ground'], title=f'{name}: {len(traj.names)} agents, t = {traj.t[0]:g}..{traj.t[-1]:g}')
        wrote.append('report.png')
    if a.animate:
        if traj.dim == 3:
            warn('--animate draws planar runs only: no animation of a 3D run')
        elif animate(traj, out / 'swarm.gif', w=w, target=world['target'], barrier=world['barrier']):
            wrote.append('swarm.gif')
        else:
            warn('pillow is not installed: no animation')
    return wrote
