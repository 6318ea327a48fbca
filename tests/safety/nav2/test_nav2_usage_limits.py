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
