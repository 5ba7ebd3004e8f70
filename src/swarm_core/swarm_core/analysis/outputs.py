"""The analysis of a run, shared by ``swarm simulate``, ``swarm run`` and ``swarm report``.

`analyse` turns a `Trajectory` into metric time series (and, with a scenario, its ``expect``
checks); `run_summary` holds what every summary reports; `summary_of` adds what a scenario
knows; `write_outputs` writes trajectory.npz, metrics.json and the figure.  Pure (no ROS).
"""
from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np

from swarm_core.analysis import metrics, outcomes
from swarm_core.analysis.plots import plot_run
from swarm_core.files import write_atomic
from swarm_core.laws import law_mapping


def analyse(traj, cutoff_radius=None, *, target=None, barrier=None, scenario=None, dt=None,
            every_time: float = 1.0, ground=None):
    """Metric time series (sampled every ``every_time`` units) and the scenario's checks.

    Without a ``scenario`` (a bag): the given ``cutoff_radius``, ``target``, ``barrier`` and
    (3D) ``ground``, the recorded step ``dt`` (default ``traj.meta['dt']``), and no checks.
    With one: its cutoff radius, target, barrier, ground, recorded step and ``expect`` checks,
    unless given."""
    if scenario is not None:
        cutoff_radius = scenario.law.cutoff_radius if cutoff_radius is None else cutoff_radius
        target = scenario.target if target is None else target
        barrier = scenario.barrier if barrier is None else barrier
        ground = scenario.ground if ground is None else ground
        dt = scenario.dt * traj.meta.get('record_every', 1) if dt is None else dt
    elif dt is None:
        dt = traj.meta.get('dt') or 1.0
    every = max(1, int(round(every_time / dt))) if dt > 0 else 1
    if traj.dim == 3:             # headings x in place of θ; the floor of a 3D barrier
        series = metrics.time_series(traj.t, traj.r, traj.x, traj.leader, cutoff_radius, target=target,
                                     barrier_points=barrier, every=every, ground=ground)
    else:
        series = metrics.time_series(traj.t, traj.r, traj.theta, traj.leader, cutoff_radius,
                                     target=target, barrier_points=barrier, every=every)
    checks = {}
    if scenario is not None and len(traj.t):
        checks = outcomes.evaluate(scenario.spec.expect, series, traj, scenario)
    return series, checks


