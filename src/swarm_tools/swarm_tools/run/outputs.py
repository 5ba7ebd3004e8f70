"""The outputs of an ended ``swarm run`` (`finish`): the trajectory the world saved, its
metrics and figure, or, when the world died, what `salvage` rebuilds from the run's bag; and
run.json with the exit code.  ``swarm run`` (`launch.main`) and ``ros2 launch swarm_tools
swarm.launch.py`` (`swarm_tools.run.launch_description`) both end here."""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from swarm_core.analysis.outputs import analyse, write_atomic, write_failed, write_outputs
from swarm_core.engine.trajectory import Trajectory
from swarm_tools.bags.mcap_io import bag_complete
from swarm_tools.bags.report import read_run, rebuild_trajectory
from swarm_tools.run.processes import REFUSED_EXIT, read_events
from swarm_tools.run.robots import read_summary
from swarm_world.lateness import TIMING_FILE, behind_line, timing_line

if TYPE_CHECKING:
    from swarm_tools.run.launch import RunPlan


def finish(run: RunPlan, code: int, wall: float) -> int:
    """The outputs of a run that has ended with ``code``: trajectory, metrics and figure (or
    what `salvage` can rebuild), and run.json; gives ``code``."""
    if code in (0, 130) and run.traj_file.exists():      # 130: Ctrl-C; the world saved the steps done
        write_run_outputs(run, code, wall)
    elif code != 0:
        print(f'swarm run: stopped (code {code}) after {wall:.1f} s', file=sys.stderr, flush=True)
        if code == REFUSED_EXIT:        # a node refused its parameters: nothing ran, nothing to save
            pass
        elif run.in_process and run.stopped and run.traj_file.exists():     # a law failed: the steps done
            write_run_outputs(run, code, wall)
        elif not run.in_process and not salvage(run.scn, run.out, run.record, run.mode, wall, figure=run.figure) \
                and run.traj_file.exists():             # the world's own record is the longer one
            write_run_outputs(run, code, wall)
    if code == 0 and run.record and not run.in_process and not bag_complete(run.record):
        print(f'swarm run: the bag {run.record} is not complete: its recorder stopped early (see above)',
              file=sys.stderr, flush=True)
        code = 1
    try:
        write_atomic(run.out / 'run.json', json.dumps(dict(
            exit_code=code, wall_seconds=wall, mode=run.mode, processes=not run.in_process,
            agents=len(run.scn.names), agents_per_process=run.per)))
    except OSError as err:
        print(write_failed('swarm run', run.out, err), file=sys.stderr)
    return code


def write_run_outputs(run: RunPlan, code: int, wall: float) -> None:
    """metrics.json and the figure from the trajectory.npz the world wrote."""
    scn, out = run.scn, run.out
    try:
        traj = Trajectory.load(run.traj_file)
        traj.meta = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, duration=scn.duration, source='ros',
                         mode=run.mode, wall_seconds=wall, events=read_events(run.events_file),
                         interrupted=code == 130 or run.stopped is not None, robots=read_summary(out))
        if run.stopped:
            traj.meta['stopped'] = run.stopped
        series, checks = analyse(traj, scenario=scn)
        timing = read_timing(out) if run.mode == 'realtime' else None
        summary = write_outputs(out, scn, traj, series, checks, figure=run.figure,
                                extra=dict(timing=timing) if timing else None)
        what = (f'stopped (code {code}) at t = {summary["t_end"]:g} after {wall:.1f} s; partial run'
                if code else f'done in {wall:.1f} s')
        print(f'swarm run: {what}; final clusters {summary.get("final_clusters", "?")}; '
              f'wrote {out}/trajectory.npz, metrics.json' + (f', {scn.label}.png' if run.figure else ''),
              flush=True)
        if summary.get('deterministic') is False:     # lockstep, yet not the run its seed makes
            print(f'swarm run: not deterministic: {"; ".join(summary["not_deterministic"][:5])} '
                  '(metrics.json summary.not_deterministic)', flush=True)
        if timing:
            for line in (timing_line(timing), behind_line(timing, timing['rtf'])):
                if line:
                    print(f'swarm run: {line}', flush=True)
    except Exception as err:  # the trajectory is there; the extras are a bonus
        print(f'swarm run: wrote {run.traj_file} (metrics/figure failed: {err})', flush=True)


def read_timing(out: Path) -> dict | None:
    """The realtime world's timing (`swarm_world.lateness`, its ``timing.json``), if it wrote one."""
    try:
        return json.loads((out / TIMING_FILE).read_text())
    except (OSError, ValueError):
        return None


def saved_samples(path) -> int:
    """The samples of a trajectory.npz (0 if there is none or it cannot be read)."""
    try:
        with np.load(path) as z:
            return int(z['t'].shape[0])
    except (OSError, ValueError, KeyError, EOFError):
        return 0


def salvage(scn, out: Path, bag, mode: str, wall: float, figure: bool = True) -> bool:
    """The run ended with an error: rebuild it from the bag of ``--record``
    (`swarm_tools.bags.report`) into ``out``, or say plainly what is lost.  A rebuild never replaces
    a longer record: if the world saved a trajectory.npz with at least as many samples, that
    one is kept (False)."""
    lost = 'the trajectory is lost (the world keeps it in memory until the end)'
    if not bag or not Path(bag).is_file():
        if saved_samples(out / 'trajectory.npz'):
            return False                    # the world saved what it had
        print(f'swarm run: {lost}; {out}/events.jsonl is kept. Record the run (--record BAG.mcap) '
              'to be able to rebuild it', file=sys.stderr, flush=True)
        return False
    try:
        run = read_run(bag, cutoff_radius=scn.law.cutoff_radius, agents=scn.names)
        traj = rebuild_trajectory(run)
        order = [traj.names.index(nm) for nm in scn.names if nm in traj.names]
        traj.names = [traj.names[k] for k in order]
        for key in ('r', 'theta', 'u', 'leader', 'x', 'y', 'z', 'v'):        # theta: planar; x, y, z, v: 3D
            if getattr(traj, key) is not None:
                setattr(traj, key, getattr(traj, key)[:, order])
        traj.meta.update(scenario=scn.name, seed=scn.seed, duration=scn.duration, source='bag',
                         mode=mode, wall_seconds=wall, interrupted=True,
                         events=read_events(out / 'events.jsonl'))
        saved = saved_samples(out / 'trajectory.npz')
        if saved >= len(traj.t):
            print(f'swarm run: kept the trajectory the world saved ({saved} samples); the bag holds '
                  f'{len(traj.t)}', file=sys.stderr, flush=True)
            return False
        series, checks = analyse(traj, scenario=scn)
        write_outputs(out, scn, traj, series, checks, figure=figure)
    except (ValueError, OSError, IndexError) as err:
        print(f'swarm run: {lost}, and rebuilding it from the bag {bag} failed: {err}', file=sys.stderr, flush=True)
        return False
    missing = sorted(set(scn.names) - set(traj.names))
    print(f'swarm run: the world did not save the trajectory; rebuilt t = {traj.t[0]:g}..{traj.t[-1]:g} '
          f'({len(traj.t)} samples, {len(traj.names)} agents) from the bag {bag} into {out}/trajectory.npz, '
          'metrics.json' + (f'; no states in the bag for {", ".join(missing)}' if missing else ''),
          file=sys.stderr, flush=True)
    return True
