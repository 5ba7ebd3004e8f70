"""The figure of a 3D run: a 3D view, a top view (x, y), a side view (x, z), λ(t) and
clusters(t).  matplotlib (mpl_toolkits.mplot3d) with the Agg backend (no screen needed)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from swarm_core.files import atomic_path

#: the views drawn besides the 3D one: (title, the two coordinates shown)
VIEWS = (('top view', (0, 1)), ('side view', (0, 2)))
AXIS = 'xyz'


def agent_colours(n):
    """One colour per agent: tab10 up to 10 agents, else viridis."""
    import matplotlib.pyplot as plt
    cmap = plt.get_cmap('tab10' if n <= 10 else 'viridis')
    return [cmap(i % 10) if n <= 10 else cmap(i / max(1, n - 1)) for i in range(n)]


def _hull(points):
    """The barrier's corners (m, 3) and its hull's triangles, or (None, None)."""
    if points is None or not len(points):
        return None, None
    from scipy.spatial import ConvexHull
    pts = np.asarray(points, dtype=float)
    return pts, ConvexHull(pts).simplices


def _draw_3d(ax, r, colours, leaders, target, barrier, ground):
    """Trajectories in space; start (dots), end (circles; stars: leaders), target, barrier, ground."""
    for k, c in enumerate(colours):
        ax.plot(r[:, k, 0], r[:, k, 1], r[:, k, 2], lw=0.8, color=c)
        ax.scatter(*r[-1, k], s=40 if k in leaders else 8, marker='*' if k in leaders else 'o', color=c)
    ax.scatter(*r[0].T, s=4, color='k')
    if target is not None:
        ax.scatter(*np.asarray(target, float), s=60, marker='x', color='r')
    pts, tri = _hull(barrier)
    if pts is not None:
        ax.plot_trisurf(*pts.T, triangles=tri, color='0.3', alpha=0.5)
    if ground is not None:
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        gx, gy = np.meshgrid([x0, x1], [y0, y1])
        ax.plot_surface(gx, gy, np.full_like(gx, float(ground)), color='tab:brown', alpha=0.2)
    ax.set_xlabel('x')
    ax.set_ylabel('y')
    ax.set_zlabel('z')


def _draw_view(ax, r, colours, leaders, axes, target, barrier, ground):
    """The trajectories projected on two coordinates ``axes``: to scale from above; a side view
    (x, z) is stretched to fit, with the ground as a line."""
    from scipy.spatial import ConvexHull
    a, b = axes
    for k, c in enumerate(colours):
        ax.plot(r[:, k, a], r[:, k, b], lw=0.8, color=c)
        ax.plot(r[-1, k, a], r[-1, k, b], marker='*' if k in leaders else 'o', ms=12 if k in leaders else 3,
                color=c, mec='k' if k in leaders else c)
    ax.plot(r[0, :, a], r[0, :, b], 'k.', ms=4, label='start')
    if target is not None:
        ax.plot(target[a], target[b], 'rx', ms=10, mew=2, label='target')
    pts, _ = _hull(barrier)
    if pts is not None:
        flat = pts[:, [a, b]]
        ax.fill(*flat[ConvexHull(flat).vertices].T, color='0.3', alpha=0.8, label='barrier')
    if ground is not None and b == 2:
        ax.axhline(float(ground), color='tab:brown', lw=2, label='ground')
    if b != 2:
        ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel(AXIS[a])
    ax.set_ylabel(AXIS[b])


def plot_run_3d(traj, series, path, *, title: str = '', w: float = 4.0, target=None, barrier=None,
                ground=None):
    """Write a 3D run's figure to ``path`` (PNG) and return the path.

    traj: a 3D `engine.Trajectory` (r (T, n, 3)); series: `metrics.time_series` of it (needs t,
    clusters); barrier: 3D points of a convex hull, ground: the floor's height."""
    import matplotlib
    import matplotlib.pyplot as plt
    matplotlib.use('Agg')

    n = traj.r.shape[1]
    stride = max(1, len(traj.t) // 4000)
    r = traj.r[::stride]
    if stride > 1 and len(traj.t) % stride != 1:
        r = np.concatenate([r, traj.r[-1:]])          # the ends are the last samples
    colours = agent_colours(n)
    leaders = set(np.flatnonzero(traj.leader.any(axis=0)).tolist())
    target = None if target is None else np.asarray(target, dtype=float)
    fig = plt.figure(figsize=(12, 10), constrained_layout=True)
    grid = fig.add_gridspec(4, 2, height_ratios=[1.6, 1.6, 0.6, 0.6], width_ratios=[1.3, 1])
    ax3 = fig.add_subplot(grid[0:2, 0], projection='3d')
    _draw_3d(ax3, r, colours, leaders, target, barrier, ground)
    ax3.set_title(title or 'trajectories (stars: leaders at the end)')
    for row, (name, axes) in enumerate(VIEWS):
        ax = fig.add_subplot(grid[row, 1])
        _draw_view(ax, r, colours, leaders, axes, target, barrier, ground)
        ax.set_title(name)
        ax.legend(loc='best', fontsize=8)
    ax_l = fig.add_subplot(grid[2, :])
    ax_l.plot(traj.t, traj.lam, 'k')
    ax_l.set_ylim(-0.05, 1.05)
    ax_l.set_ylabel('λ')
    ax_c = fig.add_subplot(grid[3, :], sharex=ax_l)
    ax_c.step(series['t'], series['clusters'], where='post', color='tab:blue')
    ax_c.set_ylabel(f'clusters\n(ρ < {w:g})')
    ax_c.set_xlabel('t')
    ax_c.yaxis.get_major_locator().set_params(integer=True)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format='png')
    plt.close(fig)
    return path
