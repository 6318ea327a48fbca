"""Each zone and source as Nav2 reads it: every default, every key, every range (SR-NAV-4).

A zone is compared whole, so a default read wrong (a slowdown ratio of a third, an approach
step of a second), a key read under another name or a range that lets 0 through is seen. The
defaults are Nav2's (configuring-collision-monitor-node).
"""

from __future__ import annotations

from fractions import Fraction

import pytest

from safety.nav2.params import Source, Zone, parse_params
from safety.nav2.reader import Nav2ParamsError

CODE = ["safety/nav2/params.py"]
HEAD = """collision_monitor:
  ros__parameters:
    observation_sources: ["scan"]
    polygons: ["Z"]
    Z:
"""
CIRCLE = 'type: "circle"\nradius: 1.5\n'


def _zone(body: str) -> Zone:
    text = HEAD + "".join(f"      {line}\n" for line in body.splitlines())
    (zone,) = parse_params(text).zones
    return zone


def _refused(body: str) -> str:
    with pytest.raises(Nav2ParamsError) as caught:
        _zone(body)
    return str(caught.value)


R = Fraction("1.5")


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_each_action_takes_nav2s_defaults() -> None:
    assert _zone(CIRCLE + 'action_type: "stop"') == Zone("Z", "circle", "stop", True, 4, radius_m=R)
    assert _zone(CIRCLE + 'action_type: "slowdown"') == Zone(
        "Z", "circle", "slowdown", True, 4, radius_m=R, slowdown_ratio=Fraction(1, 2)
    )
    assert _zone(CIRCLE + 'action_type: "limit"') == Zone(
        "Z", "circle", "limit", True, 4, radius_m=R, linear_limit_mps=Fraction(1, 2)
    )
    assert _zone(CIRCLE + 'action_type: "approach"') == Zone(
        "Z",
        "circle",
        "approach",
        True,
        4,
        radius_m=R,
        time_before_collision_s=Fraction(2),
        simulation_time_step_s=Fraction(1, 10),
    )
    assert _zone('type: "polygon"\naction_type: "approach"') == Zone(
        "Z",
        "polygon",
        "approach",
        True,
        4,
        dynamic_topic="local_costmap/published_footprint",
        time_before_collision_s=Fraction(2),
        simulation_time_step_s=Fraction(1, 10),
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_each_key_given_is_read() -> None:
    assert _zone(
        CIRCLE + 'action_type: "approach"\ntime_before_collision: 1.5\n'
        "simulation_time_step: 0.05\nmin_points: 2\nenabled: false"
    ) == Zone(
        "Z",
        "circle",
        "approach",
        False,
        2,
        radius_m=R,
        time_before_collision_s=Fraction(1.5),
        simulation_time_step_s=Fraction(0.05),
    )
    assert _zone(CIRCLE + 'action_type: "slowdown"\nslowdown_ratio: 0.25').slowdown_ratio == (
        Fraction(1, 4)
    )
    assert _zone(CIRCLE + 'action_type: "limit"\nlinear_limit: 0.75').linear_limit_mps == (
        Fraction(3, 4)
    )
    assert (
        _zone('type: "polygon"\naction_type: "approach"\nfootprint_topic: "fp"').dynamic_topic
        == "fp"
    )
    # Humble's max_points counts the points that are still allowed: one more stops.
    assert _zone(CIRCLE + 'action_type: "stop"\nmax_points: 0').min_points == 1
    assert _zone(CIRCLE + 'action_type: "stop"\nmax_points: 5\nmin_points: 2').min_points == 6
    holonomic = _zone(
        'type: "velocity_polygon"\naction_type: "stop"\nholonomic: true\n'
        'velocity_polygons: ["b"]\nb:\n  points: "[[1, 1], [1, -1], [0, 0]]"\n'
        "  linear_min: 0.0\n  linear_max: 1.0\n  theta_min: -1.0\n  theta_max: 1.0"
    )
    assert holonomic.holonomic
    plain = _zone(
        'type: "velocity_polygon"\naction_type: "stop"\n'
        'velocity_polygons: ["b"]\nb:\n  points: "[[1, 1], [1, -1], [0, 0]]"\n'
        "  linear_min: 0.0\n  linear_max: 1.0\n  theta_min: -1.0\n  theta_max: 1.0"
    )
    assert plain.holonomic is False
    assert [s.name for s in plain.subpolygons] == ["b"]


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            'type: "circle"\nradius: 0.0\naction_type: "stop"',
            "collision_monitor.Z.radius = 0.0: allowed: a number in (0, 10000]",
        ),
        (
            CIRCLE + 'action_type: "approach"\nsimulation_time_step: 0.0',
            "collision_monitor.Z.simulation_time_step = 0.0: allowed: a number in (0, 10000]",
        ),
        (
            CIRCLE + 'action_type: "approach"\ntime_before_collision: 0.0',
            "collision_monitor.Z.time_before_collision = 0.0: allowed: a number in (0, 10000]",
        ),
        (
            CIRCLE + 'action_type: "limit"\nlinear_limit: -0.1',
            "collision_monitor.Z.linear_limit = -0.1: allowed: a number in [0, 10000]",
        ),
        (
            CIRCLE + 'action_type: "slowdown"\nslowdown_ratio: 1.5',
            "collision_monitor.Z.slowdown_ratio = 1.5: allowed: a number in [0, 1]",
        ),
        (
            CIRCLE + 'action_type: "slowdown"\nslowdown_ratio: -0.5',
            "collision_monitor.Z.slowdown_ratio = -0.5: allowed: a number in [0, 1]",
        ),
        (
            CIRCLE + 'action_type: "stop"\nmax_points: -1',
            "collision_monitor.Z.max_points = -1: allowed: an integer >= 0",
        ),
        (
            CIRCLE + 'action_type: "stop"\nenabled: "yes"',
            "collision_monitor.Z.enabled = 'yes': allowed: true or false",
        ),
        (
            'type: "velocity_polygon"\naction_type: "stop"',
            "collision_monitor.Z.velocity_polygons = None: allowed: a list of distinct names",
        ),
        (
            'type: "circle"\naction_type: "stop"',
            "collision_monitor.Z.radius = None: allowed: the radius of the zone, or a "
            "polygon_sub_topic",
        ),
    ],
)
def test_a_value_out_of_range_is_refused_naming_the_key(body: str, message: str) -> None:
    assert _refused(body) == message


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_shape_given_by_topic_is_read_for_a_circle_too() -> None:
    assert _zone('type: "circle"\naction_type: "stop"\npolygon_sub_topic: "zone"') == Zone(
        "Z", "circle", "stop", True, 4, dynamic_topic="zone"
    )


