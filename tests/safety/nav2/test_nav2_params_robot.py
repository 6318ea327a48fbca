"""The robot's limits as the parameter file gives them, each with its source (SR-NAV-4).

``nav2 check`` proves zones for the speeds the robot can reach; those come from the velocity
smoother and the controller's plugins, and the report names where each came from. Every key
the reader knows is met alone here, so a key read from the wrong place, with the wrong sign or
under the wrong name is seen.
"""

from __future__ import annotations

from fractions import Fraction

import pytest

from safety.nav2.params import Limit, Nav2Params, parse_params
from safety.nav2.reader import Nav2ParamsError

CODE = ["safety/nav2/params.py"]
MONITOR = """collision_monitor:
  ros__parameters:
    observation_sources: ["scan"]
    polygons: ["S"]
    S:
      type: "circle"
      action_type: "stop"
      radius: 1.0
"""


def _params(extra: str) -> Nav2Params:
    return parse_params(MONITOR + extra)


def _limits(params: Nav2Params) -> dict[str, Limit | None]:
    return {
        "forward": params.forward,
        "reverse": params.reverse,
        "lateral": params.lateral,
        "yaw_rate": params.yaw_rate,
        "control_period": params.control_period,
    }


PLUGIN_KEYS = [
    ("max_vel_x", 0.7, "forward", 0.7),
    ("vx_max", 0.7, "forward", 0.7),
    ("desired_linear_vel", 0.7, "forward", 0.7),
    ("min_vel_x", -0.3, "reverse", 0.3),
    ("vx_min", -0.3, "reverse", 0.3),
    ("max_vel_y", 0.2, "lateral", 0.2),
    ("vy_max", 0.2, "lateral", 0.2),
    ("max_vel_theta", 1.5, "yaw_rate", 1.5),
    ("wz_max", 1.5, "yaw_rate", 1.5),
]


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
@pytest.mark.parametrize(("key", "value", "field", "limit"), PLUGIN_KEYS)
def test_each_controller_key_sets_its_own_limit(
    key: str, value: float, field: str, limit: float
) -> None:
    params = _params(
        f"controller_server:\n  ros__parameters:\n    FollowPath:\n      {key}: {value}\n"
    )
    expected: dict[str, Limit | None] = dict.fromkeys(_limits(params))
    expected[field] = Limit(Fraction(limit), f"controller_server.FollowPath.{key}")
    assert _limits(params) == expected


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_the_smoother_and_the_named_plugins_give_the_largest_with_every_source() -> None:
    """The largest of each (a robot is as fast as its fastest limit lets it be), with every
    place that gave one; the slowest of the two rates sets the control period. A plugin not
    listed in controller_plugins is not read."""
    params = _params(
        "velocity_smoother:\n  ros__parameters:\n    smoothing_frequency: 20.0\n"
        "    max_velocity: [0.5, 0.2, 2.0]\n    min_velocity: [-0.35, -0.3, -2.5]\n"
        "controller_server:\n  ros__parameters:\n    controller_frequency: 10.0\n"
        '    controller_plugins: ["Ctrl"]\n'
        "    Ctrl:\n      vx_max: 0.6\n      vy_max: 0.25\n      wz_max: 1.9\n"
        "      vx_min: -0.2\n"
        "    FollowPath:\n      vx_max: 3.0\n"
    )
    smoother, ctrl = "velocity_smoother", "controller_server.Ctrl"
    assert _limits(params) == {
        "forward": Limit(Fraction(0.6), f"{smoother}.max_velocity[0], {ctrl}.vx_max"),
        "reverse": Limit(Fraction(0.35), f"{smoother}.min_velocity[0], {ctrl}.vx_min"),
        "lateral": Limit(
            Fraction(0.3),
            f"{smoother}.max_velocity[1], {smoother}.min_velocity[1], {ctrl}.vy_max",
        ),
        "yaw_rate": Limit(
            Fraction(5, 2),
            f"{smoother}.max_velocity[2], {smoother}.min_velocity[2], {ctrl}.wz_max",
        ),
        "control_period": Limit(Fraction(1, 10), "1 / controller_server.controller_frequency"),
    }


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_robot_that_never_reverses_has_a_reverse_limit_of_zero() -> None:
    params = _params(
        "velocity_smoother:\n  ros__parameters:\n"
        "    max_velocity: [0.5, 0.0, 1.0]\n    min_velocity: [0.1, 0.0, -1.0]\n"
    )
    assert params.reverse == Limit(Fraction(0), "velocity_smoother.min_velocity[0]")
    assert params.lateral == Limit(
        Fraction(0), "velocity_smoother.max_velocity[1], velocity_smoother.min_velocity[1]"
    )
    assert params.control_period is None


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_rate_must_be_positive_and_the_slower_rate_sets_the_period() -> None:
    slow = _params("velocity_smoother:\n  ros__parameters:\n    smoothing_frequency: 0.5\n")
    assert slow.control_period == Limit(Fraction(2), "1 / velocity_smoother.smoothing_frequency")
    for node, key in (
        ("velocity_smoother", "smoothing_frequency"),
        ("controller_server", "controller_frequency"),
    ):
        with pytest.raises(Nav2ParamsError) as caught:
            _params(f"{node}:\n  ros__parameters:\n    {key}: 0\n")
        assert str(caught.value) == f"{node}.{key} = 0: allowed: a number in (0, 10000]"
    both = _params(
        "velocity_smoother:\n  ros__parameters:\n    smoothing_frequency: 5.0\n"
        "controller_server:\n  ros__parameters:\n    controller_frequency: 20.0\n"
    )
    assert both.control_period == Limit(Fraction(1, 5), "1 / velocity_smoother.smoothing_frequency")


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_listed_plugin_without_a_section_gives_nothing_and_follow_path_is_the_default() -> None:
    listed = _params(
        "controller_server:\n  ros__parameters:\n"
        '    controller_plugins: ["Missing"]\n    FollowPath:\n      vx_max: 3.0\n'
    )
    assert listed.forward is None
    default = _params(
        "controller_server:\n  ros__parameters:\n    FollowPath:\n      vx_max: 3.0\n"
    )
    assert default.forward == Limit(Fraction(3), "controller_server.FollowPath.vx_max")
