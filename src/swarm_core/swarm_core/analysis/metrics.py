"""Swarm metrics (docs/model.md, 'Metrics'), no ROS: per state table and as time series."""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, cKDTree


def cluster_labels(pos, w):
    """Connected components of the graph with an edge where ρ_jk < w: (count, labels (n,))."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    if n == 0:
        return 0, np.zeros(0, dtype=int)
    ij = cKDTree(pos).query_pairs(w, output_type='ndarray')
    if ij.size:
        d = pos[ij[:, 0]] - pos[ij[:, 1]]
        ij = ij[(d[:, 0] ** 2 + d[:, 1] ** 2) < w * w]     # strict ρ < w
    graph = coo_matrix((np.ones(len(ij)), (ij[:, 0], ij[:, 1])), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    return int(count), labels


def polarisation(theta):
    """|mean_k x_k| ∈ [0, 1] (1 = aligned)."""
    theta = np.asarray(theta, dtype=float)
    return float(np.hypot(np.cos(theta).mean(), np.sin(theta).mean()))


#: up to this many agents `min_distance` compares all pairs densely
DENSE_MIN_DISTANCE = 128


def min_distance(pos):
    """Minimum pairwise distance (collision margin), in the plane or in space (pos (N, 2) or
    (N, 3)); inf for fewer than two agents."""
    pos = np.asarray(pos, dtype=float)
    if len(pos) < 2:
        return float('inf')
    if len(pos) <= DENSE_MIN_DISTANCE:     # all pairs: faster than building a tree (per-step use)
        d2 = None
        for c in range(pos.shape[1]):      # dx² + dy² (+ dz²), left to right
            d = pos[:, c, None] - pos[:, c]
            d2 = d * d if d2 is None else d2 + d * d
        np.fill_diagonal(d2, np.inf)
        return float(np.sqrt(d2.min()))
    d, _ = cKDTree(pos).query(pos, k=2)
    return float(d[:, 1].min())


class Barrier:
    """Convex hull of the barrier points b_i, for intrusion tests."""

    def __init__(self, points):
        self.points = np.asarray(points, dtype=float)
        self._eq = ConvexHull(self.points).equations if len(self.points) >= 3 else None

    def inside(self, pos, margin: float = 0.0):
        """Bool (n,): strictly inside the hull (grown by ``margin``)."""
        pos = np.atleast_2d(np.asarray(pos, dtype=float))
        if self._eq is None:
            return np.zeros(len(pos), dtype=bool)
        d = self.points.shape[1]                        # 2, or 3 (a 3D barrier's hull)
        s = pos @ self._eq[:, :d].T + self._eq[:, d]
        return np.all(s < margin, axis=1)

    def clearance(self, pos):
        """Distance from each position to the nearest barrier point (≥ 0)."""
        d = np.atleast_2d(pos)[:, None, :] - self.points[None]
        return np.sqrt((d ** 2).sum(-1)).min(axis=1)


def leader_membership(labels, leader_idx):
    """For each cluster label, the sorted leader indices in it: {label: [leaders]}."""
    out = {int(c): [] for c in np.unique(labels)}
    for i in leader_idx:
        out[int(labels[i])].append(int(i))
    return out


#: up to this many agents `time_series` takes every sample at once (`_dense_samples`)
DENSE_SAMPLES = 32


def _components(adj):
    """Connected components of each graph of a stack (S, n, n) of boolean adjacencies with
    self loops: (count (S,), labels (S, n), the lowest agent index of each one's component)."""
    s, n, _ = adj.shape
    labels = np.broadcast_to(np.arange(n), (s, n)).copy()
    while True:                                  # at most n rounds: each takes the neighbours' least
        nxt = np.where(adj, labels[:, None, :], n).min(axis=2)
        if np.array_equal(nxt, labels):
            return (labels == np.arange(n)).sum(axis=1), labels
        labels = nxt


def _dense_samples(r, theta, leader, w):
    """clusters, polarisation, min_distance and one_leader_per_cluster of every sample of a
    small swarm with finite rows, as the per-sample functions give them, in blocks of samples."""
    n = r.shape[1]
    out = {k: [] for k in ('clusters', 'polarisation', 'min_distance', 'one_leader_per_cluster')}
    block = max(1, 200_000 // (n * n))
    eye = np.eye(n, dtype=bool)
    for a in range(0, len(r), block):
        rb, lb = r[a:a + block], leader[a:a + block]
        dx = rb[:, :, None, 0] - rb[:, None, :, 0]
        dy = rb[:, :, None, 1] - rb[:, None, :, 1]
        d2 = dx * dx + dy * dy
        count, labels = _components((d2 < w * w) | eye)
        out['clusters'].append(count)
        d2[:, eye] = np.inf
        out['min_distance'].append(np.sqrt(d2.min(axis=(1, 2))) if n > 1 else np.full(len(rb), np.inf))
        th = theta[a:a + block]
        out['polarisation'].append(np.hypot(np.cos(th).mean(axis=1), np.sin(th).mean(axis=1)))
        # leaders per component (its root: the lowest index), 1 in every one; no leader: False
        per = (lb[:, None, :] & (labels[:, None, :] == np.arange(n)[None, :, None])).sum(axis=2)
        roots = labels == np.arange(n)
        out['one_leader_per_cluster'].append(np.all((per == 1) | ~roots, axis=1) & lb.any(axis=1))
    return {k: np.concatenate(v) for k, v in out.items()}


def _each_sample(r, theta, leader, w, idx):
    """The per-sample metrics of `_dense_samples`, one sample at a time, leaving out the
    agents whose row is not finite."""
    out = {k: [] for k in ('clusters', 'polarisation', 'min_distance', 'one_leader_per_cluster')}
    for i in idx:
        ok = np.isfinite(r[i]).all(axis=1) & np.isfinite(theta[i])
        ri, lead_i = (r[i], leader[i]) if ok.all() else (r[i][ok], leader[i][ok])
        count, labels = cluster_labels(ri, w)
        out['clusters'].append(count)
        out['polarisation'].append(polarisation(theta[i][ok]) if ok.any() else float('nan'))
        out['min_distance'].append(min_distance(ri))
        lead = np.flatnonzero(lead_i)
        per = [len(v) for v in leader_membership(labels, lead).values()] if len(lead) else [0]
        out['one_leader_per_cluster'].append(all(p == 1 for p in per))
    return out


def time_series(t, r, theta, leader, w, *, target=None, barrier_points=None, every: int = 1, ground=None):
    """Metric time series over a trajectory, sampled every ``every`` records.

    Returns a dict of arrays: t, clusters, polarisation, min_distance, centroid (T, 2),
    one_leader_per_cluster (bool: each cluster holds exactly one leader), and, where the
    scenario has them, centroid_target_distance, min_target_distance, intrusions.
    Agents whose row is not finite (dead: faults.py) are left out of each sample.
    In 3D (r (T, n, 3)) ``theta`` is the headings x (T, n, 3) and ``ground`` the floor's
    height (`_natural_series`)."""
    barrier = Barrier(barrier_points) if barrier_points is not None else None
    idx = np.arange(0, len(t), every)
    if idx[-1] != len(t) - 1:
        idx = np.append(idx, len(t) - 1)
    if np.shape(r)[-1] == 3:
        return _natural_series(t, r, theta, leader, w, idx, target, barrier, ground)
    if 2 <= r.shape[1] <= DENSE_SAMPLES and np.isfinite(r[idx]).all() and np.isfinite(theta[idx]).all():
        out = _dense_samples(r[idx], theta[idx], np.asarray(leader)[idx], w)   # no dead agents
    else:
        out = _each_sample(r, theta, leader, w, idx)
    res = {k: np.asarray(v) for k, v in out.items()}
    res['t'] = np.asarray(t)[idx]
    finite = np.isfinite(r[idx]).all()
    res['centroid'] = r[idx].mean(axis=1) if finite else np.nanmean(r[idx], axis=1)
    if target is not None:
        tgt = np.asarray(target, dtype=float)
        res['centroid_target_distance'] = np.hypot(*(res['centroid'] - tgt).T)
        d = np.hypot(*(r[idx] - tgt).transpose(2, 0, 1))
        res['min_target_distance'] = d.min(axis=1) if finite else np.nanmin(d, axis=1)
    if barrier is not None:
        # intrusions are checked at every record, not only the sampled ones
        flat = np.asarray(r, dtype=float).reshape(-1, 2)
        inside = barrier.inside(flat).reshape(len(t), -1).sum(axis=1)
        res['intrusions_total'] = int(inside.sum())
        res['intrusions'] = inside[idx]
        res['barrier_clearance'] = float(np.nanmin(barrier.clearance(flat)))
    return res


def _natural_series(t, r, headings, leader, w, idx, target, barrier, ground):
    """`time_series` of a 3D run: clusters (ρ < w in space), polarisation |mean_k x_k|, minimum
    distance and leaders per cluster at each sample; intrusions (inside the barrier's hull or
    below the ground) at every record.  Agents whose row is not finite (dead) are left out."""
    out = {k: [] for k in ('clusters', 'polarisation', 'min_distance', 'one_leader_per_cluster')}
    finite = bool(np.isfinite(r[idx]).all())
    for i in idx:
        ok = slice(None) if finite else np.isfinite(r[i]).all(axis=1)
        ri = r[i][ok]
        count, labels = cluster_labels_3d(ri, w)
        out['clusters'].append(count)
        out['polarisation'].append(float(np.linalg.norm(headings[i][ok].mean(axis=0))) if len(ri) else float('nan'))
        d, _ = cKDTree(ri).query(ri, k=2) if len(ri) > 1 else (np.full((1, 2), np.inf), None)
        out['min_distance'].append(float(d[:, 1].min()))
        lead = np.flatnonzero(np.asarray(leader[i])[ok])
        per = [len(v) for v in leader_membership(labels, lead).values()] if len(lead) else [0]
        out['one_leader_per_cluster'].append(all(p == 1 for p in per))
    res = {k: np.asarray(v) for k, v in out.items()}
    res['t'] = np.asarray(t)[idx]
    res['centroid'] = r[idx].mean(axis=1) if finite else np.nanmean(r[idx], axis=1)
    if target is not None:
        tgt = np.asarray(target, dtype=float)
        res['centroid_target_distance'] = np.linalg.norm(res['centroid'] - tgt, axis=1)
        d = np.linalg.norm(r[idx] - tgt, axis=2)
        res['min_target_distance'] = d.min(axis=1) if finite else np.nanmin(d, axis=1)
    if barrier is not None or ground is not None:
        flat = np.asarray(r, dtype=float).reshape(-1, 3)
        inside = np.zeros(len(flat), dtype=bool)
        if barrier is not None:
            inside |= barrier.inside(flat)
            res['barrier_clearance'] = float(np.nanmin(barrier.clearance(flat)))
        if ground is not None:
            below = flat[:, 2] < ground                                  # floor intrusions
            inside |= below
            res['floor_intrusions_total'] = int(below.sum())
            res['floor_clearance'] = float(np.nanmin(flat[:, 2] - ground))
        inside = inside.reshape(len(t), -1).sum(axis=1)
        res['intrusions_total'] = int(inside.sum())
        res['intrusions'] = inside[idx]
    return res


def cluster_labels_3d(pos, w):
    """`cluster_labels` in space: connected components of ρ_jk < w, (count, labels (n,))."""
    n = len(pos)
    ij = cKDTree(pos).query_pairs(w, output_type='ndarray')
    if ij.size:
        d = pos[ij[:, 0]] - pos[ij[:, 1]]
        ij = ij[np.einsum('pc,pc->p', d, d) < w * w]                    # strict ρ < w
    graph = coo_matrix((np.ones(len(ij)), (ij[:, 0], ij[:, 1])), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    return int(count), labels
