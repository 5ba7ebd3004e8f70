"""The 3D side of ``swarm report BAG.mcap``: whether a bag holds a 3D run, its states on
the trajectory's grid, and its ground (`bag_ground`).

A bag is 3D when the run's ``/swarm/run`` announcement says ``dim: 3``.  A bag without an
announcement is 3D when most of its states are not planar (a z, a tilted frame or a v).
Each state row is (stamp, log time, x, y, qz, qw, angular.z, z, qx, qy, angular.y)
(`swarm_tools.bags.report`)."""
from __future__ import annotations

import numpy as np

from swarm_core.model.natural import frame_from_quaternion_3d
from swarm_core.scenario.sections import BarrierSpec3
from swarm_ros.runinfo import run_ground

#: the columns of a state row after its stamp and log time (`_state_arrays`' values)
X, Y, QZ, QW, WZ, Z, QX, QY, WY = range(9)


def run_dim(announced, per_agent: dict) -> int:
    """2 or 3: the announcement's ``dim`` (a dict, or None), else 3 if more than half of the
    states are not planar."""
    if announced is not None and announced.get('dim') in (2, 3):
        return announced['dim']
    rows = [row[7:] for rows in per_agent.values() for row in rows]
    if not rows:
        return 2
    extra = np.array(rows, dtype=np.float64)
    tilted = np.isfinite(extra).all(axis=1) & (extra != 0).any(axis=1)
    return 3 if tilted.sum() > len(rows) / 2 else 2


def bad_row_3d(row, max_coord: float) -> bool:
    """A 3D state row with a non-finite value or an absurd z."""
    z, qx, qy, wy = row[7:]
    return not (np.isfinite([z, qx, qy, wy]).all() and abs(z) <= max_coord)


def states_on_3d(grid, names, arrays: dict, gone: dict):
    """r, the frames x, y, z (each (T, N, 3)), u and v (T, N) of each agent at each stamp of
    ``grid`` (its newest state; NaN once it is gone), and the first log time of each stamp's
    states.  A state's twist is the (u, v) held over the step that ended there: the (u, v)
    applied from a state on is the next state's (u = angular.z, v = −angular.y)."""
    T, n = len(grid), len(names)
    r, fx, fy, fz = (np.empty((T, n, 3)) for _ in range(4))
    u, v = np.empty((T, n)), np.empty((T, n))
    log_first = np.full(T, np.iinfo(np.int64).max, dtype=np.int64)
    for k, name in enumerate(names):
        s, logs, vals = arrays[name]
        u_from = np.append(vals[1:, WZ], np.nan)
        v_from = np.append(-vals[1:, WY], np.nan)
        idx = np.searchsorted(s, grid, side='right') - 1
        rows = vals[idx]
        r[:, k] = rows[:, [X, Y, Z]]
        fx[:, k], fy[:, k], fz[:, k] = frame_from_quaternion_3d(rows[:, QX], rows[:, QY], rows[:, QZ], rows[:, QW])
        u[:, k], v[:, k] = u_from[idx], v_from[idx]
        log_first = np.minimum(log_first, logs[idx])
        if name in gone:
            dead = grid >= gone[name]
            for a in (r, fx, fy, fz, u, v):
                a[dead, k] = np.nan
    return r, (fx, fy, fz), u, v, log_first


def geometry_3d(target, points, bad: list):
    """The 3D target (x, y, z) and barrier points of the bag's world messages (a barrier that is
    not a convex polyhedron goes to ``bad``, and is None)."""
    barrier = None
    if points:
        try:
            barrier = [tuple(q) for q in BarrierSpec3(points=points).points]
        except ValueError as err:
            bad.append(f'barrier of {len(points)} points ({" ".join(str(err).split())[:120]})')
    return target, barrier


def ground_of(msg):
    """What a ``/parameter_events`` message tells of a node's ``ground`` parameter (the agents':
    a number as text, '' = none): (True, the floor's height or None for no floor), or (False,
    None) where it does not tell (no such parameter, or not a finite number)."""
    for p in list(getattr(msg, 'new_parameters', ())) + list(getattr(msg, 'changed_parameters', ())):
        if p.name == 'ground':
            text = p.value.string_value
            try:
                g = float(text) if text.strip() else None
            except ValueError:
                return False, None
            return (True, g) if g is None or np.isfinite(g) else (False, None)
    return False, None


#: what the report says of a 3D bag that does not tell its ground
NO_GROUND = ('the bag does not tell the ground (no ground in its /swarm/run announcement, no agent\'s '
             'ground parameter on /parameter_events): no floor intrusion check, no floor drawn')


def bag_ground(announced, parameters):
    """The floor of a 3D run's bag: (its height or None for no floor, None) where the bag tells
    it, else (None, `NO_GROUND`).  The run's ``/swarm/run`` announcement (``announced``, a dict
    or None: `swarm_ros.runinfo.run_ground`) tells it; a bag of an older run, whose announcement
    has no ground, tells it by the agents' ``ground`` parameter on ``/parameter_events``
    (``parameters``: the first (True, height) of `ground_of`, or None)."""
    said, ground = run_ground(announced)
    if said:
        return ground, None
    if parameters is not None:
        return parameters[1], None
    return None, NO_GROUND
