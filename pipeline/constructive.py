"""Convex regions built from primitives, vectorised over rows: discs, sectors, Minkowski sums.

Every function returns vertex lists ``(n, K, 2)`` whose convex hull contains the region it
stands for (a disc is replaced by a circumscribed regular polygon, an arc by tangent lines), so
a region built here never covers less than its ideal shape (SR-PRED-1). Read by prediction
(reach regions) and by the safety side (envelopes, zones, the path's bodies).
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.types import FloatArray

__all__ = ["disc_points", "minkowski", "sector_points"]


def disc_points(cx: FloatArray, cy: FloatArray, radius: FloatArray, sides: int) -> FloatArray:
    """(n, sides, 2) vertices of regular polygons circumscribing the discs (contain them)."""
    angle = (np.arange(sides) + 0.5) * (2.0 * math.pi / sides)
    outer = radius / math.cos(math.pi / sides)
    out = np.empty((cx.shape[0], sides, 2))
    out[:, :, 0] = cx[:, None] + outer[:, None] * np.cos(angle)[None, :]
    out[:, :, 1] = cy[:, None] + outer[:, None] * np.sin(angle)[None, :]
    return out


def sector_points(
    cx: FloatArray,
    cy: FloatArray,
    heading_rad: FloatArray,
    half_angle_rad: FloatArray,
    radius_m: FloatArray,
    arc_step_rad: float,
    disc_sides: int,
) -> FloatArray:
    """(n, P, 2) points whose hull contains each circular sector (apex, heading, half-angle).

    The arc is split into ``m = ceil(2 alpha / arc_step_rad)`` equal pieces and replaced by the
    tangent lines at the piece ends (they meet at radius ``R / cos(piece / 2)``), so the
    polygon contains the sector. A half-angle of 90 deg or more, or a NaN heading, gives the
    disc of radius ``R`` (:func:`disc_points`); rows with fewer points repeat the apex.
    """
    n = cx.shape[0]
    disc = ~np.isfinite(heading_rad) | (half_angle_rad >= 0.5 * math.pi)
    alpha = np.where(disc, 0.0, np.clip(half_angle_rad, 0.0, 0.5 * math.pi))
    pieces = np.maximum(np.ceil(2.0 * alpha / arc_step_rad).astype(np.int64), 1)
    most = int(pieces.max(initial=1))
    width = max(most + 3, disc_sides)
    out = np.empty((n, width, 2))
    out[:, :, 0] = cx[:, None]
    out[:, :, 1] = cy[:, None]
    h = np.where(disc, 0.0, heading_rad)
    step = 2.0 * alpha / pieces
    start = h - alpha
    out[:, 1, 0] = cx + radius_m * np.cos(start)
    out[:, 1, 1] = cy + radius_m * np.sin(start)
    k = np.arange(most)[None, :]
    mid = start[:, None] + (k + 0.5) * step[:, None]
    outer = (radius_m / np.cos(0.5 * step))[:, None]
    used = k < pieces[:, None]
    out[:, 2 : 2 + most, 0] = np.where(used, cx[:, None] + outer * np.cos(mid), cx[:, None])
    out[:, 2 : 2 + most, 1] = np.where(used, cy[:, None] + outer * np.sin(mid), cy[:, None])
    end = h + alpha
    last = 2 + pieces
    rows = np.arange(n)
    out[rows, last, 0] = cx + radius_m * np.cos(end)
    out[rows, last, 1] = cy + radius_m * np.sin(end)
    if disc.any():
        ring = disc_points(cx[disc], cy[disc], radius_m[disc], disc_sides)
        out[disc] = np.concatenate(
            [ring, np.repeat(ring[:, :1], width - disc_sides, axis=1)], axis=1
        )
    return out


def minkowski(a: FloatArray, b: FloatArray) -> FloatArray:
    """Minkowski sums of convex polygons, row by row: (n, Ka + Kb, 2) counter-clockwise vertices.

    ``a`` (n, Ka, 2) and ``b`` (n, Kb, 2) list each row's vertices counter-clockwise; repeated
    points (padding) and degenerate rows (a point, a segment traversed there and back) are
    fine. The sum's edges are the two polygons' edges merged by angle, starting from the sum
    of their lowest (then leftmost) vertices; zero-length edges add nothing. The result may
    hold repeated and collinear points (its hull is the sum).
    """
    n = a.shape[0]
    start = _lowest(a) + _lowest(b)
    edges = np.concatenate([np.roll(a, -1, axis=1) - a, np.roll(b, -1, axis=1) - b], axis=1)
    angle = np.mod(np.arctan2(edges[:, :, 1], edges[:, :, 0]), 2.0 * math.pi)
    order = np.argsort(angle, axis=1, kind="stable")
    ordered = np.take_along_axis(edges, order[:, :, None], axis=1)
    out = np.empty((n, edges.shape[1], 2))
    out[:, 0] = start
    out[:, 1:] = start[:, None, :] + np.cumsum(ordered[:, :-1], axis=1)
    return out


def _lowest(p: FloatArray) -> FloatArray:
    """(n, 2): each row's lowest point, the leftmost of those at the lowest y."""
    y = p[:, :, 1]
    at_min = y == y.min(axis=1, keepdims=True)
    pick = np.where(at_min, p[:, :, 0], np.inf).argmin(axis=1)
    lowest: FloatArray = p[np.arange(p.shape[0]), pick]
    return lowest
