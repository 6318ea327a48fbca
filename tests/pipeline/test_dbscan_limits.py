"""DBSCAN and its size filter at their exact limits, and the counts it reports (SR-TRK-2).

A pair exactly ``eps`` apart at exactly the edge of the angular search window, clusters of
exactly ``min_points`` and ``max_points`` points and one more or fewer, the cap on the number of
clusters when their nearest points tie, and every count of :class:`~pipeline.types.ClusterCounts`
on a scan whose answer is known point by point. The mutation campaign of the per-cycle stages
(SR-EVD-6, docs/findings/mutation.md) showed these unwatched.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.cluster.dbscan import neighbour_pairs, partition_points
from pipeline.config import default_config, overridden
from pipeline.points import scan_to_points
from pipeline.types import DROPPED_LABEL, NOISE_LABEL, Scan, ScanPoints

DBSCAN = ["pipeline/cluster/dbscan.py"]
RANGE_M = 10.0


def _arcs(sizes: list[int], ranges_m: list[float] | None = None) -> ScanPoints:
    """Groups of ``sizes`` points on circles about the sensor (10 m unless ``ranges_m`` says),
    0.1 m between neighbours, each group a line of neighbours (interior points core, the two
    ends border), the groups 0.5 m apart and more: never neighbours."""
    ranges = ranges_m if ranges_m is not None else [RANGE_M] * len(sizes)
    angles: list[float] = []
    dist: list[float] = []
    start = -3.0
    for size, r in zip(sizes, ranges, strict=True):
        step = 0.1 / r
        angles.extend(start + step * np.arange(size))
        dist.extend([r] * size)
        start += step * size + 0.5 / r
    assert start < math.pi
    scan = Scan(stamp_s=7.5, angles_rad=np.asarray(angles), ranges_m=np.asarray(dist))
    return scan_to_points(scan, default_config().scan)


@pytest.mark.requirement("SR-TRK-2", code=DBSCAN)
@pytest.mark.parametrize(
    ("far", "near", "eps_m"),
    [((25.0, 0.0), (16.0, 12.0), 15.0), ((625.0, 0.0), (49.0, 168.0), 600.0)],
    ids=["3-4-5", "7-24-25"],
)
def test_a_pair_exactly_eps_apart_at_the_edge_of_the_search_window_is_found(
    far: tuple[float, float], near: tuple[float, float], eps_m: float
) -> None:
    # Right angle at the nearer point: seen from the farther one the nearer lies exactly
    # asin(eps / range) ahead, the widest angle a neighbour can subtend, and exactly eps away,
    # all in exact binary arithmetic (the second window is wider than 1 rad, where a relative
    # shrink of the window outweighs its absolute slack).
    x, y = np.array([far[0], near[0]]), np.array([far[1], near[1]])
    angle, rng = np.arctan2(y, x), np.hypot(x, y)
    i, j, d2 = neighbour_pairs(x, y, angle, rng, eps_m)
    assert (i.tolist(), j.tolist(), d2.tolist()) == ([0], [1], [eps_m * eps_m])
    i, j, d2 = neighbour_pairs(x, y, angle, rng, math.nextafter(eps_m, 0.0))
    assert i.size == j.size == d2.size == 0


@pytest.mark.requirement("SR-TRK-2", code=DBSCAN)
@pytest.mark.parametrize("n", [0, 1, 2])
def test_no_pair_gives_three_empty_arrays(n: int) -> None:
    x = np.array([1.0, -5.0])[:n]
    y = np.zeros(n)
    angle, rng = np.arctan2(y, x), np.hypot(x, y)
    order = np.argsort(angle)
    i, j, d2 = neighbour_pairs(x[order], y[order], angle[order], rng[order], 0.15)
    assert (i.shape, j.shape, d2.shape) == ((0,), (0,), (0,))


@pytest.mark.requirement("SR-TRK-2", code=DBSCAN)
def test_the_size_filter_keeps_exactly_min_to_max_points_and_counts_everything() -> None:
    config = overridden(default_config(), {"cluster": {"min_points": 4, "max_points": 10}})
    # groups: a line of 4 (kept), a single point, 3 (too small), 10 (kept), a pair (noise:
    # no core point), 11 (too large), a single point
    points = _arcs([4, 1, 3, 10, 2, 11, 1])
    part = partition_points(points, config.cluster)
    assert part.stamp_s == 7.5
    d, n = DROPPED_LABEL, NOISE_LABEL
    want = [0] * 4 + [n] + [d] * 3 + [1] * 10 + [n] * 2 + [d] * 11 + [n]
    assert part.point_labels.tolist() == want
    assert part.n_clusters == 2
    c = part.counts
    assert (c.n_found, c.n_too_small, c.n_too_large, c.n_over_cap) == (4, 1, 1, 0)
    assert c.n_noise_points == 4
    assert c.n_border_points == 8  # the two ends of each of the four lines, dropped ones too


@pytest.mark.requirement("SR-TRK-2", code=DBSCAN)
def test_the_cap_keeps_the_nearest_clusters_and_the_first_ones_among_ties() -> None:
    config = overridden(default_config(), {"cluster": {"max_clusters": 20}})
    # 40 lines of 4 points at 6, 8 or 10 m: 14 at 6 m, 13 at 8 m; the cap cuts the 8 m ones
    tier = [2, 1, 1, 0, 0, 0, 0, 0, 0, 2, 1, 2, 1, 1, 2, 2, 1, 1, 1, 2]
    tier += [0, 2, 2, 0, 1, 2, 1, 0, 2, 2, 2, 0, 0, 2, 0, 1, 0, 0, 1, 1]
    part = partition_points(_arcs([4] * 40, [6.0 + 2.0 * t for t in tier]), config.cluster)
    want = sorted(sorted(range(40), key=lambda k: (tier[k], k))[:20])
    assert part.n_clusters == 20
    assert part.counts.n_over_cap == 20
    labels = part.point_labels.reshape(40, 4)
    assert np.flatnonzero(labels[:, 0] >= 0).tolist() == want
    assert labels[want].tolist() == [[k] * 4 for k in range(20)]
    assert (np.delete(labels, want, axis=0) == DROPPED_LABEL).all()
    exact = overridden(default_config(), {"cluster": {"max_clusters": 40}})
    assert partition_points(_arcs([4] * 40), exact.cluster).counts.n_over_cap == 0
