"""Reference implementations for the collision-geometry family (SR-SAT-*).

* python-fcl (FCL through its Python binding): convex prisms extruded from the polygons;
  ``collide`` (libccd GJK/EPA), penetration depth from its contact, ``distance``.
* shapely (GEOS): ``intersects`` of closed polygons, ``distance``.
* Exact arithmetic on the very same float coordinates (``fractions.Fraction``): the SAT
  verdict, its margin, penetration depth and separation distance, and a z3 linear real
  arithmetic query "is there a point in both polygons?" with its SMT-LIB text. These decide
  wherever the floating-point references disagree.

Nothing in the runtime imports this module.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from fractions import Fraction

import fcl
import numpy as np
import numpy.typing as npt
import shapely
import z3

from pipeline.types import ConvexPolygons, FloatArray

__all__ = [
    "ExactPair",
    "exact_pair",
    "exact_point_outside_sq",
    "fcl_collide",
    "fcl_distance",
    "fcl_object",
    "fcl_penetration",
    "shapely_polygons",
    "z3_common_point",
]


# ---------------------------------------------------------------------------------- FCL
def fcl_object(vertices: FloatArray, height_m: float) -> fcl.CollisionObject:
    """A convex prism over the (k, 2) counter-clockwise polygon, z in [-h/2, h/2]."""
    k = len(vertices)
    half = 0.5 * height_m
    verts = np.vstack(
        [
            np.column_stack([vertices, np.full(k, -half)]),
            np.column_stack([vertices, np.full(k, half)]),
        ]
    )
    faces = [k, *range(k - 1, -1, -1), k, *range(k, 2 * k)]
    for i in range(k):
        j = (i + 1) % k
        faces += [4, i, j, k + j, k + i]
    return fcl.CollisionObject(fcl.Convex(verts, 2 + k, faces), fcl.Transform())


def _prism_height(a: FloatArray, b: FloatArray) -> float:
    # Taller than any in-plane penetration, so FCL's reported depth is never the z overlap.
    span = max(np.ptp(a, axis=0).max(), np.ptp(b, axis=0).max())
    return float(4.0 * span + 1e-3)


def fcl_collide(a: FloatArray, b: FloatArray) -> bool:
    """FCL's overlap verdict for two (k, 2) polygons."""
    h = _prism_height(a, b)
    result = fcl.CollisionResult()
    fcl.collide(fcl_object(a, h), fcl_object(b, h), fcl.CollisionRequest(), result)
    return bool(result.is_collision)


def fcl_penetration(a: FloatArray, b: FloatArray) -> float | None:
    """FCL's penetration depth (metres) from its first contact; None when it sees none."""
    h = _prism_height(a, b)
    request = fcl.CollisionRequest(enable_contact=True, num_max_contacts=1)
    result = fcl.CollisionResult()
    fcl.collide(fcl_object(a, h), fcl_object(b, h), request, result)
    if not result.is_collision or not result.contacts:
        return None
    return float(result.contacts[0].penetration_depth)


def fcl_distance(a: FloatArray, b: FloatArray) -> float:
    """FCL's separation distance (metres); FCL reports -1 for colliding objects."""
    h = _prism_height(a, b)
    result = fcl.DistanceResult()
    return float(fcl.distance(fcl_object(a, h), fcl_object(b, h), fcl.DistanceRequest(), result))


# ------------------------------------------------------------------------------ shapely
def shapely_polygons(polygons: ConvexPolygons) -> npt.NDArray[np.object_]:
    """shapely Polygons for a batch (the padding repeats vertex 0: a closed ring)."""
    coords = np.ascontiguousarray(np.transpose(polygons.vertices_m, (2, 1, 0)))
    polys: npt.NDArray[np.object_] = shapely.polygons(coords)
    return polys


# ----------------------------------------------------------------------- exact arithmetic
def _q(vertices: FloatArray) -> list[tuple[Fraction, Fraction]]:
    return [(Fraction(float(x)), Fraction(float(y))) for x, y in vertices]


def _gaps(
    p: list[tuple[Fraction, Fraction]], q: list[tuple[Fraction, Fraction]]
) -> list[tuple[Fraction, Fraction, tuple[Fraction, Fraction]]]:
    """For each edge normal n of p (unnormalised, outward): (gap, |n|^2, n)."""
    out = []
    k = len(p)
    for i in range(k):
        (x0, y0), (x1, y1) = p[i], p[(i + 1) % k]
        nx, ny = y1 - y0, x0 - x1
        if nx == 0 and ny == 0:
            continue
        top = nx * x0 + ny * y0
        low = min(nx * x + ny * y for x, y in q)
        out.append((low - top, nx * nx + ny * ny, (nx, ny)))
    return out


