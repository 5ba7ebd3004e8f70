"""Figures like the paper's (Figs. 3-5): trajectories in the plane coloured by agent,
x(t), λ(t) and clusters(t); a 3D run's figure is `plots3d.plot_run_3d`.  matplotlib with the
Agg backend (no screen needed)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from swarm_core.analysis.plots3d import plot_run_3d
from swarm_core.files import atomic_path


def plot_run(traj, series, path, *, title: str = '', w: float = 4.0, target=None, barrier=None, ground=None):
    """Write the run's figure to ``path`` (PNG) and return the path.

    traj: a `engine.Trajectory`; series: `metrics.time_series` of it (needs t, clusters).
    A 3D run gets `plot_run_3d` (a 3D view, top and side views; ``ground``: its floor)."""
    if traj.r.shape[2] == 3:
        return plot_run_3d(traj, series, path, title=title, w=w, target=target, barrier=barrier, ground=ground)
    import matplotlib
    import matplotlib.pyplot as plt
    from scipy.spatial import ConvexHull
    matplotlib.use('Agg')

    n = traj.r.shape[1]
    r = traj.r
    cmap = plt.get_cmap('tab10' if n <= 10 else 'viridis')
    colours = [cmap(i % 10) if n <= 10 else cmap(i / max(1, n - 1)) for i in range(n)]
    fig = plt.figure(figsize=(10, 10), constrained_layout=True)
    grid = fig.add_gridspec(4, 1, height_ratios=[3.2, 1, 0.7, 0.7])
    ax = fig.add_subplot(grid[0])
    stride = max(1, len(traj.t) // 4000)
    for k in range(n):
        ax.plot(r[::stride, k, 0], r[::stride, k, 1], lw=0.8, color=colours[k])
        ax.plot(*r[-1, k], 'o', ms=3, color=colours[k])
    leaders = np.flatnonzero(traj.leader.any(axis=0))
    for k in leaders:
        ax.plot(*r[-1, k], marker='*', ms=12, color=colours[k], mec='k')
    ax.plot(*r[0].T, 'k.', ms=4, label='start')
    if target is not None:
        ax.plot(*np.asarray(target), 'rx', ms=12, mew=2, label='target')
    if barrier is not None:
        pts = np.asarray(barrier, dtype=float)
        hull = pts[ConvexHull(pts).vertices] if len(pts) >= 3 else pts
        ax.fill(*hull.T, color='0.3', alpha=0.8, label='barrier')
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel('x')
    ax.set_ylabel('y')
    ax.set_title(title or 'trajectories (stars: leaders at the end)')
    ax.legend(loc='best', fontsize=8)

    ax_x = fig.add_subplot(grid[1])
    for k in range(n):
        ax_x.plot(traj.t[::stride], traj.r[::stride, k, 0], lw=0.8, color=colours[k])
    ax_x.set_ylabel('x')
    ax_l = fig.add_subplot(grid[2], sharex=ax_x)
    ax_l.plot(traj.t, traj.lam, 'k')
    ax_l.set_ylim(-0.05, 1.05)
    ax_l.set_ylabel('λ')
    ax_c = fig.add_subplot(grid[3], sharex=ax_x)
    ax_c.step(series['t'], series['clusters'], where='post', color='tab:blue')
    ax_c.set_ylabel(f'clusters\n(ρ < {w:g})')
    ax_c.set_xlabel('t')
    ax_c.yaxis.get_major_locator().set_params(integer=True)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format='png')
    plt.close(fig)
    return path
