"""A stored map of painted ground markings: straight stripes and arcs (SR-MRK-1, SR-MRK-3).

The map is the apron's marking plan in its own (map) frame: taxi lines, road edges and stop
bars as straight segments, stand lead-in curves as circular arcs, all painted ``width_m`` wide
(0.15 m taxi lines). It answers the two questions the simulator and the localisation ask: how
far a ground point is from the nearest marking's centre line (is it on paint?) and where the
nearest centre-line point is, with the line's unit normal there (point-to-line matching).
Every query is vectorised over points; segments and arcs are few (tens), so a points x
elements distance table is cheap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.errors import SafecaseError
from pipeline.types import FloatArray, IntArray, freeze_fields

__all__ = ["MarkingMap", "MarkingMapError", "Nearest"]


class MarkingMapError(SafecaseError, ValueError):
    """A marking map with bad geometry (non-finite, zero-length segments, non-positive radii)."""


@dataclass(frozen=True, slots=True)
class Nearest:
    """The nearest marking centre line of each query point: ``distance_m`` to it, the nearest
    centre-line point ``(x_m, y_m)``, the unit normal ``(nx, ny)`` there (pointing from the line
    towards the query point; any unit normal for a point on the line) and ``element``, the
    index of the element (segments first, then arcs)."""

    distance_m: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    nx: FloatArray
    ny: FloatArray
    element: IntArray


@dataclass(frozen=True, slots=True)
class MarkingMap:
    """Painted markings in the map frame [m].

    ``segments`` (S, 4): ``x0, y0, x1, y1`` of each straight stripe's centre line. ``arcs``
    (A, 5): ``cx, cy, radius_m, start_rad, sweep_rad`` (counter-clockwise from ``start_rad``
    when ``sweep_rad`` > 0). ``width_m``: the paint's width, the same for every marking.
    """

    segments: FloatArray
    arcs: FloatArray
    width_m: float = 0.15

    def __post_init__(self) -> None:
        freeze_fields(self, ("segments", "arcs"), np.float64)
        seg, arc = self.segments.reshape(-1, 4), self.arcs.reshape(-1, 5)
        object.__setattr__(self, "segments", seg)
        object.__setattr__(self, "arcs", arc)
        if not (np.isfinite(seg).all() and np.isfinite(arc).all()):
            raise MarkingMapError("MarkingMap: every coordinate must be finite")
        if seg.shape[0] and (np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) <= 0).any():
            raise MarkingMapError("MarkingMap: a segment has zero length")
        if arc.shape[0] and ((arc[:, 2] <= 0).any() or (arc[:, 4] == 0).any()):
            raise MarkingMapError("MarkingMap: an arc needs radius > 0 and a non-zero sweep")
        if not (0.0 < self.width_m < 5.0):
            raise MarkingMapError(f"MarkingMap: width_m must be in (0, 5), got {self.width_m}")
        if seg.shape[0] + arc.shape[0] == 0:
            raise MarkingMapError("MarkingMap: no markings")

    @property
    def n_elements(self) -> int:
        """Segments plus arcs."""
        return int(self.segments.shape[0] + self.arcs.shape[0])

    def nearest(self, x_m: FloatArray, y_m: FloatArray) -> Nearest:
        """The nearest centre line of every point (:class:`Nearest`)."""
        px, py = np.asarray(x_m, float)[:, None], np.asarray(y_m, float)[:, None]
        seg, arc = self.segments, self.arcs
        # Segments: clamp the projection onto the segment.
        x0, y0, x1, y1 = seg[:, 0], seg[:, 1], seg[:, 2], seg[:, 3]
        dx, dy = x1 - x0, y1 - y0
        t = np.clip(((px - x0) * dx + (py - y0) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
        sx, sy = x0 + t * dx, y0 + t * dy
        # Arcs: the radial projection when its angle lies in the sweep, else the nearer end.
        cx, cy, r, a0, sw = (arc[:, k] for k in range(5))
        lo = np.where(sw > 0, a0, a0 + sw)
        ang = np.arctan2(py - cy, px - cx)
        rel = np.mod(ang - lo, 2.0 * math.pi)
        inside = rel <= np.abs(sw)
        e0x, e0y = cx + r * np.cos(lo), cy + r * np.sin(lo)
        e1x, e1y = cx + r * np.cos(lo + np.abs(sw)), cy + r * np.sin(lo + np.abs(sw))
        d0 = np.hypot(px - e0x, py - e0y)
        d1 = np.hypot(px - e1x, py - e1y)
        endx = np.where(d0 <= d1, e0x, e1x)
        endy = np.where(d0 <= d1, e0y, e1y)
        ax = np.where(inside, cx + r * np.cos(ang), endx)
        ay = np.where(inside, cy + r * np.sin(ang), endy)
        qx = np.concatenate([sx, ax], axis=1)
        qy = np.concatenate([sy, ay], axis=1)
        dist = np.hypot(px - qx, py - qy)
        k = np.argmin(dist, axis=1)
        rows = np.arange(dist.shape[0])
        bx, by, bd = qx[rows, k], qy[rows, k], dist[rows, k]
        # The normal: along (point - nearest) when apart; on the line, the element's own normal.
        n_seg = seg.shape[0]
        is_seg = k < n_seg
        ks = np.minimum(k, max(n_seg - 1, 0))
        ka = np.maximum(k - n_seg, 0)
        if n_seg:
            length = np.hypot(dx[ks], dy[ks])
            own_x, own_y = -dy[ks] / length, dx[ks] / length
        else:
            own_x = own_y = np.zeros_like(bd)
        if arc.shape[0]:
            ra = np.maximum(np.hypot(bx - cx[ka], by - cy[ka]), 1e-12)
            arc_x, arc_y = (bx - cx[ka]) / ra, (by - cy[ka]) / ra
        else:
            arc_x = arc_y = np.zeros_like(bd)
        own_x, own_y = np.where(is_seg, own_x, arc_x), np.where(is_seg, own_y, arc_y)
        apart = bd > 1e-9
        safe = np.where(apart, bd, 1.0)
        nx = np.where(apart, (px[:, 0] - bx) / safe, own_x)
        ny = np.where(apart, (py[:, 0] - by) / safe, own_y)
        return Nearest(bd, bx, by, nx, ny, k.astype(np.int64))

    def distance_m(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Distance of every point to the nearest centre line [m]: :meth:`nearest`'s
        ``distance_m``, one element at a time (no points x elements table: the simulator asks
        this of every footprint sample)."""
        px, py = np.asarray(x_m, float), np.asarray(y_m, float)
        best = np.full(px.shape, np.inf)
        for x0, y0, x1, y1 in self.segments:
            dx, dy = x1 - x0, y1 - y0
            t = np.clip(((px - x0) * dx + (py - y0) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
            np.minimum(best, np.hypot(px - (x0 + t * dx), py - (y0 + t * dy)), out=best)
        for cx, cy, r, a0, sw in self.arcs:
            lo = a0 if sw > 0 else a0 + sw
            ang = np.arctan2(py - cy, px - cx)
            inside = np.mod(ang - lo, 2.0 * math.pi) <= abs(sw)
            radial = np.abs(np.hypot(px - cx, py - cy) - r)
            ends = np.minimum(
                np.hypot(px - cx - r * math.cos(lo), py - cy - r * math.sin(lo)),
                np.hypot(
                    px - cx - r * math.cos(lo + abs(sw)), py - cy - r * math.sin(lo + abs(sw))
                ),
            )
            np.minimum(best, np.where(inside, radial, ends), out=best)
        return best

    def on_paint(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Whether each point lies on paint (within half the width of a centre line), as 0/1."""
        return (self.distance_m(x_m, y_m) <= 0.5 * self.width_m).astype(np.float64)

    def sample(self, step_m: float) -> tuple[FloatArray, FloatArray]:
        """Points along every centre line, about ``step_m`` apart (ends included) [m]."""
        if not step_m > 0:
            raise MarkingMapError(f"MarkingMap.sample: step_m must be > 0, got {step_m}")
        xs: list[FloatArray] = []
        ys: list[FloatArray] = []
        for x0, y0, x1, y1 in self.segments:
            n = max(math.ceil(math.hypot(x1 - x0, y1 - y0) / step_m), 1) + 1
            t = np.linspace(0.0, 1.0, n)
            xs.append(x0 + t * (x1 - x0))
            ys.append(y0 + t * (y1 - y0))
        for cx, cy, r, a0, sw in self.arcs:
            n = max(math.ceil(abs(sw) * r / step_m), 1) + 1
            a = a0 + np.linspace(0.0, sw, n)
            xs.append(cx + r * np.cos(a))
            ys.append(cy + r * np.sin(a))
        return np.concatenate(xs), np.concatenate(ys)
