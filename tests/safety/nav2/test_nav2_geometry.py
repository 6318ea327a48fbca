"""What a zone gives beyond the footprint, exactly (SR-NAV-1): depth ahead and clearance."""

from __future__ import annotations

from fractions import Fraction

from safety.nav2.geometry import Footprint, axis_depth_m, clearance_sq_m2, contains_footprint

F = Fraction
# 0.3 m x 0.3 m: leading edge 0.15 m ahead of the origin, 0.15 m to each side.
ROBOT = Footprint(F("0.3"), F("0.3"))


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
    cut = [
        (F("0.1"), F("0.5")),
        (F("0.5"), F("0.1")),
        (F("0.5"), F("-0.5")),
        (F("-0.5"), F("-0.5")),
        (F("-0.5"), F("0.5")),
    ]
    # Distance from the corner (0.15, 0.15) to the line x + y = 0.6: (0.6 - 0.3) / sqrt(2).
    assert clearance_sq_m2(cut, ROBOT) == (F("0.3") ** 2) / 2
    # The tutorial's box does not hold the robot: no clearance at all.
    assert clearance_sq_m2(_box("0", "0.4", "-0.3", "0.3"), ROBOT) == 0
