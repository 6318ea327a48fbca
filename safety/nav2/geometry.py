"""How far a zone reaches beyond the robot's footprint, exactly (SR-NAV-1).

The footprint is the configured ``length x width`` rectangle centred on the base frame's origin
(x forward, y left), the project's footprint (``geometry.footprint_*_m``). Zones are polygons in
Nav2's even-odd reading (its ray-crossing point-in-polygon test) or circles centred on the origin.
Everything is computed in exact rationals; no square root is ever taken (circles are compared
through squares).

Two measures, each the quantity a stop zone must make at least the stopping separation:

* **Depth along the direction of travel** (:func:`axis_depth_m`). For straight travel forward
  (+x) or in reverse (-x), an obstacle point on the line at lateral offset ``s`` (``|s|``
  within the footprint's half-width) meets the
  footprint's leading edge. ``L(s)`` is the length of the contiguous stretch of that line, starting
  at the leading edge, that lies inside the zone: the point is inside the zone all the way from
  distance ``L(s)`` to contact. The depth is the infimum of ``L(s)`` over the footprint's
  extent; 0 when the zone does not reach the leading edge somewhere (an obstacle right there is
  never seen).
* **Clearance in every direction** (:func:`clearance_sq_m2`), for robots that may translate in
  any direction: the squared distance from the footprint to the zone's boundary when the zone
  contains the footprint (else 0). Every point within that distance of the footprint is inside
  the zone, and along any straight path the distance to contact is at least the Euclidean
  distance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from itertools import pairwise

__all__ = [
    "DIRECTIONS",
    "Footprint",
    "axis_depth_m",
    "clearance_sq_m2",
    "contains_footprint",
    "rotate_to",
]

Vertex = tuple[Fraction, Fraction]

# Straight travel along the base frame's x axis.
DIRECTIONS = ("forward", "reverse")


@dataclass(frozen=True, slots=True)
class Footprint:
    """A ``length_m x width_m`` rectangle centred on the base frame's origin, x forward."""

    length_m: Fraction
    width_m: Fraction

    def __post_init__(self) -> None:
        if not (self.length_m > 0 and self.width_m > 0):
            raise ValueError(
                f"footprint {self.length_m} m x {self.width_m} m: both sides must be > 0"
            )

    def ahead(self) -> tuple[Fraction, Fraction]:
        """(distance from the origin to the leading edge, half-width) [m], either way along x."""
        return self.length_m / 2, self.width_m / 2

    @property
    def half_diagonal_sq_m2(self) -> Fraction:
        """Squared distance from the origin to a corner [m^2]."""
        return (self.length_m / 2) ** 2 + (self.width_m / 2) ** 2


def rotate_to(direction: str, vertices: Sequence[Vertex]) -> list[Vertex]:
    """The vertices in a frame whose +x is ``direction`` (a half turn for reverse: exact)."""
    if direction not in DIRECTIONS:
        raise ValueError(f"direction = {direction!r}: allowed: {' | '.join(DIRECTIONS)}")
    if direction == "forward":
        return list(vertices)
    return [(-x, -y) for x, y in vertices]


def _edges(vertices: Sequence[Vertex]) -> list[tuple[Vertex, Vertex]]:
    return list(zip(vertices, [*vertices[1:], vertices[0]], strict=True))


def _x_at(edge: tuple[Vertex, Vertex], y: Fraction) -> Fraction:
    (x0, y0), (x1, y1) = edge
    return x0 + (y - y0) * (x1 - x0) / (y1 - y0)


def _breakpoints(
    edges: list[tuple[Vertex, Vertex]], front: Fraction, half: Fraction
) -> list[Fraction]:
    """Lateral offsets in ``[-half, half]`` where the picture along a line can change."""
    points = {-half, half}
    points.update(y for (_, y), _ in edges)
    for edge in edges:
        (x0, y0), (x1, y1) = edge
        if y0 != y1 and min(x0, x1) <= front <= max(x0, x1) and x0 != x1:
            points.add(y0 + (front - x0) * (y1 - y0) / (x1 - x0))
    # Crossing edges (a self-intersecting ring) reorder the crossings along the line.
    for i, (a, b) in enumerate(edges):
        for c, d in edges[i + 1 :]:
            crossing = _intersection_y(a, b, c, d)
            if crossing is not None:
                points.add(crossing)
    return sorted(p for p in points if -half <= p <= half)


def _intersection_y(a: Vertex, b: Vertex, c: Vertex, d: Vertex) -> Fraction | None:
    rx, ry = b[0] - a[0], b[1] - a[1]
    sx, sy = d[0] - c[0], d[1] - c[1]
    denominator = rx * sy - ry * sx
    if denominator == 0:
        return None
    t = ((c[0] - a[0]) * sy - (c[1] - a[1]) * sx) / denominator
    u = ((c[0] - a[0]) * ry - (c[1] - a[1]) * rx) / denominator
    if 0 <= t <= 1 and 0 <= u <= 1:
        return a[1] + t * ry
    return None


