"""The swarm metrics (swarm_core.analysis.metrics) on small cases whose values are worked out by hand.

Each value below is written out in the comment next to it, so that a metric that computes
something else (a sum instead of a mean, an inverted test) fails here.
"""
import math

import numpy as np
import pytest

from swarm_core.analysis import metrics as M

# the barrier of these tests: the square 0 ≤ x, y ≤ 4
SQUARE = [[0, 0], [4, 0], [4, 4], [0, 4]]


# ------------------------------------------------------------------ clusters

def test_clusters_link_pairs_closer_than_the_cutoff():
    # pairs: (0,1) at 3 and (2,3) at 3.99 are linked; (3,4) at 6.01 is not: 3 clusters
    pos = [[0, 0], [3, 0], [10, 0], [13.99, 0], [20, 0]]
    count, labels = M.cluster_labels(pos, 4.0)
    assert count == 3
    assert labels[0] == labels[1] and labels[2] == labels[3]
    assert len({labels[0], labels[2], labels[4]}) == 3


def test_clusters_are_chains_not_diameters():
    # 0-1-2 at 3 apart: one cluster though 0 and 2 are 6 apart
    assert M.cluster_labels([[0, 0], [3, 0], [6, 0]], 4.0)[0] == 1


def test_cluster_cutoff_is_strict():
    # ρ = 4 exactly is not < w = 4: two clusters; just below: one
    assert M.cluster_labels([[0, 0], [4, 0]], 4.0)[0] == 2
    assert M.cluster_labels([[0, 0], [3.999, 0]], 4.0)[0] == 1
    assert M.cluster_labels(np.zeros((0, 2)), 4.0)[0] == 0


# ------------------------------------------------------------------ polarisation

def test_polarisation_is_the_length_of_the_mean_heading():
    # headings 0, 0, π/2, π: mean x = (1 + 1 + 0 − 1)/4 = 1/4, mean y = (0 + 0 + 1 + 0)/4 = 1/4
    assert M.polarisation([0, 0, math.pi / 2, math.pi]) == pytest.approx(math.sqrt(2) / 4, abs=1e-15)
    # six aligned agents: 1 (a sum would give 6); two opposite: 0
    assert M.polarisation(np.full(6, 0.3)) == pytest.approx(1.0, abs=1e-15)
    assert M.polarisation([0.0, math.pi]) == pytest.approx(0.0, abs=1e-15)
    # three at 120° apart cancel
    assert M.polarisation([0.0, 2 * math.pi / 3, 4 * math.pi / 3]) == pytest.approx(0.0, abs=1e-15)


# ------------------------------------------------------------------ minimum distance

def test_min_distance_small_swarm():
    # pairs: |(3,4)| = 5, |(10,0)| = 10, |(7,−4)| = √65: minimum 5
    assert M.min_distance([[0, 0], [3, 4], [10, 0]]) == 5.0
    assert M.min_distance([[1, 1]]) == math.inf


def test_min_distance_large_swarm_takes_the_tree_path():
    # a 15 x 15 grid 2 apart (225 agents, above DENSE_MIN_DISTANCE) with one agent moved to
    # 0.5 from its neighbour: minimum 0.5
    assert 15 * 15 > M.DENSE_MIN_DISTANCE
    g = np.array([[2.0 * i, 2.0 * j] for i in range(15) for j in range(15)])
    assert M.min_distance(g) == 2.0
    g[1] = g[0] + [0.3, 0.4]
    assert M.min_distance(g) == pytest.approx(0.5, abs=1e-15)


# ------------------------------------------------------------------ barrier

def test_barrier_inside_the_hull():
    b = M.Barrier(SQUARE)
    # centre and a point near a corner inside; outside on each side; on the edge is not inside
    got = b.inside([[2, 2], [0.1, 3.9], [5, 2], [-1, 2], [2, 5], [2, -0.5], [4, 2]])
    assert got.tolist() == [True, True, False, False, False, False, False]


def test_barrier_inside_with_a_margin():
    b = M.Barrier(SQUARE)
    # the hull grown by 1: x = 4.5 is 0.5 outside the x = 4 face, so inside; x = 5.5 is not
    assert b.inside([[4.5, 2], [5.5, 2]], margin=1.0).tolist() == [True, False]
    # shrunk by 1: the centre (2 from every face) still inside, (3.5, 2) not
    assert b.inside([[2, 2], [3.5, 2]], margin=-1.0).tolist() == [True, False]


def test_barrier_of_fewer_than_three_points_has_no_inside():
    assert M.Barrier([[0, 0], [1, 1]]).inside([[0.5, 0.5]]).tolist() == [False]


