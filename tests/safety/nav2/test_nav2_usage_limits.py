"""Which limits and speeds a zone is checked at (SR-NAV-1): the command line first, and
sideways travel with a velocity polygon that selects by x alone."""

from __future__ import annotations

from fractions import Fraction

import pytest

from pipeline.config import default_config
from safety.nav2.params import Limit, parse_params
from safety.nav2.usage import Overrides, RobotLimits, Use, resolve_limits, zone_uses

CODE = ["safety/nav2/usage.py"]
F = Fraction
HEAD = 'collision_monitor:\n  ros__parameters:\n    observation_sources: ["scan"]\n'
STOP = (
    '    polygons: ["Stop"]\n    Stop:\n      type: "polygon"\n      action_type: "stop"\n'
    '      points: "[[0.5, 0.3], [0.5, -0.3], [0, -0.3], [0, 0.3]]"\n'
)
SMOOTHER = (
    "velocity_smoother:\n  ros__parameters:\n"
    "    max_velocity: [0.8, 0.1, 1.5]\n    min_velocity: [-0.3, -0.1, -1.5]\n"
)


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_the_command_line_overrides_the_file_and_the_file_the_configuration() -> None:
    config = default_config()
    with_file = parse_params(HEAD + STOP + SMOOTHER)
    cli = Overrides(F("0.7"), F("0.2"), F("0.05"), F("0.9"))
    assert resolve_limits(with_file, config, cli) == RobotLimits(
        Limit(F("0.7"), "--max-speed"),
        Limit(F("0.2"), "--max-reverse-speed"),
        Limit(F("0.05"), "--max-lateral-speed"),
        Limit(F("0.9"), "--max-yaw-rate"),
    )
    from_file = resolve_limits(with_file, config, Overrides())
    assert from_file.forward == Limit(F(0.8), "velocity_smoother.max_velocity[0]")
    assert from_file.reverse == Limit(F(0.3), "velocity_smoother.min_velocity[0]")
    assert from_file.lateral.value == F(0.1)
    assert from_file.yaw_rate.value == F(1.5)
    fallback = resolve_limits(parse_params(HEAD + STOP), config, Overrides())
    assert fallback == RobotLimits(
        Limit(F(1), "stopping.robot_max_speed_mps; the file gives none"),
        Limit(F(0), "the file gives none: no reversing; check it with --max-reverse-speed"),
        Limit(F(0), "the file gives none: no sideways travel"),
        Limit(F(1), "geometry.max_yaw_rate_radps; the file gives none"),
    )


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_robot_that_moves_sideways_may_add_its_lateral_speed_to_any_band() -> None:
    """Nav2 picks the band by the commanded x alone; a robot that also translates sideways at
    up to 0.2 m/s may travel in any direction at up to |x| + 0.2 m/s (capped at its top speed,
    1.2 m/s) while a band is selected."""
    text = (
        HEAD + '    polygons: ["V"]\n    V:\n      type: "velocity_polygon"\n'
        '      action_type: "stop"\n      velocity_polygons: ["slow", "fast"]\n'
    )
    for name, low, high in (("slow", 0.0, 0.5), ("fast", 0.5, 1.0)):
        text += (
            f'      {name}:\n        points: "[[1, 0.4], [1, -0.4], [0, -0.4], [0, 0.4]]"\n'
            f"        linear_min: {low}\n        linear_max: {high}\n"
            "        theta_min: -1.0\n        theta_max: 1.0\n"
        )
    zone = parse_params(text).zones[0]
    robot = RobotLimits(
        Limit(F(1), "test"), Limit(F(0), "test"), Limit(F("0.2"), "test"), Limit(F(1), "test")
    )
    assert zone_uses(zone, robot) == {
        "slow": [Use("any", F(0), F("0.7"), "commanded |x| up to 0.5 m/s")],
        "fast": [Use("any", F(0), F("1.2"), "commanded |x| up to 1 m/s")],
    }


def _robot(forward: str, reverse: str, lateral: str = "0") -> RobotLimits:
    return RobotLimits(
        Limit(F(forward), "test"),
        Limit(F(reverse), "test"),
        Limit(F(lateral), "test"),
        Limit(F(1), "test"),
    )


