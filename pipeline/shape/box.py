"""Cluster geometry: convex hulls and minimum-area oriented boxes, all clusters at once.

The shape role's default (:class:`BoxShapes`) turns a partition into :class:`Clusters`.

Serves SR-TRK-2 (cluster geometry) and SR-TIM-3 (bounded work: no per-point Python loop).

Convex hull: Andrew's monotone chain, made data-parallel. The points of every cluster are
sorted lexicographically by (x, y); each cluster contributes a lower chain (left to right)
and an upper chain (right to left). A pass removes, in every chain at once, every interior
vertex that does not make a strict left turn with its current neighbours; passes repeat until
none is removed. Removing a non-left-turn vertex only lowers the chain, and a maximal run of
simultaneously removed vertices lies on or above the segment that replaces it (its lowest
vertex would otherwise make a strict left turn), so every input point stays on or above the
final chain; a strictly convex chain between the extreme points with every point on or above
it is the hull chain. Collinear points are not hull vertices; a cluster whose points are all
collinear has a two-vertex hull, coincident points a one-vertex hull.

Oriented box: by the rotating-calipers theorem (Freeman and Shapira 1975) a minimum-area
enclosing rectangle has a side collinear with a hull edge, so every hull-edge orientation is
evaluated (all clusters and edges in one vectorized pass, O(h^2) per cluster, which for the
h <= a few dozen hull vertices of scan clusters is faster in numpy than the O(h) sweep).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import ClusterSection
from pipeline.shape.ends import cluster_ends
from pipeline.types import Clusters, FloatArray, IntArray, Partition, ScanPoints

__all__ = ["BoxShapes", "Shapes", "cluster_geometry", "cluster_shapes", "convex_hulls"]


@dataclass(frozen=True, slots=True)
class Shapes:
    """Hulls and boxes of ``n`` clusters (arrays owned by the caller, not frozen)."""

    hull_x_m: FloatArray
    hull_y_m: FloatArray
    hull_offsets: IntArray
    width_m: FloatArray
    length_m: FloatArray
    heading_rad: FloatArray


def convex_hulls(
    x_m: FloatArray, y_m: FloatArray, labels: IntArray, n_clusters: int
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Counter-clockwise hull vertices of the points of each label ``0..n_clusters-1``.

    Points with a label outside that range are ignored; every label must have a point.
    Returns ``(hull_x_m, hull_y_m, hull_offsets)`` with ``n_clusters + 1`` offsets.
    """
    member = (labels >= 0) & (labels < n_clusters)
    idx = np.flatnonzero(member)
    lab = labels[idx]
    lower = idx[np.lexsort((y_m[idx], x_m[idx], lab))]
    size = np.bincount(lab, minlength=n_clusters)
    start = np.cumsum(size) - size
    # The upper chain of a cluster is its lower chain reversed; chains are laid out as
    # [lower_0, upper_0, lower_1, upper_1, ...] so each cluster's ring comes out in order.
    lab_sorted = labels[lower]
    pos = np.arange(lower.shape[0]) - start[lab_sorted]
    reversed_pos = start[lab_sorted] + size[lab_sorted] - 1 - pos
    order = np.empty(2 * lower.shape[0], dtype=np.int64)
    chain = np.empty(2 * lower.shape[0], dtype=np.int64)
    base = 2 * start[lab_sorted]
    order[base + pos] = lower
    chain[base + pos] = 2 * lab_sorted
    order[base + size[lab_sorted] + pos] = lower[reversed_pos]
    chain[base + size[lab_sorted] + pos] = 2 * lab_sorted + 1
    px, py = x_m[order], y_m[order]
    # Compacted working copies: each pass drops the removed vertices from all three arrays.
    ax, ay, ach = px, py, chain
    for _ in range(order.shape[0]):
        if ax.shape[0] < 3:
            break
        same = ach[:-1] == ach[1:]
        interior = same[:-1] & same[1:]
        cross = (ax[1:-1] - ax[:-2]) * (ay[2:] - ay[:-2]) - (ay[1:-1] - ay[:-2]) * (
            ax[2:] - ax[:-2]
        )
        remove = interior & (cross <= 0.0)
        if not remove.any():
            break
        keep = np.ones(ax.shape[0], dtype=bool)
        keep[1:-1] = ~remove
        ax, ay, ach = ax[keep], ay[keep], ach[keep]
    last_of_chain = np.ones(ax.shape[0], dtype=bool)
    last_of_chain[:-1] = ach[:-1] != ach[1:]
    vertex = ~last_of_chain
    hx, hy = ax[vertex], ay[vertex]
    cluster_of_vertex = ach[vertex] // 2
    counts = np.bincount(cluster_of_vertex, minlength=n_clusters)
    # All points coincident: the two chains leave two copies of the one point.
    twin = np.flatnonzero(counts == 2)
    if twin.shape[0]:
        offsets = np.concatenate([[0], np.cumsum(counts)])
        first = offsets[twin]
        same = (hx[first] == hx[first + 1]) & (hy[first] == hy[first + 1])
        if same.any():
            drop = np.ones(hx.shape[0], dtype=bool)
            drop[first[same] + 1] = False
            hx, hy, cluster_of_vertex = hx[drop], hy[drop], cluster_of_vertex[drop]
            counts = np.bincount(cluster_of_vertex, minlength=n_clusters)
    hull_offsets = np.zeros(n_clusters + 1, dtype=np.int64)
    np.cumsum(counts, out=hull_offsets[1:])
    return hx, hy, hull_offsets


