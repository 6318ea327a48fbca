"""The path clearance at its edges: the loose-point box, the pivot disc, the first pose
(SR-RUN-3).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) showed these unwatched:
a loose point exactly on the boundary of a straight piece (rear, front, side) or of a corner's
pivot disc, a point just outside them, a corner away from the x axis, and the heading of the
footprint that ``distances_now`` places. The cases use a 1 m x 0.75 m footprint (half
diagonal 0.625 m), steps of 0.25 m and a contact tolerance of 2^-10 m, so every boundary below
is exact in binary floating point.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pipeline.config import GeometrySection, default_config, overridden
from pipeline.types import FloatArray
from safety.geometry.path import PathAhead, PathClearance, PathDistances
from safety.geometry.polygons import GeometryError, NonFiniteGeometryError, convex_polygons

PATH = ["safety/geometry/path.py"]
TOL_M = 2.0**-10
STEP_M = 0.25
GEOMETRY: GeometrySection = overridden(
    default_config(),
    {
        "geometry": {
            "footprint_length_m": 1.0,
            "footprint_width_m": 0.75,
            "contact_tolerance_m": TOL_M,
        }
    },
).geometry
HALF_LENGTH_M = 0.5 + TOL_M  # the point test's half extents, tolerance included
HALF_WIDTH_M = 0.375 + TOL_M
NO_ZONES = convex_polygons(np.zeros((0, 3, 2)))


def _points(path: PathAhead, x_m: list[float], y_m: list[float]) -> PathDistances:
    return PathClearance(GEOMETRY).free_distances(path, NO_ZONES, np.array(x_m), np.array(y_m))


def _straight() -> PathAhead:
    """Along +x from the origin for 2 m: samples at 0, 0.25, ..., 2 m."""
    return PathAhead.straight((0.0, 0.0, 0.0), 2.0, STEP_M)


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
@pytest.mark.parametrize(
    ("x_m", "y_m", "free_m"),
    [
        (-HALF_LENGTH_M, 0.0, 0.0),  # the rear edge at the first pose
        (2.0 + HALF_LENGTH_M, 0.0, 1.75),  # the front edge of the last piece
        (1.0, HALF_WIDTH_M, 0.25),  # the left edge, first reached from the sample at 0.25 m
        (1.0, -HALF_WIDTH_M, 0.25),  # the right edge
    ],
)
def test_a_loose_point_on_a_straight_piece_s_boundary_is_on_the_path(
    x_m: float, y_m: float, free_m: float
) -> None:
    """The piece is closed: a point exactly at its half extent plus the tolerance holds the
    robot at the first sample whose piece reaches it."""
    got = _points(_straight(), [x_m], [y_m])
    assert got.n_points_on_path == 1
    assert got.point_free_m == free_m


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
@pytest.mark.parametrize(
    ("x_m", "y_m"),
    [
        (-HALF_LENGTH_M - 0.5 * TOL_M, 0.0),
        (2.0 + HALF_LENGTH_M + 0.5 * TOL_M, 0.0),
        (1.0, HALF_WIDTH_M + 0.5 * TOL_M),
        (1.0, -HALF_WIDTH_M - 0.5 * TOL_M),
    ],
)
def test_a_loose_point_just_outside_a_straight_piece_is_not_on_the_path(
    x_m: float, y_m: float
) -> None:
    """Half a tolerance beyond the boundary (inside the bounding box that pre-selects the
    points, which is padded by twice the tolerance): not on the path."""
    got = _points(_straight(), [x_m], [y_m])
    assert got.n_points_on_path == 0
    assert got.point_free_m == got.lookahead_m == 2.0


def _corner(side: float = 1.0) -> PathAhead:
    """Along +x at y = 1 m, then a left turn at (2, 1) (``side`` -1: mirrored, y = -1 m and a
    right turn): the piece from the sample at (1.75, 1) to the one at (2, 1) is a corner,
    covered by the disc about (1.75, 1) of radius half diagonal + step + tolerance."""
    route = np.array([[0.0, 1.0], [2.0, 1.0], [2.0, 4.0]]) * np.array([1.0, side])
    return PathAhead.along_polyline(route, 0.0, 4.0, STEP_M)


PIVOT_RADIUS_M = 0.625 + STEP_M + TOL_M


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
@pytest.mark.parametrize("side", [1.0, -1.0], ids=["left turn", "right turn"])
def test_a_loose_point_on_the_pivot_disc_is_on_the_path_and_just_outside_it_is_not(
    side: float,
) -> None:
    """A point exactly the pivot radius from the pivot (1.75, 1), beyond the straight pieces
    on both sides of the corner, holds the robot at 1.75 m; one tolerance farther it does
    not. A right turn is a corner as much as a left one."""
    path = _corner(side)
    clear = PathClearance(GEOMETRY)
    assert clear._corners(path).tolist() == [i == 7 for i in range(path.arc_m.size - 1)]
    on = _points(path, [1.75 + PIVOT_RADIUS_M, 1.75], [side, side * (1.0 - PIVOT_RADIUS_M)])
    assert on.n_points_on_path == 2
    assert on.point_free_m == 1.75
    off = _points(
        path,
        [1.75 + PIVOT_RADIUS_M + TOL_M, 1.75],
        [side, side * (1.0 - PIVOT_RADIUS_M - TOL_M)],
    )
    assert off.n_points_on_path == 0
    assert off.point_free_m == off.lookahead_m == 4.0


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_with_no_zone_the_zone_results_are_empty_arrays() -> None:
    """No zone: an empty float array of free distances and an empty bool array of hits (a
    mask the runtime can index with), whatever the loose points."""
    for x_m in ([], [1.0]):
        got = _points(_straight(), x_m, [0.0] * len(x_m))
        assert got.zone_free_m.dtype == np.float64
        assert got.zone_hit.dtype == np.bool_
        assert got.zone_free_m.shape == got.zone_hit.shape == (0,)


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_distance_now_places_the_footprint_at_the_first_pose_s_heading() -> None:
    """The path turns a quarter right after its first sample: the distance now is from the
    footprint at the first heading (front 0.5 m ahead, sides 0.375 m out), not the second."""
    path = PathAhead(
        arc_m=np.array([0.0, 1.0]),
        x_m=np.zeros(2),
        y_m=np.zeros(2),
        theta_rad=np.array([0.0, 0.5 * math.pi]),
    )
    ahead = np.array([[1.0, -0.25], [1.5, -0.25], [1.5, 0.25], [1.0, 0.25]])
    beside = np.array([[-0.25, 1.0], [0.25, 1.0], [0.25, 1.5], [-0.25, 1.5]])
    distance = PathClearance(GEOMETRY).distances_now(path, convex_polygons([ahead, beside]))
    assert distance.tolist() == pytest.approx([0.5, 0.625], abs=1e-12)


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_the_pieces_of_a_straight_path_and_of_a_corner() -> None:
    """A straight piece is the footprint stretched forward by the step (four vertices, padded
    with the first); a corner piece is the pivot disc's 16-gon, every edge at least the pivot
    radius from the pivot; the slack is 16 ulp of 1 + the largest coordinate."""
    clear = PathClearance(GEOMETRY)
    straight = clear.pieces(_straight())
    assert straight.n == 8
    assert straight.counts.tolist() == [4] * 8
    first = [[-0.5, -0.375], [0.75, -0.375], [0.75, 0.375], [-0.5, 0.375]]
    assert straight.vertices_m[:, :, 0].T.tolist() == first + [first[0]] * 12
    last = straight.vertex_list(7)
    assert last.tolist() == [[1.25, -0.375], [2.5, -0.375], [2.5, 0.375], [1.25, 0.375]]
    ulp = 2.0**-53
    assert straight.slack_m[0] == 16 * ulp * (1.0 + 0.75)
    assert straight.slack_m[7] == 16 * ulp * (1.0 + 2.5)
    away = clear.pieces(PathAhead.straight((-8.0, -4.0, 0.0), 2.0, STEP_M))
    assert away.slack_m[0] == 16 * ulp * (1.0 + 8.5)  # the largest |coordinate|: x = -8.5
    corner = clear.pieces(_corner())
    assert corner.counts.tolist() == [16 if i == 7 else 4 for i in range(corner.n)]
    ring = corner.vertex_list(7)
    a, b = ring, np.roll(ring, -1, axis=0)
    edge = b - a
    pivot = np.array([1.75, 1.0])
    inner = (edge[:, 0] * (pivot[1] - a[:, 1]) - edge[:, 1] * (pivot[0] - a[:, 0])) / np.hypot(
        edge[:, 0], edge[:, 1]
    )
    assert inner.min() >= PIVOT_RADIUS_M - 1e-12
    assert inner.max() <= PIVOT_RADIUS_M + 1e-12


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_free_distances_per_zone_and_the_nearest_loose_point() -> None:
    """A zone ahead is first touched by the piece from 1 m (its front reaches 1.75 m); a zone
    beside the path and one behind it are not touched and keep the lookahead; a zone beside
    the path within the configured tolerance (2^-10 m) is touched. Of two loose
    points on the path the nearer along it sets the loose-point distance; a point off the
    path is not counted."""
    clear = PathClearance(GEOMETRY)

    def box(x0: float, x1: float, y0: float, y1: float) -> FloatArray:
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    zones = convex_polygons(
        [
            box(1.625, 1.75, -0.1, 0.1),
            box(0.5, 1.0, 1.0, 1.5),
            box(-1.0, -0.75, -0.1, 0.1),
            box(1.0, 1.125, 0.375 + 0.5 * TOL_M, 0.5),  # within the configured tolerance
            box(1.0, 1.125, 0.375 + 1.5 * TOL_M, 0.5),  # beyond it
        ]
    )
    got = clear.free_distances(
        _straight(), zones, np.array([2.25, 1.0, 1.0]), np.array([0.0, 0.0, 3.0])
    )
    assert got.zone_hit.tolist() == [True, False, False, True, False]
    assert got.zone_free_m.tolist() == [1.0, 2.0, 2.0, 0.25, 2.0]
    assert got.n_points_on_path == 2
    assert got.point_free_m == 0.25
    assert got.lookahead_m == 2.0
    alone = clear.free_distances(_straight(), zones, np.array([2.25]), np.array([0.0]))
    assert (alone.n_points_on_path, alone.point_free_m) == (1, 1.5)


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_the_path_is_sampled_by_arc_length_along_the_polyline() -> None:
    """Samples every step from the start (a negative start is the route's start), the last
    one at the end of the lookahead or of the route, with the heading of the segment each lies
    on; a repeated point (a zero-length segment), inside the route or at its end, gives no
    NaN."""
    route = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    path = PathAhead.along_polyline(route, -0.5, 10.0, 0.25)
    assert path.arc_m.tolist() == [0.25 * i for i in range(9)]
    assert path.x_m.tolist() == [0.0, 0.25, 0.5, 0.75] + [1.0] * 5
    assert path.y_m.tolist() == [0.0] * 5 + [0.25, 0.5, 0.75, 1.0]
    assert path.theta_rad.tolist() == [0.0] * 4 + [0.5 * math.pi] * 5
    assert path.length_m == 2.0
    exact = PathAhead.along_polyline(route[:2], 0.0, 1.0, 0.25)  # no sample past the end
    assert exact.arc_m.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    middle = PathAhead.along_polyline(route[:2], 0.25, 0.625, 0.5)  # a short last step
    assert middle.arc_m.tolist() == [0.0, 0.5, 0.625]
    assert middle.x_m.tolist() == [0.25, 0.75, 0.875]
    short = PathAhead.along_polyline(route[:2], 0.5, 4.0, 0.25)  # the route ends first
    assert short.arc_m.tolist() == [0.0, 0.25, 0.5]
    assert short.x_m.tolist() == [0.5, 0.75, 1.0]
    later = PathAhead.along_polyline(route, 1.5, 10.0, 0.25)  # from the third segment on
    assert later.x_m.tolist() == [1.0, 1.0, 1.0]
    assert later.y_m.tolist() == [0.5, 0.75, 1.0]
    stub = PathAhead.along_polyline(route[:2], 1.0, 4.0, 0.25)  # at the end: one step
    assert stub.arc_m.tolist() == [0.0, 0.25]
    assert stub.x_m.tolist() == [1.0, 1.0]
    repeated_end = PathAhead.along_polyline(route[:3], 0.5, 4.0, 0.25)  # its last segment: 0 m
    assert repeated_end.x_m.tolist() == [0.5, 0.75, 1.0]
    assert repeated_end.y_m.tolist() == [0.0, 0.0, 0.0]


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_straight_ahead_of_a_pose_away_from_the_origin() -> None:
    path = PathAhead.straight((1.0, -2.0, 0.5), 3.0, 1.0)
    assert path.arc_m.tolist() == [0.0, 1.0, 2.0, 3.0]
    assert path.x_m == pytest.approx(1.0 + path.arc_m * math.cos(0.5), abs=1e-12)
    assert path.y_m == pytest.approx(-2.0 + path.arc_m * math.sin(0.5), abs=1e-12)
    assert path.theta_rad == pytest.approx(np.full(4, 0.5), abs=1e-12)


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_bad_paths_name_what_is_wrong() -> None:
    """The shape, finiteness and order checks of a path and of a polyline, word for word; two
    samples are enough."""
    two = np.zeros(2)
    assert PathAhead(np.array([0.0, 1.0]), two, two, two).length_m == 1.0
    shapes = "1-D arrays of one length >= 2, got "
    with pytest.raises(GeometryError, match=re.escape(shapes + "(1,), (1,), (1,), (1,)")):
        PathAhead(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1))
    with pytest.raises(GeometryError, match=re.escape(shapes + "(2, 2), (2,), (2,), (2,)")):
        PathAhead(np.zeros((2, 2)), two, two, two)
    with pytest.raises(GeometryError, match=re.escape(shapes + "(2,), (2,), (3,), (2,)")):
        PathAhead(np.array([0.0, 1.0]), two, np.zeros(3), two)
    with pytest.raises(NonFiniteGeometryError, match=r"^PathAhead: every pose and arc length"):
        PathAhead(np.array([0.0, 1.0]), two, two, np.array([0.0, np.inf]))
    with pytest.raises(GeometryError, match=r"^PathAhead: arc_m must start at 0 and increase"):
        PathAhead(np.array([0.5, 1.0]), two, two, two)
    for arc in ([0.0, 1.0, 0.5], [0.0, 1.0, 1.0]):
        with pytest.raises(GeometryError, match="increase strictly"):
            PathAhead(np.array(arc), np.zeros(3), np.zeros(3), np.zeros(3))
    polyline = "PathAhead: polyline must be finite (N >= 2, 2), got "
    for bad, shape in [
        (np.zeros((3, 3)), "(3, 3)"),
        (np.zeros(4), "(4,)"),
        (np.zeros((1, 2)), "(1, 2)"),
        (np.array([[0.0, 0.0], [np.nan, 1.0]]), "(2, 2)"),
    ]:
        with pytest.raises(GeometryError, match=re.escape(polyline + shape)):
            PathAhead.along_polyline(bad, 0.0, 1.0, 0.25)
    route = np.array([[0.0, 0.0], [1.0, 0.0]])
    expected = re.escape("PathAhead: lookahead_m = 1.0, step_m = 0.0: expected > 0")
    with pytest.raises(GeometryError, match=expected):
        PathAhead.along_polyline(route, 0.0, 1.0, 0.0)
    with pytest.raises(GeometryError, match=re.escape("lookahead_m = 0.0, step_m = 0.25")):
        PathAhead.along_polyline(route, 0.0, 0.0, 0.25)
    with pytest.raises(GeometryError, match="expected > 0"):
        PathAhead.along_polyline(route, math.nan, 1.0, 0.25)


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
def test_a_route_in_single_precision_is_sampled_as_its_float64_value() -> None:
    """A float32 route (exact values) gives the samples of the same route in float64: the
    segment lengths are not rounded to float32 (sqrt 2 here)."""
    route = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 3.0]])
    wide = PathAhead.along_polyline(route, 0.0, 3.0, 0.25)
    narrow = PathAhead.along_polyline(route.astype(np.float32), 0.0, 3.0, 0.25)
    for name in ("arc_m", "x_m", "y_m", "theta_rad"):
        assert getattr(narrow, name).tolist() == getattr(wide, name).tolist(), name


@pytest.mark.requirement("SR-RUN-3", kind="example", code=PATH)
@pytest.mark.parametrize(
    ("turn_rad", "corner"),
    [
        (1e-9, False),  # the threshold itself: straight
        (2e-9, True),
        (-2e-9, True),
        (1.0 / (2.0 * math.pi), True),
        (1.0, True),
        (-1.0, True),
        (math.pi, True),  # a U-turn
        (2.0 * math.pi, False),  # a full turn: the same heading
    ],
)
def test_a_heading_change_above_a_nanoradian_makes_a_corner(turn_rad: float, corner: bool) -> None:
    """Any turn between two samples larger than 1e-9 rad in either direction, a U-turn
    included, is a corner (covered by the pivot disc); a full turn is not."""
    path = PathAhead(
        arc_m=np.array([0.0, 0.25, 0.5]),
        x_m=np.array([0.0, 0.25, 0.25]),
        y_m=np.zeros(3),
        theta_rad=np.array([0.0, 0.0, turn_rad]),
    )
    clear = PathClearance(GEOMETRY)
    assert clear._corners(path).tolist() == [False, corner]
    assert clear.pieces(path).counts.tolist() == [4, 16 if corner else 4]