SOURCES = """collision_monitor:
  ros__parameters:
    polygons: ["Z"]
    Z:
      type: "circle"
      radius: 1.0
      action_type: "stop"
"""


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_each_source_takes_its_own_keys_or_the_nodes_defaults() -> None:
    params = parse_params(
        SOURCES + '    observation_sources: ["front", "rear", "cloud"]\n'
        "    source_timeout: 0.5\n"
        '    rear:\n      type: "scan"\n      source_timeout: 0.25\n      enabled: false\n'
        '    cloud:\n      type: "pointcloud"\n'
    )
    assert params.sources == (
        Source("front", "scan", True, Fraction(1, 2)),
        Source("rear", "scan", False, Fraction(1, 4)),
        Source("cloud", "pointcloud", True, Fraction(1, 2)),
    )
    default = parse_params(SOURCES + '    observation_sources: ["front"]\n')
    assert default.sources == (Source("front", "scan", True, Fraction(2)),)
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(SOURCES)
    assert str(caught.value) == (
        "collision_monitor.observation_sources = None: allowed: a list of distinct names"
    )
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(
            SOURCES + '    observation_sources: ["front"]\n    front:\n      type: "sonar"\n'
        )
    assert str(caught.value) == (
        "collision_monitor.front.type = 'sonar': allowed: scan | pointcloud | range | polygon"
    )
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(SOURCES + '    observation_sources: ["front"]\n    source_timeout: -1.0\n')
    assert str(caught.value) == (
        "collision_monitor.source_timeout = -1.0: allowed: a number in [0, 10000]"
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_the_file_names_its_frame_its_polygons_and_itself() -> None:
    params = parse_params(
        HEAD + "      " + CIRCLE.replace("\n", "\n      ") + 'action_type: "stop"\n'
    )
    assert (params.name, params.base_frame_id) == ("<text>", "base_footprint")
    framed = parse_params(
        HEAD.replace("    Z:\n", '    base_frame_id: "base_link"\n    Z:\n')
        + '      type: "circle"\n      radius: 1.0\n      action_type: "stop"\n',
        "robot.yaml",
    )
    assert (framed.name, framed.base_frame_id) == ("robot.yaml", "base_link")
    no_list = HEAD.replace('    polygons: ["Z"]\n', "")
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(
            no_list + '      type: "circle"\n      radius: 1.0\n      action_type: "stop"\n'
        )
    assert (
        str(caught.value) == "collision_monitor.polygons = None: allowed: a list of distinct names"
    )
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(HEAD)
    assert str(caught.value) == (
        "collision_monitor.Z = None: allowed: a mapping with the polygon's type and action_type "
        "(it is listed in polygons)"
    )
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(HEAD.replace("    Z:\n", "    Z: 5\n"))
    assert str(caught.value) == "collision_monitor.Z = 5: allowed: a mapping of its parameters"
