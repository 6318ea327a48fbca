"""Convex polygons at their edges: the input checks word for word, the hull's vertices and
its rounding slack, bounds, rigid motions and the scratch buffers (SR-SAT-1, SR-SAT-4).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) asks of each check and
each term whether a test would notice it changed: which polygon and point a message names,
the coordinate limit at exactly 1e6 m, which input points become vertices (ties, repeats,
points on an edge, points past ``counts``), when the hull needs slack and how much, and the
rounding allowances of bounds and transforms.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pipeline.types import FloatArray
from safety.geometry.polygons import (
    HULL_HALFPLANE,
    MAX_COORD_M,
    DegeneratePolygonError,
    GeometryError,
    NonFiniteGeometryError,
    PolygonBounds,
    U,
    Workspace,
    convex_hull_batch,
    convex_polygons,
    polygon_bounds,
    transform_polygons,
)

POLYGONS = ["safety/geometry/polygons.py"]
SQUARE = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]


def _ring(points: list[list[float]]) -> FloatArray:
    return np.array(points, dtype=np.float64)


@pytest.mark.requirement("SR-SAT-4", kind="example", code=POLYGONS)
@pytest.mark.parametrize(
    ("second", "error", "message"),
    [
        (
            [[0.0, 0.0], [1.0, 0.0], [0.0, math.nan]],
            NonFiniteGeometryError,
            "polygon 1: point 2 is (0.0, nan); expected finite coordinates in metres",
        ),
        (
            [[0.0, 0.0], [-math.inf, 0.0], [0.0, 1.0]],
            NonFiniteGeometryError,
            "polygon 1: point 1 is (-inf, 0.0); expected finite coordinates in metres",
        ),
        (
            [[0.0, 0.0], [1.0, 0.0], [0.0, -1000001.0]],
            NonFiniteGeometryError,
            "polygon 1: point 2 is (0.0, -1000001.0); expected coordinates within +/-1e+06 m",
        ),
        (
            [[0.0, 0.0], [1000001.0, 0.0], [0.0, 1.0]],
            NonFiniteGeometryError,
            "polygon 1: point 1 is (1000001.0, 0.0); expected coordinates within +/-1e+06 m",
        ),
        (
            [[3.0, 3.0], [3.0, 3.0], [3.0, 3.0]],
            DegeneratePolygonError,
            "polygon 1: all points coincide at (3.0, 3.0); a polygon needs at least 3 distinct "
            "points",
        ),
        (
            [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]],
            DegeneratePolygonError,
            "polygon 1: all points are collinear (within 5.33e-15 m); a polygon needs 3 points "
            "that are not on one line",
        ),
        (
            [[0.0, 0.0], [1.0, 1.0]],
            DegeneratePolygonError,
            "polygon 1: 2 point(s) given; a polygon needs at least 3 distinct points",
        ),
    ],
)
def test_a_bad_polygon_is_named_with_its_point_and_value(
    second: list[list[float]], error: type[Exception], message: str
) -> None:
    """The second polygon of two is the bad one: the message names it, the point and the
    value (the collinear band is HULL_HALFPLANE = 24u times the largest coordinate, 2 m)."""
    with pytest.raises(error, match="^" + re.escape(message) + "$"):
        convex_polygons([_ring(SQUARE), _ring(second)])


@pytest.mark.requirement("SR-SAT-4", kind="example", code=POLYGONS)
def test_coordinates_up_to_a_million_metres_are_accepted() -> None:
    """Exactly +/-1e6 m is inside the limit, in x and in y."""
    big = _ring([[-MAX_COORD_M, 0.0], [MAX_COORD_M, -MAX_COORD_M], [0.0, MAX_COORD_M]])
    polys = convex_polygons([big])
    assert polys.counts.tolist() == [3]


@pytest.mark.requirement("SR-SAT-4", kind="example", code=POLYGONS)
def test_malformed_arrays_and_counts_are_refused_word_for_word() -> None:
    square = _ring(SQUARE)
    with pytest.raises(
        GeometryError, match=re.escape("polygon 1: expected a (k, 2) array, got (4, 3)")
    ):
        convex_polygons([square, np.zeros((4, 3))])
    with pytest.raises(
        GeometryError, match=re.escape("polygon 0: expected a (k, 2) array, got (8,)")
    ):
        convex_polygons([square.ravel()])
    with pytest.raises(
        GeometryError, match=re.escape("convex_polygons: counts apply to an (N, K, 2) array only")
    ):
        convex_polygons([square], counts=[4])
    with pytest.raises(
        GeometryError,
        match=re.escape("convex_polygons: expected (N, K, 2) vertices, got (1, 4, 3)"),
    ):
        convex_polygons(np.zeros((1, 4, 3)))
    stacked = np.stack([square, square + 2.0])
    within = re.escape("convex_polygons: counts must be (N,) within [1, 4]")
    for counts in ([4, 0], [5, 4], [4], [[4, 4]]):
        with pytest.raises(GeometryError, match=within):
            convex_polygons(stacked, counts)
    with pytest.raises(DegeneratePolygonError, match=re.escape("polygon 1: 1 point(s) given")):
        convex_polygons(stacked, [4, 1])
    with pytest.raises(
        GeometryError,
        match=re.escape("point set: expected (B, P) arrays of equal shape, got (2, 3)"),
    ):
        convex_hull_batch(np.zeros((2, 3)), np.zeros((2, 4)))
    with pytest.raises(GeometryError, match=re.escape("got (2, 0)")):
        convex_hull_batch(np.zeros((2, 0)), np.zeros((2, 0)))
    with pytest.raises(GeometryError, match=re.escape("got (4,)")):
        convex_hull_batch(np.zeros(4), np.zeros(4))


@pytest.mark.requirement("SR-SAT-4", kind="example", code=POLYGONS)
def test_the_hull_keeps_the_corners_counter_clockwise_from_the_lowest_x() -> None:
    """Repeated points, points on an edge and interior points are never vertices; ties for
    an extreme coordinate are broken towards the corner; only the first ``counts`` points of a
    row count (the rest may be anything finite)."""
    messy = _ring(
        [
            [1.0, 1.0], [0.5, 0.0], [0.0, 1.0], [1.0, 0.0], [0.0, 0.5], [0.0, 0.0],
            [0.5, 0.5], [1.0, 1.0], [1.0, 0.5], [0.5, 1.0], [0.0, 0.0],
        ]
    )  # fmt: skip
    polys = convex_polygons([messy])
    assert polys.counts.tolist() == [4]
    assert polys.vertex_list(0).tolist() == SQUARE
    padded = np.zeros((2, 6, 2))
    padded[0, :4] = SQUARE
    padded[0, 4:] = [[50.0, 50.0], [-9.0, 3.0]]  # beyond counts: ignored
    padded[1, :3] = [[0.0, 1.0], [0.0, 0.0], [2.0, 0.0]]  # lowest x twice: (0, 0) first
    polys = convex_polygons(padded, [4, 3])
    assert polys.counts.tolist() == [4, 3]
    assert polys.vertex_list(0).tolist() == SQUARE
    assert polys.vertex_list(1).tolist() == [[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]]
    # Lowest x and highest y at one point; highest x and lowest y at another.
    kite = convex_polygons([_ring([[0.0, 2.0], [1.0, 1.0], [2.0, -1.0], [0.5, 0.5]])])
    assert kite.vertex_list(0).tolist() == [[0.0, 2.0], [0.5, 0.5], [2.0, -1.0], [1.0, 1.0]]
    # Every extreme shared: the diamond's four points, in order, from any start.
    diamond = [[0.0, 0.0], [1.0, -1.0], [2.0, 0.0], [1.0, 1.0]]
    for shift in range(4):
        got = convex_polygons([_ring(diamond[shift:] + diamond[:shift])])
        assert got.vertex_list(0).tolist() == diamond


@pytest.mark.requirement("SR-SAT-4", kind="example", code=["pipeline/types/geometry.py"])
def test_padding_repeats_each_first_vertex_and_never_shrinks() -> None:
    """A triangle and a square (K = 4) padded to 6 vertices: each column's own vertices, then
    copies of its first; padding below K is refused."""
    polys = convex_polygons([_ring([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]]), _ring(SQUARE)])
    out = polys.padded_vertices(6)
    assert out.shape == (2, 6, 2)
    assert out[:, :, 0].T.tolist() == [[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]] + [[0.0, 0.0]] * 3
    assert out[:, :, 1].T.tolist() == SQUARE + [[0.0, 0.0]] * 2
    np.testing.assert_array_equal(polys.padded_vertices(4), polys.vertices_m)
    with pytest.raises(GeometryError, match="cannot pad 4 vertices to 3"):
        polys.padded_vertices(3)


@pytest.mark.requirement("SR-SAT-1", kind="example", code=POLYGONS)
def test_a_point_on_an_edge_gives_the_hull_its_rounding_slack() -> None:
    """A point exactly on an edge is left out but not certainly inside: the polygon gets the
    slack HULL_HALFPLANE M / sin(half the sharpest vertex angle) (here a right angle,
    sin 45 deg less 8u, M = 2 m). Interior points and copies of vertices need none."""
    square2 = [[2.0 * x, 2.0 * y] for x, y in SQUARE]
    on_edge = convex_polygons([_ring([*square2, [1.0, 0.0]])])
    assert on_edge.slack_m.tolist() == [HULL_HALFPLANE * 2.0 / math.sqrt(0.5 - 8.0 * U)]
    triangle = convex_polygons([_ring([[0.0, 0.0], [4.0, 0.0], [0.0, 2.0], [2.0, 0.0]])])
    # The sharpest angle is at (4, 0): tan = 1/2; cos of its turn = -2/sqrt(5).
    sin_half = math.sqrt((1.0 - 2.0 / math.sqrt(5.0)) * 0.5 - 8.0 * U)
    assert triangle.slack_m[0] == pytest.approx(HULL_HALFPLANE * 4.0 / sin_half, rel=1e-12)
    inside = convex_polygons([_ring([*square2, [1.0, 1.0], [2.0, 2.0], [0.0, 0.0]])])
    assert inside.slack_m.tolist() == [0.0]
    both = convex_polygons([_ring([*square2, [1.0, 0.0]]), _ring(square2)])
    assert both.slack_m.tolist() == [on_edge.slack_m[0], 0.0]


@pytest.mark.requirement("SR-SAT-4", kind="example", code=POLYGONS)
def test_a_needle_with_a_point_on_its_edge_is_refused() -> None:
    """A vertex angle of about 1e-10 rad with a point on an edge: no useful slack bound."""
    needle = _ring([[0.0, 0.0], [1.0, 0.0], [1.0, 1e-10], [0.5, 0.0]])
    message = (
        "polygon 1: a vertex angle below 2e-09 rad with points within rounding of the "
        "boundary; the hull cannot bound its rounding error"
    )
    with pytest.raises(DegeneratePolygonError, match=re.escape(message)):
        convex_polygons([_ring(SQUARE), needle])
    assert convex_polygons([needle[:3]]).slack_m.tolist() == [0.0]  # no near point: accepted


@pytest.mark.requirement("SR-SAT-1", kind="example", code=POLYGONS)
def test_bounds_of_polygons() -> None:
    """Box, centre, magnitude (largest absolute coordinate) and a circle about the centre
    rounded up by 16u M, which holds every vertex."""
    polys = convex_polygons([_ring([[-3.0, 1.0], [1.0, 1.0], [1.0, 2.0]]), _ring(SQUARE)])
    bounds = polygon_bounds(polys)
    assert isinstance(bounds, PolygonBounds)
    assert bounds.min_x_m.tolist() == [-3.0, 0.0]
    assert bounds.max_x_m.tolist() == [1.0, 1.0]
    assert bounds.min_y_m.tolist() == [1.0, 0.0]
    assert bounds.max_y_m.tolist() == [2.0, 1.0]
    assert bounds.centre_x_m.tolist() == [-1.0, 0.5]
    assert bounds.centre_y_m.tolist() == [1.5, 0.5]
    assert bounds.magnitude_m.tolist() == [3.0, 1.0]
    assert bounds.pack[3].tolist() == bounds.slack.tolist() == polys.slack_m.tolist()
    expected = [math.sqrt(4.0 + 0.25) + 16 * U * 3.0, math.sqrt(0.5) + 16 * U * 1.0]
    assert bounds.radius_m.tolist() == expected
    assert (bounds.radius_m > [math.sqrt(4.25), math.sqrt(0.5)]).all()
    assert bounds.radius_m is bounds.radius_m  # computed once


@pytest.mark.requirement("SR-SAT-4", kind="example", code=POLYGONS)
def test_a_rigid_motion_of_each_polygon_and_its_checks() -> None:
    """Each polygon takes its own pose (broadcast from scalars), its slack grows by 8u of its
    largest coordinate; a non-finite pose or a result beyond 1e6 m is refused by name."""
    polys = convex_polygons([_ring(SQUARE), _ring([[2.0 * x, 2.0 * y] for x, y in SQUARE])])
    moved = transform_polygons(polys, [1.0, -4.0], 0.5, 0.0)
    assert moved.vertex_list(0).tolist() == [[1.0, 0.5], [2.0, 0.5], [2.0, 1.5], [1.0, 1.5]]
    assert moved.vertex_list(1).tolist() == [[-4.0, 0.5], [-2.0, 0.5], [-2.0, 2.5], [-4.0, 2.5]]
    assert moved.slack_m.tolist() == [8.0 * U * 2.0, 8.0 * U * 4.0]
    assert moved.counts.tolist() == [4, 4]
    turned = transform_polygons(polys.take([0]), 0.0, 0.0, math.pi)
    assert turned.vertex_list(0) == pytest.approx(-_ring(SQUARE), abs=1e-15)
    for name, args in (
        ("x_m", (math.nan, 0.0, 0.0)),
        ("y_m", (0.0, math.inf, 0.0)),
        ("theta_rad", (0.0, 0.0, math.nan)),
    ):
        with pytest.raises(NonFiniteGeometryError, match=f"^transform_polygons: {name} is not"):
            transform_polygons(polys, *args)
    with pytest.raises(
        NonFiniteGeometryError, match=re.escape("transform_polygons: result exceeds +/-1e+06 m")
    ):
        transform_polygons(polys, MAX_COORD_M - 1.5, 0.0, 0.0)
    edge = transform_polygons(polys.take([0]), MAX_COORD_M - 1.0, 0.0, 0.0)  # exactly at it
    assert edge.vertices_m.max() == MAX_COORD_M


@pytest.mark.requirement("SR-SAT-1", kind="example", code=POLYGONS)
def test_the_workspace_hands_out_views_of_one_buffer_per_name() -> None:
    ws = Workspace()
    assert ws.nbytes == 0
    a = ws.get("a", (3, 5))
    assert a.shape == (3, 5)
    assert a.flags.c_contiguous
    assert ws.nbytes == 4096 * 8  # at least 4096 values
    a[...] = 7.0
    again = ws.get("a", (2, 2))
    assert np.shares_memory(a, again)
    assert np.shares_memory(a, ws.get("a", (4096,)))  # exactly the buffer's size: reused
    assert again.tolist() == [[7.0, 7.0], [7.0, 7.0]]
    big = ws.get("a", (5000,))
    assert big.shape == (5000,)
    assert ws.nbytes == 5000 * 8
    ws.get("b", (10,))
    assert ws.nbytes == (5000 + 4096) * 8
