"""What a zone gives beyond the footprint, exactly (SR-NAV-1): depth ahead and clearance."""

from __future__ import annotations

import math
from fractions import Fraction

import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from safety.nav2.geometry import (
    Footprint,
    Vertex,
    _intersection_y,
    axis_depth_m,
    clearance_sq_m2,
    contains_footprint,
    rotate_to,
)

F = Fraction
# 0.3 m x 0.3 m: leading edge 0.15 m ahead of the origin, 0.15 m to each side.
ROBOT = Footprint(F("0.3"), F("0.3"))
# A square of 1 m with its front right corner cut at 45 degrees, 0.3 m from the robot's corner.
CUT_CORNER = [
    (F("0.1"), F("0.5")),
    (F("0.5"), F("0.1")),
    (F("0.5"), F("-0.5")),
    (F("-0.5"), F("-0.5")),
    (F("-0.5"), F("0.5")),
]
# A 2 m square with a notch cut from its front whose tip points at the robot from 0.3 m ahead.
NOTCHED = [
    (F(1), F(-1)),
    (F(1), F(-1, 2)),
    (F(3, 10), F(0)),
    (F(1), F(1, 2)),
    (F(1), F(1)),
    (F(-1), F(1)),
    (F(-1), F(-1)),
]


def _box(x0: str, x1: str, y0: str, y1: str) -> list[tuple[F, F]]:
    return [(F(x1), F(y1)), (F(x1), F(y0)), (F(x0), F(y0)), (F(x0), F(y1))]


def test_a_box_ahead_gives_its_reach_beyond_the_front() -> None:
    # The tutorial's stop box: 0.4 m ahead of the origin, 0.3 m each side.
    box = _box("0", "0.4", "-0.3", "0.3")
    assert axis_depth_m(box, ROBOT, "forward") == F("0.25")
    # Nothing of it lies behind the robot.
    assert axis_depth_m(box, ROBOT, "reverse") == 0


def test_a_box_narrower_than_the_robot_or_short_of_its_front_gives_nothing() -> None:
    assert axis_depth_m(_box("0", "0.4", "-0.1", "0.1"), ROBOT, "forward") == 0
    # Starts 5 cm beyond the front: an obstacle in the gap is never seen.
    assert axis_depth_m(_box("0.2", "0.9", "-0.3", "0.3"), ROBOT, "forward") == 0


def test_a_slanted_front_gives_its_shortest_reach_across_the_robot() -> None:
    # Front edge from (0.5, 0.3) to (0.9, -0.3): at y = 0.15 it is at x = 0.6.
    slanted = [(F("0.5"), F("0.3")), (F("0.9"), F("-0.3")), (F("0"), F("-0.3")), (F("0"), F("0.3"))]
    assert axis_depth_m(slanted, ROBOT, "forward") == F("0.6") - F("0.15")


def test_a_notch_reaching_into_the_zone_limits_the_depth() -> None:
    # A U-shaped zone: 1 m deep, but a notch cut back to 0.35 m in front of the robot's side.
    notched = [
        (F("0"), F("0.3")),
        (F("0"), F("-0.3")),
        (F("1"), F("-0.3")),
        (F("1"), F("0.1")),
        (F("0.35"), F("0.1")),
        (F("0.35"), F("0.2")),
        (F("1"), F("0.2")),
        (F("1"), F("0.3")),
    ]
    assert axis_depth_m(notched, ROBOT, "forward") == F("0.2")


def test_a_self_crossing_ring_is_read_even_odd_like_nav2() -> None:
    # A bow tie crossing at (0.5, 0): even-odd, the waist is a single point, so lines just
    # beside y = 0 run inside all the way to x = 1.
    bow = [(F("0"), F("0.3")), (F("1"), F("-0.3")), (F("1"), F("0.3")), (F("0"), F("-0.3"))]
    depth = axis_depth_m(bow, ROBOT, "forward")
    # At y = +-0.15 the tie's left half ends at x = 0.25: that bounds the depth.
    assert depth == F("0.25") - F("0.15")