def axis_depth_m(vertices: Sequence[Vertex], footprint: Footprint, direction: str) -> Fraction:
    """Infimum over the footprint's extent of the covered stretch ahead of it [m] (exact).

    Between consecutive breakpoints (vertex offsets, where an edge crosses the leading edge,
    where two edges cross) the crossings keep their order, so the stretch ahead is bounded by
    one edge and is linear in the offset; its infimum over the open slab is the smaller of the
    edge's two end values.
    """
    front, half = footprint.ahead()
    edges = _edges(rotate_to(direction, vertices))
    depth: Fraction | None = None
    for low, high in pairwise(_breakpoints(edges, front, half)):
        middle = (low + high) / 2
        crossing = sorted(
            (_x_at(e, middle), i)
            for i, e in enumerate(edges)
            if min(e[0][1], e[1][1]) < middle < max(e[0][1], e[1][1])
        )
        # Even-odd: inside between crossings 0-1, 2-3, ...; find the stretch holding the front.
        bound = None
        for (x_in, _), (x_out, edge) in zip(crossing[0::2], crossing[1::2], strict=True):
            if x_in <= front <= x_out:
                bound = edges[edge]
                break
        if bound is None:
            return Fraction(0)
        slab = min(_x_at(bound, low), _x_at(bound, high)) - front
        depth = slab if depth is None else min(depth, slab)
    assert depth is not None  # a footprint's width is > 0: [-half, half] is one slab at least
    return max(depth, Fraction(0))


def _inside(vertices: Sequence[Vertex], point: Vertex) -> bool:
    """Even-odd ray crossing, as Nav2's ``Polygon::isPointInside`` (exact arithmetic)."""
    x, y = point
    inside = False
    for (x0, y0), (x1, y1) in _edges(vertices):
        if (y <= y0) == (y > y1) and x0 + (y - y0) * (x1 - x0) / (y1 - y0) > x:
            inside = not inside
    return inside


def _segment_meets_box(a: Vertex, b: Vertex, hx: Fraction, hy: Fraction) -> bool:
    """True when segment ab meets the open box ``|x| < hx, |y| < hy`` (Liang-Barsky, exact)."""
    t0, t1 = Fraction(0), Fraction(1)
    dx, dy = b[0] - a[0], b[1] - a[1]
    for p, q in ((-dx, a[0] + hx), (dx, hx - a[0]), (-dy, a[1] + hy), (dy, hy - a[1])):
        if p == 0:
            if q <= 0:
                return False
            continue
        r = q / p
        if p < 0:
            t0 = max(t0, r)
        else:
            t1 = min(t1, r)
    return t0 < t1


def contains_footprint(vertices: Sequence[Vertex], footprint: Footprint) -> bool:
    """True when the closed footprint rectangle lies inside the polygon (its boundary may touch)."""
    hx, hy = footprint.length_m / 2, footprint.width_m / 2
    if any(_segment_meets_box(a, b, hx, hy) for a, b in _edges(vertices)):
        return False
    return _inside(vertices, (Fraction(0), Fraction(0)))


def _point_segment_sq(p: Vertex, a: Vertex, b: Vertex) -> Fraction:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length_sq = dx * dx + dy * dy
    t = Fraction(0) if length_sq == 0 else ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length_sq
    t = min(max(t, Fraction(0)), Fraction(1))
    ex, ey = a[0] + t * dx - p[0], a[1] + t * dy - p[1]
    return ex * ex + ey * ey


def _point_box_sq(p: Vertex, hx: Fraction, hy: Fraction) -> Fraction:
    ex = max(abs(p[0]) - hx, Fraction(0))
    ey = max(abs(p[1]) - hy, Fraction(0))
    return ex * ex + ey * ey


def clearance_sq_m2(vertices: Sequence[Vertex], footprint: Footprint) -> Fraction:
    """Squared distance from the footprint to the polygon's boundary [m^2]; 0 if not inside.

    Neither the boundary's segments nor the rectangle cross, so each segment's distance to the
    rectangle is reached at one of the segment's ends or at a corner of the rectangle.
    """
    if not contains_footprint(vertices, footprint):
        return Fraction(0)
    hx, hy = footprint.length_m / 2, footprint.width_m / 2
    corners = [(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)]
    best: Fraction | None = None
    for a, b in _edges(vertices):
        candidates = [_point_box_sq(a, hx, hy), _point_box_sq(b, hx, hy)]
        candidates += [_point_segment_sq(c, a, b) for c in corners]
        edge_best = min(candidates)
        best = edge_best if best is None else min(best, edge_best)
    assert best is not None
    return best
