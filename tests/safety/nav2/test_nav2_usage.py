"""Which speeds each zone is in use for (SR-NAV-1): Nav2's first-match rule and its gaps."""

from __future__ import annotations

from fractions import Fraction

from safety.nav2.params import Limit, Zone, parse_params
from safety.nav2.usage import RobotLimits, Use, zone_uses

F = Fraction


def _limits(forward: str, reverse: str = "0", lateral: str = "0", yaw: str = "1") -> RobotLimits:
    return RobotLimits(
        Limit(F(forward), "test"),
        Limit(F(reverse), "test"),
        Limit(F(lateral), "test"),
        Limit(F(yaw), "test"),
    )


def _velocity_zone(
    bands: list[tuple[str, float, float, float, float]],
    holonomic: bool = False,
    sectors: list[tuple[float, float]] | None = None,
) -> Zone:
    names = ", ".join(f'"{b[0]}"' for b in bands)
    text = (
        'collision_monitor:\n  ros__parameters:\n    polygons: ["V"]\n'
        '    observation_sources: ["scan"]\n    V:\n      type: "velocity_polygon"\n'
        f'      action_type: "stop"\n      holonomic: {str(holonomic).lower()}\n'
        f"      velocity_polygons: [{names}]\n"
    )
    for i, (name, lin_lo, lin_hi, th_lo, th_hi) in enumerate(bands):
        text += (
            f'      {name}:\n        points: "[[0.5, 0.3], [0.5, -0.3], [0, -0.3], [0, 0.3]]"\n'
            f"        linear_min: {lin_lo}\n        linear_max: {lin_hi}\n"
            f"        theta_min: {th_lo}\n        theta_max: {th_hi}\n"
        )
        if sectors is not None:
            start, end = sectors[i]
            text += f"        direction_start_angle: {start}\n        direction_end_angle: {end}\n"
    return parse_params(text).zones[0]


def _bands(uses: dict[str, list[Use]]) -> dict[str, list[tuple[str, float, float]]]:
    return {
        name: [(u.travel, float(u.low_mps), float(u.high_mps)) for u in found]
        for name, found in uses.items()
    }


def test_a_static_zone_is_used_at_every_speed_in_each_direction_the_robot_drives() -> None:
    zone = parse_params(
        'collision_monitor:\n  ros__parameters:\n    polygons: ["S"]\n'
        '    observation_sources: ["scan"]\n    S:\n      type: "circle"\n      radius: 0.5\n'
        '      action_type: "stop"\n'
    ).zones[0]
    assert _bands(zone_uses(zone, _limits("1", "0.3"))) == {
        "": [("forward", 0.0, 1.0), ("reverse", 0.0, 0.3)]
    }
    # A robot that moves sideways may meet an obstacle from any direction.
    assert _bands(zone_uses(zone, _limits("1", "0.3", lateral="0.2"))) == {"": [("any", 0.0, 1.2)]}


def test_the_first_matching_band_wins_like_nav2() -> None:
    # Nav2's documented example: "stopped" lists every speed but comes last.
    zone = _velocity_zone(
        [
            ("rotation", 0.0, 0.05, -1.0, 1.0),
            ("forward", 0.0, 1.0, -1.0, 1.0),
            ("backward", -1.0, 0.0, -1.0, 1.0),
            ("stopped", -1.0, 1.0, -1.0, 1.0),
        ]
    )
    uses = _bands(zone_uses(zone, _limits("0.5", "0.5", yaw="1")))
    assert uses["rotation"] == [("forward", 0.0, 0.05), ("reverse", 0.0, 0.0)]
    assert uses["forward"] == [("forward", 0.05, 0.5)]
    assert uses["backward"] == [("reverse", 0.0, 0.5)]
    assert uses["stopped"] == []


def test_velocities_no_band_holds_are_charged_to_every_band() -> None:
    # The robot turns at up to 2 rad/s, the bands only hold +-1 rad/s: Nav2 keeps the last
    # band whatever the speed, so each band may be in use at any speed.
    zone = _velocity_zone([("slow", 0.0, 0.3, -1.0, 1.0), ("fast", 0.3, 1.0, -1.0, 1.0)])
    uses = zone_uses(zone, _limits("1", yaw="2"))
    assert _bands(uses)["slow"] == [("forward", 0.0, 1.0)]
    assert "no sub-polygon holds" in uses["slow"][0].why
    # A band past the robot's top speed leaves a gap too.
    short = _velocity_zone([("slow", 0.0, 0.3, -1.0, 1.0), ("fast", 0.3, 0.8, -1.0, 1.0)])
    assert _bands(zone_uses(short, _limits("1")))["slow"] == [("forward", 0.0, 1.0)]


def test_holonomic_bands_need_their_sectors_to_cover_every_direction() -> None:
    bands = [("ahead", 0.0, 1.0, -1.0, 1.0), ("behind", 0.0, 1.0, -1.0, 1.0)]
    half = 1.5707963267948966
    # Two half-planes, wrapping through pi: every direction is held.
    covered = _velocity_zone(bands, holonomic=True, sectors=[(-half, half), (half, -half)])
    # Top speed 0.6 + 0.4 = 1 m/s: the bands hold every magnitude.
    robot = _limits("0.6", "0.6", lateral="0.4")
    assert _bands(zone_uses(covered, robot)) == {
        "ahead": [("any", 0.0, 1.0)],
        "behind": [("any", 0.0, 1.0)],
    }
    # Leave out part of the back: every band may be in use at every speed up to the top.
    gap = _velocity_zone(bands, holonomic=True, sectors=[(-half, half), (half, 3.0)])
    assert _bands(zone_uses(gap, robot))["ahead"] == [("any", 0.0, 1.0)]
    assert "no sub-polygon holds" in zone_uses(gap, robot)["ahead"][0].why
    # A faster robot outruns the bands: magnitudes above 1 m/s are a gap.
    assert _bands(zone_uses(covered, _limits("1", "1", lateral="0.5")))["ahead"] == [
        ("any", 0.0, 1.5)
    ]