def _wrap_half_pi(angle: FloatArray) -> FloatArray:
    """Map a line direction (defined modulo pi) into [-pi/2, pi/2)."""
    return np.mod(angle + math.pi / 2.0, math.pi) - math.pi / 2.0


def _boxes(
    hx: FloatArray, hy: FloatArray, offsets: IntArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Minimum-area box (width <= length, heading of the long side) of each hull."""
    n = offsets.shape[0] - 1
    h = np.diff(offsets)
    width = np.zeros(n)
    length = np.zeros(n)
    heading = np.zeros(n)
    pair = np.flatnonzero(h == 2)
    if pair.shape[0]:
        dx = hx[offsets[pair] + 1] - hx[offsets[pair]]
        dy = hy[offsets[pair] + 1] - hy[offsets[pair]]
        length[pair] = np.hypot(dx, dy)
        heading[pair] = _wrap_half_pi(np.arctan2(dy, dx))
    poly = np.flatnonzero(h >= 3)
    if poly.shape[0] == 0:
        return width, length, heading
    hp = h[poly]
    # Edges: every hull vertex of the polygon clusters, to its successor on the ring.
    edge_start = np.repeat(offsets[poly], hp)
    edge_cluster = np.repeat(np.arange(poly.shape[0]), hp)
    edge_pos = np.arange(edge_start.shape[0]) - np.repeat(np.cumsum(hp) - hp, hp)
    e0 = edge_start + edge_pos
    e1 = edge_start + (edge_pos + 1) % np.repeat(hp, hp)
    ex, ey = hx[e1] - hx[e0], hy[e1] - hy[e0]
    norm = np.hypot(ex, ey)
    ux, uy = ex / norm, ey / norm
    # Every (edge, vertex of the same hull) pair, grouped by edge.
    per_edge = np.repeat(hp, hp)
    pair_edge = np.repeat(np.arange(e0.shape[0]), per_edge)
    block_start = np.cumsum(per_edge) - per_edge
    vertex = np.repeat(edge_start, per_edge) + (
        np.arange(pair_edge.shape[0]) - np.repeat(block_start, per_edge)
    )
    rx = hx[vertex] - hx[e0[pair_edge]]
    ry = hy[vertex] - hy[e0[pair_edge]]
    along = rx * ux[pair_edge] + ry * uy[pair_edge]
    across = ry * ux[pair_edge] - rx * uy[pair_edge]
    extent_u = np.maximum.reduceat(along, block_start) - np.minimum.reduceat(along, block_start)
    extent_n = np.maximum.reduceat(across, block_start) - np.minimum.reduceat(across, block_start)
    area = extent_u * extent_n
    best_first = np.lexsort((np.arange(area.shape[0]), area, edge_cluster))
    cluster_sorted = edge_cluster[best_first]
    first = np.ones(best_first.shape[0], dtype=bool)
    first[1:] = cluster_sorted[1:] != cluster_sorted[:-1]
    best = best_first[first]
    eu, en = extent_u[best], extent_n[best]
    along_long = eu >= en
    width[poly] = np.where(along_long, en, eu)
    length[poly] = np.where(along_long, eu, en)
    direction = np.where(
        along_long, np.arctan2(uy[best], ux[best]), np.arctan2(ux[best], -uy[best])
    )
    heading[poly] = _wrap_half_pi(direction)
    return width, length, heading


def cluster_shapes(x_m: FloatArray, y_m: FloatArray, labels: IntArray, n_clusters: int) -> Shapes:
    """Convex hull and minimum-area oriented box of each cluster ``0..n_clusters-1``."""
    hx, hy, offsets = convex_hulls(x_m, y_m, labels, n_clusters)
    width, length, heading = _boxes(hx, hy, offsets)
    return Shapes(hx, hy, offsets, width, length, heading)


def cluster_geometry(points: ScanPoints, partition: Partition, config: ClusterSection) -> Clusters:
    """Centroid, oriented box, hull, point density and ends of every kept cluster (SR-TRK-2)."""
    labels = partition.point_labels
    n_kept = partition.n_clusters
    member = labels >= 0
    lab = labels[member]
    n_points = np.bincount(lab, minlength=n_kept)
    cx = np.bincount(lab, weights=points.x_m[member], minlength=n_kept) / np.maximum(n_points, 1)
    cy = np.bincount(lab, weights=points.y_m[member], minlength=n_kept) / np.maximum(n_points, 1)
    shapes = cluster_shapes(points.x_m, points.y_m, labels, n_kept)
    area = shapes.width_m * shapes.length_m
    end_x, end_y, end_occluded = cluster_ends(points, labels, n_kept)
    return Clusters(
        stamp_s=points.stamp_s,
        centroid_x_m=cx,
        centroid_y_m=cy,
        width_m=shapes.width_m,
        length_m=shapes.length_m,
        heading_rad=shapes.heading_rad,
        area_m2=area,
        point_density_per_m2=n_points / np.maximum(area, config.density_min_area_m2),
        n_points=n_points,
        hull_x_m=shapes.hull_x_m,
        hull_y_m=shapes.hull_y_m,
        hull_offsets=shapes.hull_offsets,
        point_labels=labels,
        counts=partition.counts,
        end_x_m=end_x,
        end_y_m=end_y,
        end_occluded=end_occluded,
    )


@dataclass(frozen=True)
class BoxShapes:
    """The shape role's default: minimum-area oriented boxes (:func:`cluster_geometry`)."""

    config: ClusterSection

    def clusters(self, points: ScanPoints, partition: Partition) -> Clusters:
        """The kept clusters of ``partition`` with their geometry."""
        return cluster_geometry(points, partition, self.config)
