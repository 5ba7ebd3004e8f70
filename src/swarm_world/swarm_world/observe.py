"""Per-step observation, without ROS: collisions and barrier intrusions counted, and the
progress line paced every ``progress_every`` sim seconds."""
from __future__ import annotations

import numpy as np

from swarm_core.analysis import metrics as M


class Observer:
    """Counts ``collisions`` (steps with a pair closer than ``collision_distance``) and
    ``intrusions`` (agent-steps inside ``barrier``, a `metrics.Barrier` or None)."""

    def __init__(self, collision_distance, cutoff_radius, progress_every=0.0):
        self.collision_distance = collision_distance
        self.cutoff_radius = cutoff_radius
        self.progress_every = progress_every
        self.next_progress = 0.0
        self.collisions = 0
        self.intrusions = 0

    def check(self, t, pos, names, barrier=None):
        """Agents ``names`` (a sequence, or a function giving it: called only for a complaint
        that names them) at ``pos`` at time t → (minimum distance, complaints as (kind, text))."""
        md = M.min_distance(pos)
        out = []
        if md < self.collision_distance:
            self.collisions += 1
            out.append(('collision', f'nothing: collision at t={t:.2f} (min distance {md:.4f})'))
        if barrier is not None:
            inside = barrier.inside(pos)
            if inside.any():
                names = names() if callable(names) else names
                self.intrusions += int(inside.sum())
                out.append(('intrusion', f'nothing: barrier intrusion at t={t:.2f} by '
                            + ', '.join(names[i] for i in np.flatnonzero(inside))))
        return md, out

    def progress(self, t, pos, md, lam, rate=None):
        """The progress line if one is due at t (else None); ``rate`` steps/s if known."""
        if self.progress_every <= 0 or t < self.next_progress:
            return None
        self.next_progress = t + self.progress_every
        c, _ = (M.cluster_labels_3d if pos.shape[1] == 3 else M.cluster_labels)(pos, self.cutoff_radius)
        line = f'[world] t={t:8.2f}  clusters={c}  λ={lam:.3f}  min_dist={md:.3f}'
        return line if rate is None else line + f'  ({rate:.0f} steps/s)'