def finite(x):
    """``x`` (dicts, lists, tuples, floats) with NaN and ±inf as None (JSON has no NaN)."""
    if isinstance(x, dict):
        return {k: finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def jsonable(x):
    """``default=`` for `json.dumps`: numpy arrays and scalars as plain values, NaN and ±inf
    as null (so the file stays valid JSON)."""
    if isinstance(x, np.ndarray):
        return finite(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return finite(x.item())
    raise TypeError(type(x))


def cluster_changes(series) -> list[tuple[float, int]]:
    """[(t, clusters)] at the first sample and at every change."""
    c, t = series['clusters'], series['t']
    out = [(float(t[0]), int(c[0]))]
    for i in range(1, len(c)):
        if c[i] != c[i - 1]:
            out.append((float(t[i]), int(c[i])))
    return out


def behaviour_ok(checks):
    """True if every check passed, False if one failed, None if none failed but some could not
    be judged (a run shorter than the scenario) or there are no checks."""
    if not checks or any(v['passed'] is False for v in checks.values()):
        return False if checks else None
    return None if any(v['passed'] is None for v in checks.values()) else True


def run_summary(traj, series) -> dict:
    """What every summary reports: size, length, clusters, distance, polarisation, and the
    barrier and target metrics when the run has them."""
    c = series['clusters']
    out = dict(steps=len(traj.t) - 1, t_end=float(traj.t[-1]) if len(traj.t) else 0.0,
               agents=len(traj.names), final_clusters=int(c[-1]), max_clusters=int(c.max()),
               min_distance=float(np.min(series['min_distance'])),
               final_polarisation=float(series['polarisation'][-1]),
               cluster_changes=cluster_changes(series))
    if 'intrusions_total' in series:
        out['intrusions_total'] = series['intrusions_total']
        for key in ('barrier_clearance', 'floor_intrusions_total', 'floor_clearance'):   # 3D: a floor
            if key in series:
                out[key] = series[key]
    if 'centroid_target_distance' in series:
        out['closest_centroid_target_distance'] = float(series['centroid_target_distance'].min())
    return out


def summary_of(scn, traj, series, checks) -> dict:
    """`run_summary` with what the scenario knows: its name, seed, step, law, the checks and
    their verdict, and the run's events and radio record."""
    out = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, **run_summary(traj, series),
               law=scn.law.kind, checks=checks, behaviour_ok=behaviour_ok(checks),
               interrupted=bool(traj.meta.get('interrupted', False)),
               wall_seconds=round(traj.meta.get('wall_seconds', 0.0), 3))
    out['agents'] = len(scn.names)
    if traj.meta.get('stopped'):
        out['stopped'] = traj.meta['stopped']      # why the run ended early: a law that failed
    if traj.meta.get('events'):
        out['events'] = traj.meta['events']        # faults, failover, reunion (faults.py)
    if traj.meta.get('comms'):
        out['comms'] = traj.meta['comms']      # what the radio did (swarm_core.radio)
    if traj.meta.get('robots'):
        out['robots'] = traj.meta['robots']    # robot contacts, time at the limits (swarm_robots)
    why = not_deterministic(traj.meta)
    if why:
        out['deterministic'], out['not_deterministic'] = False, why
    return out


def not_deterministic(meta: dict) -> list[str]:
    """Why a lockstep ROS run (``meta``: its trajectory's) is no longer the run its scenario
    and seed make, whatever the machine: an agent the world dropped after its wall-clock time-out
    (a ``lost`` event: a process gone, starved or crowded out), a step a robot went on without
    its command (``commands_missed``).  Empty for any other run (a batch run; realtime, which
    follows the wall clock anyway)."""
    if meta.get('source') != 'ros' or meta.get('mode') != 'lockstep':
        return []
    events = [e for e in meta.get('events') or () if isinstance(e, dict)]
    out = [f'{e.get("agent")} lost at t = {e.get("t")}' for e in events if e.get('kind') == 'lost']
    missed = (meta.get('robots') or {}).get('commands_missed') or {}
    return out + [f"{nm}'s robot went on without its command at {len(v)} step(s) from step {v[0]}"
                  for nm, v in missed.items() if v]


def dumps(doc) -> str:
    """``doc`` as indented, valid JSON: numpy values as plain ones, NaN and ±inf as null."""
    return json.dumps(finite(doc), default=jsonable, indent=1)


def write_failed(prog, out, err) -> str:
    """One line for a results write that failed (full disk, permissions)."""
    where = getattr(err, 'filename', None) or out
    return f'{prog}: cannot write results to {out}: {getattr(err, "strerror", None) or err} ({where})'


def check_output_dir(path) -> str | None:
    """Create ``path`` and check that a file can be written in it; None if so, else one line
    saying why not (a read-only directory is refused before the work, not after)."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        return f'cannot create output directory {path}: {err.strerror or err} ({err.filename})'
    try:
        with tempfile.NamedTemporaryFile(dir=path, prefix='.write_test_'):
            pass
    except OSError as err:
        return f'output directory {path} is not writable: {err.strerror or err}'
    return None


def write_outputs(out_dir, scn, traj, series, checks, figure=True, extra=None):
    """trajectory.npz, metrics.json (each written atomically) and the figure in ``out_dir``;
    the figure is named after the scenario's `label` (never a path taken from its name).
    ``extra``: further top-level entries of metrics.json (a realtime run's ``timing``)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    traj.save(out / 'trajectory.npz')
    summary = summary_of(scn, traj, series, checks)
    if scn.law_hash:            # a user's law: the hash of its file as the run imported it
        summary['law_hash'] = scn.law_hash
    parameters = scn.spec.model_dump(mode='json', by_alias=True)
    parameters['law'] = law_mapping(scn.law)          # the law's section, as the law has it
    doc = dict(summary=summary, series={k: v for k, v in series.items()}, parameters=parameters, **(extra or {}))
    write_atomic(out / 'metrics.json', dumps(doc))
    if figure and len(traj.t) > 1:
        plot_run(traj, series, out / f'{scn.label}.png',
                 title=f'{scn.name}, seed {scn.seed}: {scn.law.kind} law, n = {len(scn.names)}',
                 w=scn.law.cutoff_radius, target=scn.target, barrier=scn.barrier, ground=scn.ground)
    return summary