def test_clearance_all_round_is_the_distance_to_the_boundary() -> None:
    square = _box("-0.5", "0.5", "-0.5", "0.5")
    assert contains_footprint(square, ROBOT)
    assert clearance_sq_m2(square, ROBOT) == F("0.35") ** 2
    # A corner cut at 45 degrees: the nearest point is the footprint's corner.
    # Distance from the corner (0.15, 0.15) to the line x + y = 0.6: (0.6 - 0.3) / sqrt(2).
    assert clearance_sq_m2(CUT_CORNER, ROBOT) == (F("0.3") ** 2) / 2
    # The tutorial's box does not hold the robot: no clearance at all.
    assert clearance_sq_m2(_box("0", "0.4", "-0.3", "0.3"), ROBOT) == 0


# A footprint and zones on a 1/64 m grid: binary fractions, so GEOS reads every coordinate
# exactly and decides touching (an edge along the footprint's side, a vertex on its corner)
# as exact arithmetic does. 0.3125 m x 0.25 m: half-sizes 10/64 and 8/64 m.
GRID = 64
ON_GRID = Footprint(F(20, GRID), F(16, GRID))
HX, HY = F(10, GRID), F(8, GRID)


@st.composite
def _zones(draw: st.DrawFn) -> list[Vertex]:
    """Star polygons (one vertex per equal sector) or boxes, anywhere within 1.5 m of the
    robot: holding it, cutting it, beside it or far from it, some touching its sides."""
    if draw(st.booleans()):
        # Box sides on or near the footprint's own lines (+-10 and +-8 grid steps).
        near = st.integers(-24, 24)
        x0, x1 = sorted(draw(st.lists(near, min_size=2, max_size=2, unique=True)))
        y0, y1 = sorted(draw(st.lists(near, min_size=2, max_size=2, unique=True)))
        return _box(*(str(F(v, GRID)) for v in (x0, x1, y0, y1)))
    n = draw(st.integers(3, 8))
    cx, cy = (F(draw(st.integers(-96, 96)), GRID) for _ in range(2))
    sector = 360 // n
    points = []
    for k in range(n):
        r = draw(st.integers(4, 80))
        a = math.radians(k * sector + draw(st.integers(0, sector - 1)))
        points.append((cx + F(round(r * math.cos(a)), GRID), cy + F(round(r * math.sin(a)), GRID)))
    return points


@pytest.mark.requirement("SR-NAV-1", kind="cross-check", code=["safety/nav2/geometry.py"])
@settings(max_examples=examples(300), deadline=None)
@given(zone=_zones())
def test_holding_the_footprint_and_the_clearance_agree_with_geos(zone: list[Vertex]) -> None:
    """contains_footprint is GEOS's ``covers`` (the boundary may touch), and the clearance is
    the squared distance from the footprint to the zone's boundary, on zones anywhere."""
    polygon = shapely.Polygon([(float(x), float(y)) for x, y in zone])
    assume(polygon.is_valid and polygon.area > 0)
    robot = shapely.box(-float(HX), -float(HY), float(HX), float(HY))
    holds = contains_footprint(zone, ON_GRID)
    assert holds == polygon.covers(robot)
    clearance = clearance_sq_m2(zone, ON_GRID)
    reference = polygon.exterior.distance(robot) ** 2 if holds else 0.0
    assert math.isclose(float(clearance), reference, rel_tol=1e-12, abs_tol=1e-15)
    rec = current()
    rec.count("zones", "hold the footprint" if holds else "do not hold it")
    if not holds and polygon.disjoint(robot):
        rec.count("zones", "apart from the footprint")
    if holds and clearance == 0:
        rec.count("zones", "hold it touching")


