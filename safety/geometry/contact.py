"""Penetration depth, minimum translation vector and separation distance (SR-SAT-2).

For two convex polygons the separating axis theorem gives more than a verdict: the largest
edge-normal gap ``g`` (gap of the projections along the unit normal) is the penetration
depth ``-g`` when they overlap (the Minkowski difference of two convex polygons has exactly
their edge normals), and the translation of B by ``depth`` along that normal separates them.
For disjoint polygons the Euclidean distance is attained between a vertex of one and an edge
of the other. These are not on the per-cycle hot path (the governor asks for them for the
few blocked pairs), so they evaluate all pairs of features directly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.errors import GeometryError
from pipeline.types import ConvexPolygons, FloatArray

__all__ = ["Contact", "contact_pairs"]


@dataclass(frozen=True, slots=True)
class Contact:
    """Per matched pair: ``depth_m`` (penetration, 0 when apart), ``mtv_m`` (N, 2) the
    translation of B that separates it from A (zero when apart), ``distance_m`` (0 when they
    overlap or touch) and ``best_gap_m`` (the largest edge-normal gap, signed)."""

    depth_m: FloatArray
    mtv_m: FloatArray
    distance_m: FloatArray
    best_gap_m: FloatArray


def _stack(a: ConvexPolygons, b: ConvexPolygons) -> FloatArray:
    k = max(a.k, b.k)
    v = np.empty((2, 2, k, a.n))
    v[0, :, : a.k] = a.vertices_m
    v[1, :, : b.k] = b.vertices_m
    v[0, :, a.k :] = a.vertices_m[:, :1]
    v[1, :, b.k :] = b.vertices_m[:, :1]
    return v


def contact_pairs(a: ConvexPolygons, b: ConvexPolygons) -> Contact:
    """Penetration depth, MTV and distance of each matched pair (a[i], b[i]), in metres."""
    if not (isinstance(a, ConvexPolygons) and isinstance(b, ConvexPolygons)):
        raise GeometryError("contact_pairs: expected ConvexPolygons for a and b")
    if a.n != b.n:
        raise GeometryError(f"contact_pairs: {a.n} polygons in a but {b.n} in b")
    v = _stack(a, b)
    x, y = v[:, 0], v[:, 1]  # (side, K, N)
    ex = np.roll(x, -1, axis=1) - x
    ey = np.roll(y, -1, axis=1) - y
    length = np.sqrt(ex * ex + ey * ey)
    real = length > 0
    safe = np.where(real, length, 1.0)
    nx, ny = ey / safe, -ex / safe  # outward unit normals of side s
    top = nx * x + ny * y
    # gap of side s's edge i: min over the other side's vertices j of n_i . v_j - n_i . u_i
    ox, oy = x[::-1], y[::-1]
    low = (nx[:, :, None, :] * ox[:, None, :, :] + ny[:, :, None, :] * oy[:, None, :, :]).min(
        axis=2
    )
    gap = np.where(real, low - top, -np.inf)
    n_pairs = a.n
    flat = gap.transpose(2, 0, 1).reshape(n_pairs, -1)
    best = flat.argmax(axis=1)
    side, edge = np.divmod(best, gap.shape[1])
    cols = np.arange(n_pairs)
    best_gap = flat[cols, best]
    depth = np.maximum(-best_gap, 0.0)
    sign = np.where(side == 0, 1.0, -1.0)
    mtv = np.column_stack(
        [nx[side, edge, cols] * depth * sign, ny[side, edge, cols] * depth * sign]
    )
    distance = np.where(best_gap > 0, _distance(x, y, ex, ey), 0.0)
    return Contact(depth_m=depth, mtv_m=mtv, distance_m=distance, best_gap_m=best_gap)


def _distance(x: FloatArray, y: FloatArray, ex: FloatArray, ey: FloatArray) -> FloatArray:
    """Smallest vertex-to-edge distance between the two sides (valid for disjoint pairs)."""
    ox, oy = x[::-1], y[::-1]
    # point j of the other side against edge i of side s
    px = ox[:, None, :, :] - x[:, :, None, :]
    py = oy[:, None, :, :] - y[:, :, None, :]
    ee = (ex * ex + ey * ey)[:, :, None, :]
    t = np.clip(
        (px * ex[:, :, None, :] + py * ey[:, :, None, :]) / np.where(ee > 0, ee, 1.0), 0.0, 1.0
    )
    dx = px - t * ex[:, :, None, :]
    dy = py - t * ey[:, :, None, :]
    d2: FloatArray = (dx * dx + dy * dy).min(axis=(0, 1, 2))
    out: FloatArray = np.sqrt(d2)
    return out
