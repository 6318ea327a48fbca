"""The hull's rounding slack from its sharpest vertex, the empty batch, quick-reject data and
rigid motions in double precision (SR-SAT-1, SR-SAT-3)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from pipeline.errors import DegeneratePolygonError, GeometryError
from safety.geometry.polygons import (
    HULL_HALFPLANE,
    convex_hull_batch,
    convex_polygons,
    no_polygons,
    polygon_bounds,
    transform_polygons,
)

CODE = ["safety/geometry/polygons.py"]
TRIANGLE = np.array([[0.0, 0.0], [4.0, 1.0], [1.0, 3.0]])


def _interior_angles(corners: np.ndarray) -> list[float]:
    """Each corner's interior angle [rad], from the directions to its two neighbours."""
    out = []
    for k in range(len(corners)):
        a, b = corners[k - 1] - corners[k], corners[(k + 1) % len(corners)] - corners[k]
        turn = math.atan2(b[1], b[0]) - math.atan2(a[1], a[0])
        out.append(abs(math.remainder(turn, 2 * math.pi)))
    return out


@pytest.mark.requirement("SR-SAT-3", kind="example", code=CODE)
def test_a_point_on_an_edge_gives_the_slack_of_the_sharpest_vertex() -> None:
    """A triangle with the midpoint of one edge among its points: that point is dropped without
    being certainly inside, so the set gets slack HULL_HALFPLANE * magnitude / sin(alpha / 2)
    for its smallest interior angle alpha (module docstring), and no rounding warning."""
    points = np.vstack([TRIANGLE, 0.5 * (TRIANGLE[0] + TRIANGLE[1])])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        order, counts, slack = convex_hull_batch(points[None, :, 0], points[None, :, 1])
    assert counts.tolist() == [3]
    assert sorted(order[0, :3].tolist()) == [0, 1, 2]
    sharpest = min(_interior_angles(TRIANGLE))
    expected = HULL_HALFPLANE * 4.0 / math.sin(0.5 * sharpest)
    assert slack[0] == pytest.approx(expected, rel=1e-9, abs=0.0)
    inside = convex_hull_batch(TRIANGLE[None, :, 0], TRIANGLE[None, :, 1])[2]
    assert inside.tolist() == [0.0]


