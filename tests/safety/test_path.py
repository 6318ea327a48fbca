"""Examples for the path clearance (SR-RUN-3): corners, loose points, bad paths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.config import default_config
from safety.geometry.path import PathAhead, PathClearance
from safety.geometry.polygons import GeometryError, NonFiniteGeometryError, convex_polygons

CONFIG = default_config()


@pytest.mark.requirement("SR-RUN-3", kind="example", code=["safety/geometry/path.py"])
def test_a_pivot_at_a_corner_sweeps_the_footprint_s_outer_corner() -> None:
    # A 90 deg left turn at (2, 0). Half way through the pivot, the robot's rear right corner
    # (0.45, -0.3) is at (2.53, 0.11): outside the footprint before and after the corner (and
    # outside their hull), inside the region the turning robot sweeps.
    clear = PathClearance(CONFIG.geometry)
    path = PathAhead.along_polyline(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0]]), 0.0, 6.0, 0.05)
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    corner = np.array([2.0 + 0.45 * c + 0.3 * s, 0.45 * s - 0.3 * c])
    speck = convex_polygons([corner + np.array([[-0.005, -0.005], [0.005, -0.005], [0.0, 0.005]])])
    got = clear.free_distances(path, speck, np.zeros(0), np.zeros(0))
    assert got.zone_hit[0]
    assert got.zone_free_m[0] <= 2.0
    loose = clear.free_distances(path, speck, corner[:1], corner[1:])
    assert loose.n_points_on_path == 1
    assert loose.point_free_m <= 2.0


@pytest.mark.requirement("SR-RUN-3", kind="example", code=["safety/geometry/path.py"])
def test_a_wall_of_loose_points_ahead_and_points_beside_the_path() -> None:
    clear = PathClearance(CONFIG.geometry)
    path = PathAhead.straight((0.0, 0.0, 0.0), 6.0, 0.05)
    wall_y = np.linspace(-2.0, 2.0, 401)
    x = np.concatenate([np.full(401, 3.0), np.linspace(-1, 5, 50)])
    y = np.concatenate([wall_y, np.full(50, 0.31)])  # a row just beside the 0.6 m wide robot
    got = clear.free_distances(path, convex_polygons(np.zeros((0, 3, 2))), x, y)
    # The robot's front is 0.45 m ahead of its centre: it may drive 2.55 m, sampled down.
    assert 2.5 <= got.point_free_m <= 2.55
    assert got.n_points_on_path == int(np.count_nonzero(np.abs(wall_y) <= 0.3 + 1e-9))


def test_bad_paths_are_refused_with_the_reason() -> None:
    with pytest.raises(NonFiniteGeometryError, match="finite"):
        PathAhead(np.array([0.0, 1.0]), np.array([0.0, np.nan]), np.zeros(2), np.zeros(2))
    with pytest.raises(GeometryError, match="increase strictly"):
        PathAhead(np.array([0.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2))
    with pytest.raises(GeometryError, match="lookahead_m"):
        PathAhead.straight((0.0, 0.0, 0.0), -1.0, 0.05)
    with pytest.raises(GeometryError, match="polyline"):
        PathAhead.along_polyline(np.array([[0.0, 0.0]]), 0.0, 5.0, 0.05)


def test_the_end_of_the_route_is_a_stub_and_a_short_route_ends_early() -> None:
    route = np.array([[0.0, 0.0], [1.0, 0.0]])
    assert PathAhead.along_polyline(route, 0.0, 6.0, 0.05).length_m == pytest.approx(1.0)
    stub = PathAhead.along_polyline(route, 5.0, 6.0, 0.05)
    assert stub.length_m == pytest.approx(0.05)