def test_barrier_clearance_is_the_distance_to_the_nearest_barrier_point():
    b = M.Barrier(SQUARE)
    # (2, 2): √8 to every corner; (7, 4): 3 to (4, 4); (−3, −4): 5 to (0, 0)
    got = b.clearance([[2, 2], [7, 4], [-3, -4]])
    np.testing.assert_allclose(got, [math.sqrt(8), 3.0, 5.0], rtol=0, atol=1e-15)


# ------------------------------------------------------------------ one record, target distance

def test_one_record_target_and_intrusions():
    # agents at (0, 0), (2, 0) and (2, 2) (the last inside the square barrier); target (1, 3)
    pos = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    s = M.time_series(np.zeros(1), pos[None], np.array([[0.0, 0.0, math.pi]]), np.array([[True, False, False]]),
                      4.0, target=(1.0, 3.0), barrier_points=SQUARE)
    snap = {k: v[0] for k, v in s.items() if k not in ('intrusions_total', 'barrier_clearance')}
    assert snap['clusters'] == 1                                   # 2 and 2√2 < 4
    assert snap['polarisation'] == pytest.approx(1 / 3, abs=1e-15)  # |(1 + 1 − 1)/3|
    assert snap['min_distance'] == 2.0
    assert snap['centroid'] == pytest.approx([4 / 3, 2 / 3], abs=1e-15)
    # centroid (4/3, 2/3) to (1, 3): √((1/3)² + (7/3)²) = √50 / 3
    assert snap['centroid_target_distance'] == pytest.approx(math.sqrt(50) / 3, abs=1e-14)
    # nearest agent to (1, 3): (2, 2) at √2
    assert snap['min_target_distance'] == pytest.approx(math.sqrt(2), abs=1e-15)
    assert snap['intrusions'] == 1 and s['intrusions_total'] == 1
    assert snap['one_leader_per_cluster']


# ------------------------------------------------------------------ time series

def test_time_series_counts_every_record_inside_the_barrier():
    # three records of two agents; agent 1 is inside the square at records 1 and 2 only,
    # agent 0 stays at (−3, −4) (clearance 5); sampled every 2 records: t = 0 and t = 2
    t = np.array([0.0, 1.0, 2.0])
    r = np.array([[[-3, -4], [6, 2]], [[-3, -4], [3, 2]], [[-3, -4], [2, 2]]], dtype=float)
    theta = np.zeros((3, 2))
    leader = np.array([[True, False]] * 3)
    s = M.time_series(t, r, theta, leader, 4.0, target=(0.0, 0.0), barrier_points=SQUARE, every=2)
    assert s['t'].tolist() == [0.0, 2.0]
    assert s['intrusions_total'] == 2                 # records 1 and 2, though record 1 is not sampled
    assert s['intrusions'].tolist() == [0, 1]
    # clearance over every record: agent 1 at (3, 2) is √(1 + 4) = √5 from (4, 0) and (4, 4)
    assert s['barrier_clearance'] == pytest.approx(math.sqrt(5), abs=1e-15)
    # t = 0: |(−3,−4) − (6,2)| = √117 > 4: two clusters, one holds no leader
    assert s['clusters'].tolist() == [2, 2]
    assert s['one_leader_per_cluster'].tolist() == [False, False]
    # target (0, 0): centroid at t = 2 is (−0.5, −1): √1.25; nearest agent (2, 2): √8
    assert s['centroid_target_distance'][1] == pytest.approx(math.sqrt(1.25), abs=1e-15)
    assert s['min_target_distance'][1] == pytest.approx(math.sqrt(8), abs=1e-15)
    assert s['polarisation'].tolist() == [1.0, 1.0]


def test_time_series_leaves_out_dead_agents():
    # agent 2 is dead (NaN row) at the second record: clusters and polarisation of the others
    t = np.array([0.0, 1.0])
    r = np.array([[[0, 0], [1, 0], [20, 0]], [[0, 0], [1, 0], [np.nan, np.nan]]])
    theta = np.array([[0.0, 0.0, math.pi], [0.0, 0.0, np.nan]])
    leader = np.array([[True, False, True], [True, False, False]])
    s = M.time_series(t, r, theta, leader, 4.0)
    assert s['clusters'].tolist() == [2, 1]
    assert s['polarisation'][0] == pytest.approx(1 / 3, abs=1e-15)
    assert s['polarisation'][1] == 1.0
    assert s['one_leader_per_cluster'].tolist() == [True, True]
    assert s['min_distance'].tolist() == [1.0, 1.0]
