"""Grid costmap of obstacle envelopes, rasterized conservatively (SR-PRED-2).

The grid (``costmap`` section) has square cells of ``resolution_m`` (0.05 m by default) over
``width_m`` x ``height_m`` centred on (``centre_x_m``, ``centre_y_m``) in the envelopes' frame.
Cell ``(i, j)`` (row ``i`` along y, column ``j`` along x) is the closed box
``[x0 + j r, x0 + (j + 1) r] x [y0 + i r, y0 + (i + 1) r]``.

A cell is marked when it touches an envelope (shares at least one point with the closed
polygon). For a convex polygon this is exact by slabs: within the horizontal slab of grid row
``i``, the polygon's part is convex, so a cell of that row touches the polygon exactly when its
x-interval meets the x-extent of the polygon's part of the slab, which is spanned by the
polygon's vertices inside the slab and its edges' crossings of the slab's two lines. The
extents are widened by ``contact_tolerance_m`` so that rounding can only add cells, never drop
one: every cell that touches an envelope is marked (checked against shapely's ``intersects``).
Envelopes reaching beyond the grid are clipped to it and counted (``n_clipped``). All
(polygon, grid row) pairs are handled in one vectorised pass; no loop over polygons or cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import CostmapSection
from pipeline.types import BoolArray, ConvexPolygons, FloatArray, IntArray, frozen_array

__all__ = ["Costmap", "CostmapBuilder"]


@dataclass(frozen=True, slots=True)
class Costmap:
    """Marked cells (``occupied`` (rows, cols), row i along y) and the grid's placement.

    ``n_clipped`` counts the envelopes that reach past the grid's edge (or lie outside it).
    """

    occupied: BoolArray
    origin_x_m: float
    origin_y_m: float
    resolution_m: float
    n_clipped: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "occupied", frozen_array(self.occupied, np.bool_))
        if self.occupied.ndim != 2:
            raise ValueError("Costmap: occupied must be a 2-D array")

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return (int(self.occupied.shape[0]), int(self.occupied.shape[1]))

    def cell_bounds(self, i: IntArray, j: IntArray) -> FloatArray:
        """(n, 4) boxes ``[x_min, y_min, x_max, y_max]`` of cells (i, j) in metres."""
        r = self.resolution_m
        x0 = self.origin_x_m + np.asarray(j) * r
        y0 = self.origin_y_m + np.asarray(i) * r
        return np.stack([x0, y0, x0 + r, y0 + r], axis=-1)


class CostmapBuilder:
    """Rasterizes envelopes into the configured grid (SR-PRED-2). Holds the grid buffers."""

    def __init__(self, section: CostmapSection) -> None:
        self.section = section
        r = section.resolution_m
        self.cols = max(1, math.ceil(section.width_m / r - 1e-9))
        self.rows = max(1, math.ceil(section.height_m / r - 1e-9))
        self.origin_x_m = section.centre_x_m - 0.5 * self.cols * r
        self.origin_y_m = section.centre_y_m - 0.5 * self.rows * r

    def rasterize(self, polygons: ConvexPolygons) -> Costmap:
        """The costmap of ``polygons`` (every cell touching one is marked).

        Vectorised over all (polygon, grid row) pairs inside the polygons' bounding boxes.
        """
        r, tol = self.section.resolution_m, self.section.contact_tolerance_m
        x0, y0 = self.origin_x_m, self.origin_y_m
        rows, cols = self.rows, self.cols
        occupied = np.zeros((rows, cols), dtype=np.bool_)
        if polygons.n == 0:
            return Costmap(occupied, x0, y0, r, 0)
        v = polygons.vertices_m  # (2, K, N)
        lo, hi = v.min(axis=1) - tol, v.max(axis=1) + tol  # (2, N)
        # The first closed cell reaching ``lo`` is ceil - 1, not floor: on a grid line the cell
        # below (left of) it touches too, which zero tolerance would otherwise drop.
        i_lo = np.ceil((lo[1] - y0) / r).astype(np.int64) - 1
        i_hi = np.floor((hi[1] - y0) / r).astype(np.int64)
        j_lo = np.ceil((lo[0] - x0) / r).astype(np.int64) - 1
        j_hi = np.floor((hi[0] - x0) / r).astype(np.int64)
        clipped = int(np.count_nonzero((i_lo < 0) | (j_lo < 0) | (i_hi >= rows) | (j_hi >= cols)))
        i_lo, i_hi = np.maximum(i_lo, 0), np.minimum(i_hi, rows - 1)
        visible = (i_lo <= i_hi) & (np.maximum(j_lo, 0) <= np.minimum(j_hi, cols - 1))
        span = np.where(visible, i_hi - i_lo + 1, 0)
        poly = np.repeat(np.arange(polygons.n), span)  # one entry per (polygon, grid row)
        if poly.size == 0:
            return Costmap(occupied, x0, y0, r, clipped)
        first = np.cumsum(span) - span
        row = i_lo[poly] + np.arange(poly.size) - first[poly]
        xmin, xmax = _slab_extents(
            v[0].T[poly], v[1].T[poly], y0 + r * row.astype(np.float64), r, tol
        )
        some = np.isfinite(xmin) & np.isfinite(xmax)
        c_lo = np.ceil((np.where(some, xmin, x0) - tol - x0) / r).astype(np.int64) - 1
        c_hi = np.floor((np.where(some, xmax, x0) + tol - x0) / r).astype(np.int64)
        c_lo, c_hi = np.maximum(c_lo, 0), np.minimum(c_hi, cols - 1)
        keep = some & (c_lo <= c_hi)
        # Mark column ranges through a difference array over the grid rows touched: +1 at the
        # start, -1 past the end (bincount, not np.add.at, which is several times slower).
        touched, local = np.unique(row[keep], return_inverse=True)
        width = cols + 1
        size = touched.size * width
        start = local * width + c_lo[keep]
        diff = np.bincount(start, minlength=size) - np.bincount(
            start + (c_hi[keep] - c_lo[keep] + 1), minlength=size
        )
        occupied[touched] = np.cumsum(diff.reshape(touched.size, width)[:, :cols], axis=1) > 0
        return Costmap(occupied, x0, y0, r, clipped)


def _slab_extents(
    vx: FloatArray, vy: FloatArray, bottom_y: FloatArray, height: float, tol: float
) -> tuple[FloatArray, FloatArray]:
    """Per entry: the x-extent of polygon (vx, vy) (m, K) within the horizontal slab
    ``[bottom_y, bottom_y + height]`` (m,), each widened by ``tol``; +/-inf when empty."""
    ax, ay = vx, vy
    bx, by = np.roll(vx, -1, axis=1), np.roll(vy, -1, axis=1)
    low, high = np.minimum(ay, by), np.maximum(ay, by)
    dy = by - ay
    flat = dy == 0.0
    safe_dy = np.where(flat, 1.0, dy)
    xmin = np.full(vx.shape[0], np.inf)
    xmax = np.full(vx.shape[0], -np.inf)
    for line in (bottom_y, bottom_y + height):
        y = line[:, None]
        crosses = (y >= low - tol) & (y <= high + tol)
        t = np.clip((y - ay) / safe_dy, 0.0, 1.0)
        x_at = ax + t * (bx - ax)
        # A horizontal edge on the line contributes both of its ends.
        x_lo = np.where(flat, np.minimum(ax, bx), x_at)
        x_hi = np.where(flat, np.maximum(ax, bx), x_at)
        xmin = np.minimum(xmin, np.where(crosses, x_lo, np.inf).min(axis=1))
        xmax = np.maximum(xmax, np.where(crosses, x_hi, -np.inf).max(axis=1))
    inside = (vy >= bottom_y[:, None] - tol) & (vy <= bottom_y[:, None] + height + tol)
    xmin = np.minimum(xmin, np.where(inside, vx, np.inf).min(axis=1))
    xmax = np.maximum(xmax, np.where(inside, vx, -np.inf).max(axis=1))
    return xmin, xmax
