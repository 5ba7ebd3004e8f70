"""``swarm report --animate``: a GIF of a planar run (agents coloured by cluster, leaders as stars)."""
from __future__ import annotations

import numpy as np

from swarm_core.analysis.metrics import cluster_labels
from swarm_core.files import atomic_path


def animate(traj, path, *, w, target=None, barrier=None, frames=100, fps=12):
    """A GIF of the swarm (agents coloured by cluster, leaders as stars, short trails), the
    view following the swarm's centroid; None without pillow."""
    import matplotlib
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter
    try:
        import PIL  # noqa: F401
    except ImportError:
        return None
    matplotlib.use('Agg')


    T = len(traj.t)
    idx = np.unique(np.linspace(0, T - 1, min(frames, T)).astype(int))
    fig, ax = plt.subplots(figsize=(5, 5), dpi=70)
    centre = traj.r.mean(axis=1)                                   # (T, 2)
    spread = np.abs(traj.r - centre[:, None, :]).max()
    half = 1.2 * spread + 2.0 * w
    ax.set_aspect('equal')
    if target is not None:
        ax.plot(*target, 'rx', ms=10, mew=2)
    if barrier is not None:
        ax.fill(*np.asarray(barrier).T, color='0.3', alpha=0.7)
    cmap = plt.get_cmap('tab10')
    trails = [ax.plot([], [], lw=0.6, color='0.6')[0] for _ in traj.names]
    dots = ax.scatter(traj.r[0, :, 0], traj.r[0, :, 1], s=25, zorder=3)
    stars = ax.scatter([], [], marker='*', s=120, c='k', zorder=4)
    label = ax.set_title('')
    trail_len = max(1, T // 20)

    def draw(i):
        ax.set_xlim(centre[i, 0] - half, centre[i, 0] + half)
        ax.set_ylim(centre[i, 1] - half, centre[i, 1] + half)
        _, lab = cluster_labels(traj.r[i], w)
        dots.set_offsets(traj.r[i])
        dots.set_color([cmap(v % 10) for v in lab])
        lead = traj.leader[i]
        stars.set_offsets(traj.r[i][lead] if lead.any() else np.empty((0, 2)))
        for k, line in enumerate(trails):
            seg = traj.r[max(0, i - trail_len):i + 1, k]
            line.set_data(seg[:, 0], seg[:, 1])
        lam = traj.lam[i]
        label.set_text(f't = {traj.t[i]:.1f}' + (f', λ = {lam:.2f}' if np.isfinite(lam) else '')
                       + f', clusters = {lab.max() + 1}')
        return [dots, stars, label, *trails]

    anim = FuncAnimation(fig, draw, frames=idx, blit=False)
    with atomic_path(path, suffix='.tmp.gif') as tmp:       # (PIL picks the format by it)
        anim.save(str(tmp), writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path
