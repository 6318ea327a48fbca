"""DBSCAN on scan points and per-cluster geometry (requirements SR-TRK-2, SR-TIM-3).

Parameters from the source material: ``eps_m`` 0.15, ``min_samples`` 3 (a point counts itself,
as in scikit-learn), clusters of ``min_points``..``max_points`` (4..200) kept, at most
``max_clusters`` per scan (the nearest to the robot are kept; the rest are counted).

Neighbour search exploits the scan's angular order instead of a tree: two points closer than
``eps`` with sensor ranges ``r_i``, ``r_j`` (both > eps) subtend at the sensor an angle of at
most ``asin(eps / max(r_i, r_j))`` (an obtuse angle at the sensor would make their distance
exceed both ranges). So the candidates of point ``i`` lie in the angular window
``(a_i, a_i + asin(eps / r_i)]`` ahead of it (a half plane when ``r_i <= eps``), found with one
``searchsorted`` on the sorted bearings (with a 2 pi copy for scans that wrap), and each
candidate pair is then checked exactly: ``dx*dx + dy*dy <= eps*eps``, the same arithmetic as
scikit-learn's KD-tree radius query.

Partition rule. Core points (at least ``min_samples`` points, itself included, within eps)
and their clusters (connected components of the core-core eps graph) are exactly those of
``sklearn.cluster.DBSCAN``. A border point (not core, within eps of a core point) joins the
cluster of its NEAREST core point (ties: the lower cluster index). scikit-learn instead gives
it to whichever adjacent cluster its expansion loop reaches first, which depends on the input
order; ours depends only on geometry. The two differ only on border points within eps of two
clusters; the cross-check counts them. Noise (neither) is identical.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import ClusterSection, SafecaseConfig
from pipeline.points import scan_to_points
from pipeline.shape.box import cluster_geometry
from pipeline.types import (
    DROPPED_LABEL,
    NOISE_LABEL,
    BoolArray,
    ClusterCounts,
    Clusters,
    FloatArray,
    IntArray,
    Partition,
    Scan,
    ScanPoints,
)

__all__ = [
    "DbscanClusterer",
    "DbscanResult",
    "cluster_points",
    "cluster_scan",
    "dbscan_points",
    "neighbour_pairs",
    "partition_points",
]

_TWO_PI = 2.0 * math.pi
# Relative widening of the angular window: the exact distance test decides, so a window a
# little too wide costs nothing, while one too narrow by a rounding error would miss a pair.
_WINDOW_SLACK = 1e-9


@dataclass(frozen=True, slots=True)
class DbscanResult:
    """Raw DBSCAN output before the size filter (SR-TRK-2).

    ``labels``: cluster per point, -1 for noise, clusters numbered in order of their first
    point (sweep order). ``is_core``: core-point mask. ``n_clusters``: number of clusters.
    """

    labels: IntArray
    is_core: BoolArray
    n_clusters: int


def neighbour_pairs(
    x_m: FloatArray, y_m: FloatArray, angle_rad: FloatArray, range_m: FloatArray, eps_m: float
) -> tuple[IntArray, IntArray, FloatArray]:
    """Every unordered pair of points at distance <= ``eps_m``, each once (SR-TRK-2).

    Points must be sorted by ``angle_rad`` (in [-pi, pi)), as :func:`scan_to_points` returns
    them; ``range_m`` is the distance from the sensor. Returns ``(i, j, d2_m2)``.
    """
    n = x_m.shape[0]
    empty = np.empty(0, dtype=np.int64)
    if n < 2:
        return empty, empty, np.empty(0)
    ratio = np.minimum(eps_m / np.maximum(range_m, 1e-300), 1.0)
    window = np.where(range_m > eps_m, np.arcsin(ratio), math.pi) * (1.0 + _WINDOW_SLACK)
    window += _WINDOW_SLACK
    extended = np.concatenate([angle_rad, angle_rad + _TWO_PI])
    start = np.arange(n)
    end = np.minimum(np.searchsorted(extended, angle_rad + window, side="right"), start + n)
    count = np.maximum(end - start - 1, 0)
    total = int(count.sum())
    if total == 0:
        return empty, empty, np.empty(0)
    first = np.repeat(start, count)
    block = np.cumsum(count) - count
    second = first + 1 + (np.arange(total) - np.repeat(block, count))
    second[second >= n] -= n
    dx = x_m[first] - x_m[second]
    dy = y_m[first] - y_m[second]
    d2 = dx * dx + dy * dy
    close = d2 <= eps_m * eps_m
    i, j, d2 = first[close], second[close], d2[close]
    if range_m.min() <= eps_m:
        # Two points within eps of the sensor on opposite bearings can be found from both ends.
        lo, hi = np.minimum(i, j), np.maximum(i, j)
        _, unique = np.unique(lo * n + hi, return_index=True)
        i, j, d2 = lo[unique], hi[unique], d2[unique]
    return i, j, d2


def _components(n: int, a: IntArray, b: IntArray) -> IntArray:
    """Root (lowest index) of each node's connected component in the graph of edges a-b.

    Vectorized hook-and-jump (Shiloach-Vishkin style): every edge joining two different trees
    hangs the larger root under the smaller one, then pointer jumping flattens the trees. Each
    round at least halves the number of trees an edge can still join, so rounds are few (and
    never more than n). scipy's connected_components does the same job with ~70 us of fixed
    overhead per call, most of the DBSCAN budget.
    """
    parent = np.arange(n)
    for _ in range(n):
        ra, rb = parent[a], parent[b]
        open_edge = ra != rb
        if not open_edge.any():
            break
        ra, rb = ra[open_edge], rb[open_edge]
        np.minimum.at(parent, np.maximum(ra, rb), np.minimum(ra, rb))
        for _ in range(n):
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
    return parent


def dbscan_points(points: ScanPoints, eps_m: float, min_samples: int) -> DbscanResult:
    """DBSCAN over ``points`` with the border rule in the module docstring (SR-TRK-2)."""
    n = points.n
    i, j, d2 = neighbour_pairs(points.x_m, points.y_m, points.angle_rad, points.range_m, eps_m)
    degree = np.bincount(i, minlength=n) + np.bincount(j, minlength=n) + 1
    is_core = degree >= min_samples
    labels = np.full(n, -1, dtype=np.int64)
    core_edge = is_core[i] & is_core[j]
    root = _components(n, i[core_edge], j[core_edge])
    core_index = np.flatnonzero(is_core)
    # Each component's root is its lowest point index, so sorting roots numbers the clusters
    # in sweep order of their first core point.
    roots, dense = np.unique(root[core_index], return_inverse=True)
    labels[core_index] = dense
    n_clusters = int(roots.shape[0])
    mixed = is_core[i] != is_core[j]
    if mixed.any():
        core_end = np.where(is_core[i[mixed]], i[mixed], j[mixed])
        border = np.where(is_core[i[mixed]], j[mixed], i[mixed])
        cluster = labels[core_end]
        order = np.lexsort((cluster, d2[mixed], border))
        border_sorted = border[order]
        first = np.ones(order.shape[0], dtype=bool)
        first[1:] = border_sorted[1:] != border_sorted[:-1]
        labels[border_sorted[first]] = cluster[order[first]]
    return DbscanResult(labels=labels, is_core=is_core, n_clusters=n_clusters)


def partition_points(points: ScanPoints, config: ClusterSection) -> Partition:
    """DBSCAN, size filter and cap for one scan's points (SR-TRK-2, SR-TIM-3)."""
    raw = dbscan_points(points, config.eps_m, config.min_samples)
    sizes = np.bincount(raw.labels[raw.labels >= 0], minlength=raw.n_clusters)
    too_small = sizes < config.min_points
    too_large = sizes > config.max_points
    keep = ~too_small & ~too_large
    kept = np.flatnonzero(keep)
    n_over_cap = 0
    if kept.shape[0] > config.max_clusters:
        # Keep the nearest clusters: the ones that matter first for a stopping decision.
        lab = raw.labels[raw.labels >= 0]
        nearest = np.full(raw.n_clusters, np.inf)
        np.minimum.at(nearest, lab, points.range_m[raw.labels >= 0])
        chosen = kept[np.argsort(nearest[kept], kind="stable")[: config.max_clusters]]
        n_over_cap = kept.shape[0] - config.max_clusters
        kept = np.sort(chosen)
    # Raw label -1 (noise) indexes the extra last entry and stays NOISE_LABEL; every dropped
    # cluster becomes DROPPED_LABEL (the radar's LiDAR degradation index counts noise alone).
    remap = np.full(raw.n_clusters + 1, DROPPED_LABEL, dtype=np.int64)
    remap[-1] = NOISE_LABEL
    remap[kept] = np.arange(kept.shape[0])
    return Partition(
        stamp_s=points.stamp_s,
        point_labels=remap[raw.labels],
        n_clusters=int(kept.shape[0]),
        counts=ClusterCounts(
            n_found=raw.n_clusters,
            n_too_small=int(too_small.sum()),
            n_too_large=int(too_large.sum()),
            n_over_cap=n_over_cap,
            n_noise_points=int(np.count_nonzero(raw.labels < 0)),
            n_border_points=int(np.count_nonzero((raw.labels >= 0) & ~raw.is_core)),
        ),
    )


@dataclass(frozen=True)
class DbscanClusterer:
    """The clustering role's default: :func:`partition_points` with the ``cluster`` section."""

    config: ClusterSection

    def partition(self, points: ScanPoints) -> Partition:
        """The kept clusters of ``points``."""
        return partition_points(points, self.config)


def cluster_points(points: ScanPoints, config: ClusterSection) -> Clusters:
    """Partition and cluster geometry for one scan's points (SR-TRK-2, SR-TIM-3)."""
    return cluster_geometry(points, partition_points(points, config), config)


def cluster_scan(scan: Scan, config: SafecaseConfig) -> tuple[ScanPoints, Clusters]:
    """Sanitize ``scan`` and cluster its points with the ``scan`` and ``cluster`` sections."""
    points = scan_to_points(scan, config.scan)
    return points, cluster_points(points, config.cluster)