@pytest.mark.requirement("SR-SAT-3", kind="example", code=CODE)
def test_padded_sets_of_different_sizes_give_no_rounding_warning() -> None:
    """Sets padded to one width (a repeated point) beside a set with a point on an edge: the
    padding's zero-length edges are left out of the slack without a division warning."""
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [1.0, 0.0]])
    small = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    xs = np.stack([square[:, 0], small[:, 0]])
    ys = np.stack([square[:, 1], small[:, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, counts, slack = convex_hull_batch(xs, ys)
    assert counts.tolist() == [4, 3]
    assert slack[0] == pytest.approx(
        HULL_HALFPLANE * 2.0 / math.sin(math.pi / 4), rel=1e-9, abs=0.0
    )
    assert slack[1] == 0.0


@pytest.mark.requirement("SR-SAT-1", kind="example", code=CODE)
def test_the_empty_batch_has_the_least_polygon_width_and_integer_counts() -> None:
    empty = no_polygons()
    assert empty.n == 0
    assert empty.vertices_m.shape == (2, 3, 0)
    assert empty.counts.dtype == np.int64


@pytest.mark.requirement("SR-SAT-1", kind="example", code=CODE)
def test_the_quick_reject_pack_is_centre_magnitude_and_slack() -> None:
    polygons = convex_polygons(np.array([TRIANGLE, TRIANGLE + 10.0]))
    bounds = polygon_bounds(polygons)
    assert bounds.pack.shape == (4, 2)
    np.testing.assert_array_equal(bounds.pack[0], [2.0, 12.0])
    np.testing.assert_array_equal(bounds.pack[1], [1.5, 11.5])
    np.testing.assert_array_equal(bounds.pack[2], [4.0, 14.0])
    np.testing.assert_array_equal(bounds.pack[3], polygons.slack_m)


@pytest.mark.requirement("SR-SAT-1", kind="example", code=CODE)
def test_a_pose_given_in_single_precision_is_applied_in_double() -> None:
    """A float32 pose is widened to float64 before the rotation: the result equals the one of
    the same values given as Python floats."""
    polygons = convex_polygons(TRIANGLE[None])
    pose32 = (np.float32(0.3), np.float32(-1.7), np.float32(0.7))
    moved32 = transform_polygons(polygons, *pose32)
    moved64 = transform_polygons(polygons, *(float(v) for v in pose32))
    np.testing.assert_array_equal(moved32.vertices_m, moved64.vertices_m)
    assert moved32.vertices_m.dtype == np.float64


@pytest.mark.requirement("SR-SAT-3", kind="example", code=CODE)
def test_points_in_single_precision_are_hulled_in_double() -> None:
    """float32 coordinates give the hull and slack of the same values as float64 (the
    orientation tests are made in double precision)."""
    points = np.vstack([TRIANGLE, 0.5 * (TRIANGLE[0] + TRIANGLE[1])]) + 0.1
    single = points.astype(np.float32)
    wide = single.astype(np.float64)
    got = convex_hull_batch(single[None, :, 0], single[None, :, 1])
    want = convex_hull_batch(wide[None, :, 0], wide[None, :, 1])
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    assert got[2].dtype == np.float64
    assert got[2][0] > 0.0


@pytest.mark.requirement("SR-SAT-3", kind="example", code=CODE)
def test_a_set_of_one_point_is_degenerate_and_named_with_its_point() -> None:
    with pytest.raises(DegeneratePolygonError) as caught:
        convex_hull_batch(np.array([[0.0], [1.5]]), np.array([[0.0], [-2.0]]), what="body")
    assert str(caught.value) == (
        "body 0: all points coincide at (0.0, 0.0); a polygon needs at least 3 distinct points"
    )


@pytest.mark.requirement("SR-SAT-3", kind="example", code=CODE)
def test_a_point_outside_by_less_than_rounding_is_covered_by_slack_not_made_a_vertex() -> None:
    """Far from the origin (magnitude 1010 m) a point one ulp outside the middle of a
    diamond's edge is within that edge's rounding threshold (which grows with the magnitude):
    it is not made a vertex, and the diamond gets slack that holds it."""
    mid = float(np.nextafter(1002.5, -np.inf))  # one ulp outside the lower-left edge
    xs = np.array([[1000.0, 1005.0, 1010.0, 1005.0, mid]])
    ys = np.array([[1005.0, 1000.0, 1005.0, 1010.0, mid]])
    order, counts, slack = convex_hull_batch(xs, ys)
    assert counts.tolist() == [4]
    assert 4 not in order[0].tolist()
    outside_m = (2 * 1002.5 - 2 * mid) / math.sqrt(2.0)  # distance beyond the edge x + y = 2005
    assert slack[0] >= outside_m > 0.0


@pytest.mark.requirement("SR-SAT-3", kind="example", code=CODE)
def test_a_point_inside_by_less_than_rounding_is_covered_by_slack() -> None:
    """A point one ulp inside the middle of the same diamond's edge is not certainly inside
    (within half the edge's rounding threshold): the diamond gets slack for it."""
    mid = float(np.nextafter(1002.5, np.inf))
    xs = np.array([[1000.0, 1005.0, 1010.0, 1005.0, mid]])
    ys = np.array([[1005.0, 1000.0, 1005.0, 1010.0, mid]])
    _, counts, slack = convex_hull_batch(xs, ys)
    assert counts.tolist() == [4]
    assert slack[0] > 0.0
    clear = convex_hull_batch(xs[:, :4], ys[:, :4])[2]
    assert clear.tolist() == [0.0]


@pytest.mark.requirement("SR-SAT-4", kind="example", code=CODE)
@pytest.mark.parametrize("as_list", [False, True])
def test_single_precision_vertices_give_double_precision_polygons(as_list: bool) -> None:
    """With an edge's midpoint among the points the hull's slack is computed, and float32
    arithmetic would give another value: the polygons of the float64 values."""
    points = np.vstack([TRIANGLE, 0.5 * (TRIANGLE[0] + TRIANGLE[1])]) + 0.1
    single = np.array([points], dtype=np.float32)
    wide = single.astype(np.float64)
    got = convex_polygons(list(single) if as_list else single)
    want = convex_polygons(list(wide) if as_list else wide)
    assert got.vertices_m.dtype == np.float64
    np.testing.assert_array_equal(got.vertices_m, want.vertices_m)
    np.testing.assert_array_equal(got.slack_m, want.slack_m)
    assert got.slack_m[0] > 0.0


@pytest.mark.requirement("SR-SAT-4", kind="example", code=CODE)
def test_counts_with_a_list_of_polygons_are_refused() -> None:
    with pytest.raises(GeometryError) as caught:
        convex_polygons([TRIANGLE], counts=[3])
    assert str(caught.value) == "convex_polygons: counts apply to an (N, K, 2) array only"