def test_a_zone_just_too_small_or_touching_the_footprint() -> None:
    """Edges along the footprint's sides and a vertex on its corner still hold it; a zone
    short of it by one grid step in length or in width does not."""
    exact = _box(*(str(v) for v in (-HX, HX, -HY, HY)))
    assert contains_footprint(exact, ON_GRID)
    assert clearance_sq_m2(exact, ON_GRID) == 0
    step = F(1, GRID)
    assert not contains_footprint(_box(*(str(v) for v in (-HX + step, HX, -HY, HY))), ON_GRID)
    assert not contains_footprint(_box(*(str(v) for v in (-HX, HX, -HY, HY - step))), ON_GRID)
    # A diamond whose edge x + y = HX + HY passes through the corner (HX, HY).
    reach = HX + HY
    diamond = [(reach, F(0)), (F(0), reach), (-reach, F(0)), (F(0), -reach)]
    assert contains_footprint(diamond, ON_GRID)
    # A zone entirely to the left of the robot, its slanted edges spanning the robot's y = 0.
    left = [(F(-1), F(-1)), (F(-1, 2), F(0)), (F(-1), F(1)), (F(-3, 2), F(0))]
    assert not contains_footprint(left, ON_GRID)
    # A tall zone to the right of the robot: the ray along +x crosses both of its slanted
    # edges, so it does not hold the origin (an even count), however steep the edges.
    right = [(F(1), F(-2)), (F(2), F(-2)), (F(1), F(2)), (F(1, 2), F(2))]
    assert not contains_footprint(right, ON_GRID)
    # A notch pointing at the robot's front from 0.3 m: the notch's edges, extended, would
    # cut the footprint; the edges themselves stop short of it.
    assert contains_footprint(NOTCHED, ON_GRID)
    # A repeated vertex (a zero-length edge) is read as the point it is.
    square = _box("-0.5", "0.5", "-0.5", "0.5")
    assert clearance_sq_m2([square[0], *square], ROBOT) == F("0.35") ** 2


def test_depth_needs_the_crossings_of_the_front_and_of_the_edges() -> None:
    """A slanted slot cut from the far side: along y in (-0.12, -0.10) the front lies in the
    slot, so the depth is 0, though the front lies inside the zone at the middle and at both
    sides of the robot. A zone whose near edge is the front line itself covers it."""
    slot = [
        (F(-1), F("-0.3")),
        (F(1), F("-0.3")),
        (F(1), F("0.3")),
        (F(-1, 20), F("0.3")),
        (F(9, 40), F(-1, 4)),
        (F(43, 200), F(-1, 4)),
        (F(-3, 50), F("0.3")),
        (F(-1), F("0.3")),
    ]
    assert axis_depth_m(slot, ROBOT, "forward") == 0
    assert axis_depth_m(_box("0.15", "1", "-0.3", "0.3"), ROBOT, "forward") == F("0.85")


def _sampled_depth(zone: list[Vertex], samples: int) -> Fraction:
    """The stretch holding the front, even-odd, at ``samples + 1`` offsets across the robot
    (exact arithmetic, offsets nudged off the grid's vertex heights): its least value."""
    front, half = ROBOT.ahead()
    edges = list(zip(zone, [*zone[1:], zone[0]], strict=True))
    least = None
    for k in range(samples + 1):
        s = min(-half + 2 * half * F(k, samples) + F(1, 10**7), half - F(1, 10**7))
        xs = sorted(
            x0 + (s - y0) * (x1 - x0) / (y1 - y0)
            for (x0, y0), (x1, y1) in edges
            if min(y0, y1) < s < max(y0, y1)
        )
        stretch = F(0)
        for x_in, x_out in zip(xs[0::2], xs[1::2], strict=True):
            if x_in <= front <= x_out:
                stretch = x_out - front
        least = stretch if least is None else min(least, stretch)
    assert least is not None
    return least


