"""Independent references for the simulator (SR-SIM-*): GEOS through shapely.

Nothing here shares code with ``pipeline.sources.sim`` beyond reading its data: the rays are shapely
line strings, the scene is the union of the polygons' boundaries as GEOS sees them, and the
first hit is GEOS's distance from the ray's origin to the ray-scene intersection.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import shapely

from pipeline.types import FloatArray

__all__ = [
    "first_hits",
    "first_hits_per_ray",
    "footprint_distances",
    "overlaps_any",
    "vertex_touch",
]


def _boundaries(polygons: Sequence[FloatArray]) -> shapely.Geometry:
    rings = [shapely.LinearRing(np.asarray(p, dtype=np.float64)) for p in polygons]
    return shapely.MultiLineString([np.asarray(r.coords) for r in rings])


def _ranges(origins: FloatArray, dirs: FloatArray, max_range_m: float, scene: object) -> FloatArray:
    ends = origins + max_range_m * dirs
    coords = np.stack([origins, ends], axis=1)  # (B, 2, 2)
    rays = shapely.linestrings(coords)
    hits = shapely.intersection(rays, scene)
    dist = shapely.distance(shapely.points(origins), hits)
    empty = shapely.is_empty(hits)
    out: FloatArray = np.where(empty, np.inf, dist)
    return out


def first_hits(
    origin: FloatArray, angles_rad: FloatArray, max_range_m: float, polygons: Sequence[FloatArray]
) -> FloatArray:
    """Range of the first intersection of each ray from ``origin`` (world angles
    ``angles_rad``) with the boundaries of ``polygons``; ``inf`` when none within range."""
    if not polygons:
        return np.full(angles_rad.shape, np.inf)
    dirs = np.stack([np.cos(angles_rad), np.sin(angles_rad)], axis=1)
    origins = np.broadcast_to(np.asarray(origin, dtype=np.float64), dirs.shape)
    return _ranges(np.ascontiguousarray(origins), dirs, max_range_m, _boundaries(polygons))


def first_hits_per_ray(
    origins: FloatArray,
    angles_rad: FloatArray,
    max_range_m: float,
    polygons_per_ray: Sequence[Sequence[FloatArray]],
) -> FloatArray:
    """Like :func:`first_hits`, but every ray has its own origin and its own scene (a
    time-skewed scan, where each beam sees the world at its own instant)."""
    out = np.empty(angles_rad.shape)
    dirs = np.stack([np.cos(angles_rad), np.sin(angles_rad)], axis=1)
    for i, polys in enumerate(polygons_per_ray):
        if not polys:
            out[i] = np.inf
            continue
        scene = _boundaries(polys)
        out[i] = _ranges(origins[i : i + 1], dirs[i : i + 1], max_range_m, scene)[0]
    return out


def footprint_distances(
    footprint: FloatArray, objects: Sequence[Sequence[FloatArray]]
) -> FloatArray:
    """GEOS distance from a polygon to each object (a union of polygons), 0 on contact."""
    fp = shapely.Polygon(footprint)
    return np.array(
        [shapely.distance(fp, shapely.union_all(_polygons(parts))) for parts in objects]
    )


def _polygons(polygons: Sequence[FloatArray]) -> list[shapely.Geometry]:
    """Shapely polygons, built in vectorized groups of equal vertex count."""
    groups: dict[int, list[int]] = {}
    for i, p in enumerate(polygons):
        groups.setdefault(len(p), []).append(i)
    out: list[shapely.Geometry] = [None] * len(polygons)
    for idx in groups.values():
        made = shapely.polygons(np.stack([np.asarray(polygons[i], dtype=np.float64) for i in idx]))
        for i, g in zip(idx, made, strict=True):
            out[i] = g
    return out


def overlaps_any(polygons: Sequence[FloatArray], structure: Sequence[FloatArray]) -> bool:
    """Whether any of ``polygons`` intersects (touches or overlaps) any structure polygon."""
    if not polygons or not structure:
        return False
    region = shapely.union_all(_polygons(structure))
    shapely.prepare(region)
    return bool(np.any(shapely.intersects(region, np.array(_polygons(polygons), dtype=object))))


def vertex_touch(
    origin: FloatArray, angle_rad: float, vertices: FloatArray, ranges_m: Sequence[float]
) -> bool:
    """Whether the ray passes within 1e-9 m of a vertex lying at one of ``ranges_m`` along it.

    A ray through a polygon's corner that does not enter it is a tangent: a measure-zero
    event whose "hit" two correct implementations may round either way (GEOS itself reports
    some and misses others). The cross-check accepts either answer there and counts it.
    """
    d = np.array([np.cos(angle_rad), np.sin(angle_rad)])
    rel = vertices - origin
    along = rel @ d
    perp = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])
    near = (perp <= 1e-9) & (along >= 0)
    return any(bool(np.any(np.abs(along[near] - r) <= 1e-9)) for r in ranges_m if np.isfinite(r))
