"""The samples within a radius: clustered and lone points get what a brute force gives, by index."""

import numpy as np
from scipy.spatial import cKDTree

from pinchmatch.mesh.neighbours import CLUSTER_POINTS, neighbours_within
from pinchmatch.mesh.shapes import torus
from conftest import random_rigid


def brute_force(samples, point, radius, k):
    """The samples within ``radius`` of ``point``, the ``k`` nearest (ties to the lower index), by
    index."""
    d2 = ((samples - point) ** 2).sum(axis=1)
    inside = np.flatnonzero(d2 < radius * radius)
    nearest = inside[np.lexsort((inside, d2[inside]))][:k]
    return np.sort(nearest)


def test_clustered_and_lone_points_get_the_brute_force_neighbours_by_index():
    """A torus turned at random and moved off the origin, its dense points as samples: clusters of
    points around a few targets (one ball query per cube) and lone points far apart (a KD-tree query
    each) get exactly the brute force's neighbours, the nearest k where more lie within the radius,
    ascending; a point gets the same neighbours whether it is asked alone or in a cluster."""
    R, t = random_rigid(11)
    mesh = torus(faces=6000).mesh
    samples = mesh.sample(20000, seed=3) @ R.T + t
    tree = cKDTree(samples)
    rng = np.random.default_rng(5)
    targets = samples[rng.integers(0, len(samples), 12)]
    cluster = (targets[:, None, :] + rng.normal(0.0, 2.5, (12, 25, 3))).reshape(-1, 3)
    lone = samples[rng.integers(0, len(samples), 5)] + rng.normal(0.0, 1.0, (5, 3))
    points = np.concatenate([cluster, lone])
    for radius, k in ((8.0, 320), (8.0, 40), (3.0, 320)):
        idx, counts = neighbours_within(tree, samples, points, radius, k)
        assert idx.shape == (len(points), max(counts.max(), 1))
        capped = 0
        for i, p in enumerate(points):
            want = brute_force(samples, p, radius, k)
            assert np.array_equal(idx[i, :counts[i]], want), (radius, k, i)
            assert (idx[i, counts[i]:] == 0).all()
            capped += counts[i] == k
        if k == 40:
            assert capped > 100  # the cap was exercised
    # asked alone (a cube of one point: the KD-tree's own query), the same
    assert len(cluster) >= CLUSTER_POINTS
    one, n_one = neighbours_within(tree, samples, cluster[7:8], 8.0, 40)
    idx, counts = neighbours_within(tree, samples, points, 8.0, 40)
    assert np.array_equal(one[0, :n_one[0]], idx[7, :counts[7]])
