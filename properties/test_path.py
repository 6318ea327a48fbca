"""Free distance along the path never exceeds the truth (SR-RUN-3).

The governor's proof is about its input distance; :mod:`safety.geometry.path` must not hand it more
than is free. The oracle places the footprint on the continuous path (every 2 mm, and through every
heading at a corner, where the route pivots) and asks GEOS whether it touches the zone or holds a
loose point. A second check keeps the distance honest the other way: on a straight piece the
footprint does touch the zone within one sample step after the free distance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.config import SafecaseConfig
from safety.geometry.path import PathAhead, PathClearance
from safety.geometry.polygons import convex_polygons

CODE = ["safety/geometry/path.py"]
ORACLE_STEP_M = 0.002


def _footprint(clear: PathClearance, x: float, y: float, theta: float) -> shapely.Polygon:
    hl, hw = 0.5 * clear.length_m, 0.5 * clear.width_m
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    c, s = math.cos(theta), math.sin(theta)
    return shapely.Polygon(
        np.stack([x + c * local[:, 0] - s * local[:, 1], y + s * local[:, 0] + c * local[:, 1]], 1)
    )


def _poses_up_to(points: np.ndarray, start_m: float, until_m: float) -> list[tuple[float, ...]]:
    """Poses on the polyline from arc ``start_m`` to ``start_m + until_m`` every
    ``ORACLE_STEP_M``, plus every heading between the two segments at each corner passed."""
    seg = np.hypot(*np.diff(points, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    heads = np.arctan2(*np.diff(points, axis=0).T[::-1])
    stop = min(start_m + until_m, float(cum[-1]))
    out: list[tuple[float, ...]] = []
    for s in np.append(np.arange(start_m, stop, ORACLE_STEP_M), stop):
        k = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, seg.size - 1))
        f = (s - cum[k]) / seg[k]
        p = points[k] + f * (points[k + 1] - points[k])
        out.append((float(p[0]), float(p[1]), float(heads[k])))
    for k in range(1, seg.size):  # pivots at corners within the range
        if start_m < cum[k] < stop:
            turn = math.atan2(math.sin(heads[k] - heads[k - 1]), math.cos(heads[k] - heads[k - 1]))
            for f in np.linspace(0.0, 1.0, 17):
                out.append((float(points[k, 0]), float(points[k, 1]), heads[k - 1] + f * turn))
    return out


@st.composite
def scenes(draw: st.DrawFn) -> tuple[np.ndarray, float, list[np.ndarray], np.ndarray]:
    """A polyline route (2-4 points, straight pieces of 0.5-4 m), a start arc, zones (random
    convex hulls of 3-8 points, 0.05-2 m across, near the route) and loose points."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(2, 4))
    heading = rng.uniform(-math.pi, math.pi)
    points = [rng.uniform(-5, 5, 2)]
    for _ in range(n - 1):
        heading += rng.uniform(-1.5, 1.5) if rng.random() < 0.6 else 0.0
        length = rng.uniform(0.5, 4.0)
        points.append(points[-1] + length * np.array([math.cos(heading), math.sin(heading)]))
    route = np.array(points)
    start = float(rng.uniform(0.0, 0.5))
    zones = []
    for _ in range(draw(st.integers(1, 6))):
        k = int(rng.integers(len(route) - 1))
        centre = route[k] + rng.uniform(0, 1) * (route[k + 1] - route[k]) + rng.normal(0, 1.0, 2)
        size = rng.uniform(0.05, 2.0)
        zones.append(centre + rng.uniform(-0.5, 0.5, (int(rng.integers(3, 9)), 2)) * size)
    loose = route[0] + rng.uniform(-4, 8, (int(rng.integers(0, 40)), 2))
    return route, start, zones, loose