def _seg_dist_sq(
    p: tuple[Fraction, Fraction], a: tuple[Fraction, Fraction], b: tuple[Fraction, Fraction]
) -> Fraction:
    ex, ey = b[0] - a[0], b[1] - a[1]
    px, py = p[0] - a[0], p[1] - a[1]
    den = ex * ex + ey * ey
    t = Fraction(0) if den == 0 else min(max((px * ex + py * ey) / den, Fraction(0)), Fraction(1))
    dx, dy = px - t * ex, py - t * ey
    return dx * dx + dy * dy


@dataclass(frozen=True)
class ExactPair:
    """Exact facts about two polygons given by float vertices (evaluated as rationals).

    ``overlap``: they share a point (touching counts). ``margin_sq_signed``: the largest
    separation along an edge normal, squared with its sign (positive: separated along that
    axis). ``distance_sq``: squared Euclidean distance (0 when overlapping).
    ``penetration_sq``: squared penetration depth (0 when disjoint). ``mtv_axis``: the edge
    normal giving the penetration (unnormalised).
    """

    overlap: bool
    margin_sq_signed: Fraction
    distance_sq: Fraction
    penetration_sq: Fraction

    def margin_m(self) -> float:
        """The SAT margin in metres (negative: overlap depth along the best axis)."""
        value = math.sqrt(float(abs(self.margin_sq_signed)))
        return value if self.margin_sq_signed >= 0 else -value

    def distance_m(self) -> float:
        """Euclidean distance in metres, correctly rounded from the exact square."""
        return math.sqrt(float(self.distance_sq))

    def penetration_m(self) -> float:
        """Penetration depth in metres."""
        return math.sqrt(float(self.penetration_sq))


def exact_pair(a: FloatArray, b: FloatArray) -> ExactPair:
    """Exact SAT over all edge normals of both (k, 2) counter-clockwise polygons."""
    p, q = _q(a), _q(b)
    gaps = _gaps(p, q) + _gaps(q, p)
    best = max(gaps, key=lambda g: (g[0] > 0, g[0] * abs(g[0]) / g[1]))
    gap, norm_sq, _ = best
    signed = gap * abs(gap) / norm_sq
    overlap = all(g[0] <= 0 for g in gaps)
    if overlap:
        depth_sq = min(g[0] * g[0] / g[1] for g in gaps)
        return ExactPair(True, signed, Fraction(0), depth_sq)
    dist = min(
        min(_seg_dist_sq(v, p[i], p[(i + 1) % len(p)]) for v in q for i in range(len(p))),
        min(_seg_dist_sq(v, q[i], q[(i + 1) % len(q)]) for v in p for i in range(len(q))),
    )
    return ExactPair(False, signed, dist, Fraction(0))


def exact_point_outside_sq(point: tuple[float, float], polygon: FloatArray) -> Fraction:
    """Squared Euclidean distance from a point to a counter-clockwise polygon (0 inside)."""
    p = (Fraction(point[0]), Fraction(point[1]))
    q = _q(polygon)
    k = len(q)
    inside = True
    for i in range(k):
        (x0, y0), (x1, y1) = q[i], q[(i + 1) % k]
        if (x1 - x0) * (p[1] - y0) - (y1 - y0) * (p[0] - x0) < 0:
            inside = False
            break
    if inside:
        return Fraction(0)
    return min(_seg_dist_sq(p, q[i], q[(i + 1) % k]) for i in range(k))


# ------------------------------------------------------------------------------------ z3
@dataclass(frozen=True)
class SmtResult:
    """A z3 decision with the SMT-LIB text that reproduces it."""

    common_point: bool
    smtlib: str
    model: dict[str, Fraction]
    time_s: float
    solver: str


def _halfplanes(vertices: FloatArray, x: z3.ArithRef, y: z3.ArithRef) -> list[z3.BoolRef]:
    q = _q(vertices)
    k = len(q)
    out = []
    for i in range(k):
        (x0, y0), (x1, y1) = q[i], q[(i + 1) % k]
        # left of (or on) edge i: (x1-x0)(y-y0) - (y1-y0)(x-x0) >= 0, over the reals
        out.append((x1 - x0) * (y - y0) - (y1 - y0) * (x - x0) >= 0)
    return out


def z3_common_point(a: FloatArray, b: FloatArray) -> SmtResult:
    """Linear real arithmetic: does a point (x, y) lie in both closed polygons?"""
    x, y = z3.Reals("x y")
    solver = z3.Solver()
    solver.set("random_seed", 0)
    solver.add(*_halfplanes(a, x, y), *_halfplanes(b, x, y))
    smtlib = "(set-logic QF_LRA)\n" + solver.to_smt2()
    start = time.perf_counter()
    verdict = solver.check()
    elapsed = time.perf_counter() - start
    if verdict == z3.unknown:
        raise RuntimeError("z3 returned unknown on a linear real arithmetic query")
    model: dict[str, Fraction] = {}
    if verdict == z3.sat:
        m = solver.model()
        for var in (x, y):
            value = m.eval(var, model_completion=True)
            model[str(var)] = Fraction(value.as_fraction())
    return SmtResult(verdict == z3.sat, smtlib, model, elapsed, f"z3 {z3.get_version_string()}")