def _bands(names: list[tuple[str, float, float]], sectors: list[tuple[float, float]] | None) -> str:
    text = (
        HEAD + '    polygons: ["V"]\n    V:\n      type: "velocity_polygon"\n'
        f'      action_type: "stop"\n      holonomic: {"true" if sectors else "false"}\n'
        f"      velocity_polygons: [{', '.join(repr(n) for n, _, _ in names)}]\n"
    ).replace("'", '"')
    for i, (name, low, high) in enumerate(names):
        text += (
            f'      {name}:\n        points: "[[1, 0.4], [1, -0.4], [0, -0.4], [0, 0.4]]"\n'
            f"        linear_min: {low}\n        linear_max: {high}\n"
            "        theta_min: -1.0\n        theta_max: 1.0\n"
        )
        if sectors:
            start, end = sectors[i]
            text += f"        direction_start_angle: {start}\n        direction_end_angle: {end}\n"
    return text


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_static_zone_is_used_at_every_speed_the_robot_has_each_way() -> None:
    zone = parse_params(HEAD + STOP).zones[0]
    assert zone_uses(zone, _robot("1", "0.5")) == {
        "": [
            Use("forward", F(0), F(1), "every forward speed"),
            Use("reverse", F(0), F("0.5"), "every reverse speed"),
        ]
    }
    assert zone_uses(zone, _robot("0", "0.5")) == {
        "": [Use("reverse", F(0), F("0.5"), "every reverse speed")]
    }
    assert zone_uses(zone, _robot("1", "0")) == {
        "": [Use("forward", F(0), F(1), "every forward speed")]
    }
    assert zone_uses(zone, _robot("1", "0.5", lateral="0.2")) == {
        "": [Use("any", F(0), F("1.2"), "every velocity of the robot")]
    }


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_directional_bands_are_charged_the_commanded_x_they_hold_each_way() -> None:
    """A backward band holds standstill first (Nav2's first match), so it is in use for the
    commanded x = 0 too; a robot faster than the last band makes every band carry the speeds no
    band holds."""
    text = _bands([("back", -0.5, 0.0), ("slow", 0.0, 0.5), ("fast", 0.5, 1.0)], None)
    zone = parse_params(text).zones[0]
    assert zone_uses(zone, _robot("1", "0.5")) == {
        "back": [
            Use("forward", F(0), F(0), "commanded x in [0, 0] m/s"),
            Use("reverse", F(0), F("0.5"), "commanded -x in [0, 0.5] m/s"),
        ],
        "slow": [Use("forward", F(0), F("0.5"), "commanded x in [0, 0.5] m/s")],
        "fast": [Use("forward", F("0.5"), F(1), "commanded x in [0.5, 1] m/s")],
    }
    gap = " (with the velocities no sub-polygon holds)"
    faster = zone_uses(zone, _robot("1.2", "0.5"))
    assert faster["fast"] == [
        Use("forward", F("0.5"), F("1.2"), f"commanded x in [0.5, 1.2] m/s{gap}")
    ]
    assert faster["back"][1] == Use("reverse", F(0), F("0.5"), f"commanded -x in [0, 0.5] m/s{gap}")


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_holonomic_sectors_that_meet_exactly_cover_every_direction() -> None:
    """Two half-planes meeting at +-pi/2, the second wrapping through pi: every direction is
    held, with no gap; leave out part of the back and both bands carry the gap."""
    half = 1.5707963267948966
    names = [("ahead", 0.0, 1.0), ("behind", 0.0, 1.0)]
    robot = _robot("0.6", "0.6", lateral="0.4")
    covered = parse_params(_bands(names, [(-half, half), (half, -half)])).zones[0]
    whole = [Use("any", F(0), F(1), "speed magnitudes [0, 1] m/s")]
    assert zone_uses(covered, robot) == {"ahead": whole, "behind": whole}
    gap = parse_params(_bands(names, [(-half, half), (half, 3.0)])).zones[0]
    carried = [
        Use(
            "any",
            F(0),
            F(1),
            "speed magnitudes [0, 1] m/s (with the velocities no sub-polygon holds)",
        )
    ]
    assert zone_uses(gap, robot) == {"ahead": carried, "behind": carried}


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_band_is_charged_only_the_directions_the_robot_drives() -> None:
    """A robot that only reverses charges standstill to reversing; a band of reverse speeds
    away from standstill is charged from its slower end (0.2 m/s), not from 0."""
    text = _bands([("back", -0.5, 0.0), ("slow", 0.0, 0.5), ("fast", 0.5, 1.0)], None)
    zone = parse_params(text).zones[0]
    assert zone_uses(zone, _robot("0", "0.5")) == {
        "back": [Use("reverse", F(0), F("0.5"), "commanded -x in [0, 0.5] m/s")],
        "slow": [],
        "fast": [],
    }
    away = parse_params(_bands([("far", -0.5, -0.2), ("rest", -0.2, 1.0)], None)).zones[0]
    far = zone_uses(away, _robot("1", "0.5"))["far"]
    assert far == [Use("reverse", F(0.2), F("0.5"), "commanded -x in [0.2, 0.5] m/s")]