@pytest.mark.requirement("SR-NAV-1", kind="property", code=["safety/nav2/geometry.py"])
@settings(max_examples=examples(60), deadline=None)
@given(
    zone=st.lists(st.tuples(st.integers(-20, 20), st.integers(-8, 8)), min_size=3, max_size=7).map(
        lambda points: [(F(x, 20), F(y, 20)) for x, y in points]
    )
)
def test_depth_of_any_ring_self_crossing_or_not_is_the_least_stretch(zone: list[Vertex]) -> None:
    """Rings with crossing edges are read even-odd, as Nav2 reads them (GEOS refuses them):
    the depth is at most the stretch at every sampled offset, and within a sample step of
    the least of them (edges on the 1/20 m grid are at most 40 times as long as tall)."""
    depth = axis_depth_m(zone, ROBOT, "forward")
    sampled = _sampled_depth(zone, 300)
    assert depth <= sampled
    assert sampled - depth <= 40 * F(3, 10) / 300
    current().count("rings", "some depth" if depth > 0 else "no depth")


def test_a_ring_whose_edges_cross_in_front_of_the_robot() -> None:
    ring = [(F(9, 10), F(0)), (F(-1, 20), F(1, 5)), (F(-7, 10), F(-2, 5)), (F(4, 5), F(-1, 5))]
    ring.append((F(-1, 20), F(2, 5)))
    # Found by search: without the crossing of its edges the depth would read 37/240 m.
    assert axis_depth_m(ring, ROBOT, "forward") == F(3, 80)


def test_clearance_reaches_a_vertex_pointing_at_the_robot_and_every_corner() -> None:
    # The notch's tip 0.3 m ahead of the origin, 0.15 m from the robot's front.
    assert clearance_sq_m2(NOTCHED, ROBOT) == F("0.15") ** 2
    # The same cut at the rear left (a half turn): its nearest point is the corner (-0.15, -0.15).
    rear_left = [(-x, -y) for x, y in CUT_CORNER]
    assert clearance_sq_m2(rear_left, ROBOT) == (F("0.3") ** 2) / 2


def test_a_direction_or_footprint_that_does_not_exist_is_refused() -> None:
    with pytest.raises(ValueError, match=r"^direction = 'sideways': allowed: forward \| reverse$"):
        axis_depth_m(_box("0", "1", "-1", "1"), ROBOT, "sideways")
    for length, width in ((F("0.3"), F(0)), (F(0), F("0.3"))):
        with pytest.raises(ValueError, match="both sides must be > 0"):
            Footprint(length, width)
    # Reverse travel turns the zone a half turn (not a mirror image).
    assert rotate_to("reverse", [(F(1), F(2))]) == [(F(-1), F(-2))]


@pytest.mark.parametrize(
    ("a", "b", "c", "d"),
    [
        ((0.1, 0.7), (0.9, -0.5), (1.3, 0.4), (-0.2, -0.35)),
        ((-0.4, -0.1), (0.6, 0.45), (0.5, -0.6), (-0.1, 0.8)),
        ((0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.6, 0.4)),  # c-d ends on a-b: crossing at d
        ((0.0, 0.0), (1.0, 1.0), (2.0, 0.0), (1.5, 1.0)),  # the lines cross beyond both ends
        ((0.1, 0.2), (1.1, 1.2), (1.2, 0.1), (0.9, 0.4)),  # within a-b, beyond c-d's end
        ((1.2, 0.1), (0.9, 0.4), (0.1, 0.2), (1.1, 1.2)),  # the same, the other way round
        ((1.0, -0.7), (-0.5, 1.0), (-0.1, -0.7), (0.0, 0.6)),  # crossing near c-d's end
        ((0.0, 0.0), (1.0, 1.0), (0.0, 0.5), (1.0, 1.5)),  # parallel
    ],
)
def test_where_two_edges_cross_against_geos(
    a: tuple[float, float], b: tuple[float, float], c: tuple[float, float], d: tuple[float, float]
) -> None:
    """The height at which two edges of a ring cross (a breakpoint of the depth), or None."""
    exact = [(F(repr(x)), F(repr(y))) for x, y in (a, b, c, d)]
    found = _intersection_y(*exact)
    meet = shapely.LineString([a, b]).intersection(shapely.LineString([c, d]))
    if meet.is_empty:
        assert found is None
    else:
        assert found is not None
        assert math.isclose(float(found), meet.y, abs_tol=1e-12)