@pytest.mark.requirement("SR-RUN-3", kind="property", code=CODE)
@settings(max_examples=examples(60), deadline=None)
@given(scene=scenes())
def test_the_footprint_is_clear_up_to_the_free_distance(
    safecase_config: SafecaseConfig,
    scene: tuple[np.ndarray, float, list[np.ndarray], np.ndarray],
) -> None:
    route, start, zone_points, loose = scene
    rc = safecase_config.runtime
    clear = PathClearance(safecase_config.geometry)
    path = PathAhead.along_polyline(route, start, rc.path_lookahead_m, rc.path_step_m)
    zones = convex_polygons(zone_points)
    got = clear.free_distances(path, zones, loose[:, 0], loose[:, 1])
    shapes = [shapely.Polygon(zones.vertex_list(i)) for i in range(zones.n)]
    rec = current()
    for i, shape in enumerate(shapes):
        if got.zone_free_m[i] == 0.0:  # touching already: nothing is claimed free
            rec.count("zones", "touching at the start")
            continue
        poses = _poses_up_to(route, start, float(got.zone_free_m[i]))
        prints = [_footprint(clear, *p) for p in poses]
        touching = [shapely.intersects(fp, shape) for fp in prints]
        assert not any(touching), f"zone {i}: touched before its free distance"
        rec.count("zones", "on the path" if got.zone_hit[i] else "off the path")
        rec.count("footprints placed", "zones", len(prints))
    if loose.shape[0] and got.point_free_m > 0.0:
        poses = _poses_up_to(route, start, got.point_free_m)
        pts = shapely.points(loose[:, 0], loose[:, 1])
        for p in poses:
            inside = shapely.contains_properly(_footprint(clear, *p), pts)
            assert not inside.any(), f"a loose point inside the footprint before {got.point_free_m}"
        rec.count("loose points", "on the path" if got.n_points_on_path else "none on the path")


@pytest.mark.requirement("SR-RUN-3", kind="property", code=CODE)
@settings(max_examples=examples(60), deadline=None)
@given(
    offset=st.floats(-1.5, 1.5),
    ahead=st.floats(0.0, 5.0),
    size=st.floats(0.05, 1.0),
    angle=st.floats(-math.pi, math.pi),
)
def test_on_a_straight_path_the_zone_is_touched_within_one_step(
    safecase_config: SafecaseConfig, offset: float, ahead: float, size: float, angle: float
) -> None:
    """Not vacuous: a square ahead on a straight path is reached within one step of the free
    distance (the sampling is the only slack), and one beside the path is never reached."""
    rc = safecase_config.runtime
    clear = PathClearance(safecase_config.geometry)
    path = PathAhead.straight((0.0, 0.0, 0.0), rc.path_lookahead_m, rc.path_step_m)
    c, s = math.cos(angle), math.sin(angle)
    square = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * size / 2
    square = square @ np.array([[c, s], [-s, c]]) + np.array([ahead + 0.5, offset])
    got = clear.free_distances(path, convex_polygons([square]), np.zeros(0), np.zeros(0))
    shape = shapely.Polygon(square)
    route = np.array([[0.0, 0.0], [rc.path_lookahead_m, 0.0]])
    reach = _poses_up_to(route, 0.0, float(got.zone_free_m[0]) + rc.path_step_m + 1e-9)
    touched = any(shapely.intersects(_footprint(clear, *p), shape) for p in reach)
    if got.zone_hit[0]:
        assert touched, "a zone on the path is never touched near its free distance"
    else:
        far = _poses_up_to(route, 0.0, rc.path_lookahead_m)
        assert not any(shapely.intersects(_footprint(clear, *p), shape) for p in far)
    current().count("squares", "on the path" if got.zone_hit[0] else "beside or beyond")


@pytest.mark.requirement("SR-RUN-3", kind="cross-check", code=CODE)
@settings(max_examples=examples(100), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.sampled_from([0.01, 0.3, 1.0, 5.0]))
def test_distance_now_agrees_with_geos(
    safecase_config: SafecaseConfig, seed: int, scale: float
) -> None:
    rng = np.random.default_rng(seed)
    clear = PathClearance(safecase_config.geometry)
    pose = (float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3)))
    path = PathAhead.straight(pose, 2.0, 0.05)
    bodies = [
        pose[:2] + rng.normal(0, 2.0, 2) + rng.uniform(-1, 1, (6, 2)) * scale for _ in range(5)
    ]
    polys = convex_polygons(bodies)
    ours = clear.distances_now(path, polys)
    robot = _footprint(clear, *pose)
    geos = np.array(
        [shapely.distance(robot, shapely.Polygon(polys.vertex_list(i))) for i in range(polys.n)]
    )
    assert np.all(ours <= geos + 1e-9), (ours, geos)  # never more than the truth
    assert np.allclose(ours, geos, atol=1e-9 + 1e-12 * scale), (ours, geos)
    current().count("distances compared", "touching" if (geos == 0).any() else "apart", polys.n)
