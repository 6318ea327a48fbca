"""Reading a Nav2 collision_monitor parameter file (SR-NAV-4): layout, encodings, errors."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from safety.nav2.params import load_params, parse_params
from safety.nav2.reader import Nav2ParamsError, nearest_float32

CODE = ["safety/nav2/params.py", "safety/nav2/reader.py"]
EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "nav2"

HEAD = """collision_monitor:
  ros__parameters:
    polygons: ["Stop"]
    observation_sources: ["scan"]
"""


def _zone(body: str, head: str = HEAD) -> str:
    return head + "    Stop:\n" + "".join(f"      {line}\n" for line in body.splitlines())


STOP = 'type: "polygon"\naction_type: "stop"\npoints: "[[0.4, 0.3], [0.4, -0.3], [0.0, -0.3]]"'


def test_both_point_encodings_give_nav2s_own_values() -> None:
    string = parse_params(_zone(STOP)).zones[0]
    flat = parse_params(
        _zone('type: "polygon"\naction_type: "stop"\npoints: [0.4, 0.3, 0.4, -0.3, 0.0, -0.3]')
    ).zones[0]
    assert string.vertices is not None
    assert flat.vertices is not None
    # The string is read as single-precision floats (parseVVF), the list as doubles.
    assert string.vertices[0] == (
        Fraction(float(np.float32(0.4))),
        Fraction(float(np.float32(0.3))),
    )
    assert flat.vertices[0] == (Fraction(0.4), Fraction(0.3))
    assert [float(x) for v in string.vertices for x in v] == pytest.approx(
        [float(x) for v in flat.vertices for x in v], abs=1e-7
    )


def test_nearest_float32_rounds_to_nearest_with_ties_to_even() -> None:
    for text in ("0.1", "0.7", "1.15", "-0.35", "123.456", "0"):
        assert nearest_float32(Fraction(text)) == Fraction(float(np.float32(float(text))))
    # Halfway between 1 and the next float32 (1 + 2^-23): ties go to the even mantissa, 1.
    assert nearest_float32(1 + Fraction(1, 2**24)) == 1


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_the_tutorial_file_reads_with_nav2s_defaults() -> None:
    params = load_params(EXAMPLES / "tutorial.yaml")
    stop, slow = params.zones
    assert (stop.name, stop.shape, stop.action, stop.min_points) == (
        "PolygonStop",
        "polygon",
        "stop",
        4,
    )
    assert (slow.action, slow.slowdown_ratio) == ("slowdown", Fraction(0.3))
    assert params.data_age_bound_s() == 5
    assert params.base_frame_id == "base_footprint"
    assert params.forward is None
    assert params.control_period is None


def test_max_points_is_min_points_less_one_and_sources_override_the_timeout() -> None:
    text = _zone(STOP + "\nmax_points: 3").replace(
        'observation_sources: ["scan"]',
        'source_timeout: 1.0\n    observation_sources: ["scan", "cloud"]\n'
        "    scan:\n      source_timeout: 0.2\n    cloud:\n      type: pointcloud",
    )
    params = parse_params(text)
    assert params.zones[0].min_points == 4
    assert [s.timeout_s for s in params.sources] == [Fraction(0.2), Fraction(1)]
    assert params.data_age_bound_s() == 1
    zero = parse_params(text.replace("source_timeout: 0.2", "source_timeout: 0.0"))
    assert zero.data_age_bound_s() is None


def test_speed_limits_come_from_the_smoother_and_the_controller() -> None:
    text = _zone(STOP) + (
        "velocity_smoother:\n  ros__parameters:\n    smoothing_frequency: 20.0\n"
        "    max_velocity: [0.5, 0.0, 2.0]\n    min_velocity: [-0.35, 0.0, -2.0]\n"
        "controller_server:\n  ros__parameters:\n    controller_frequency: 10.0\n"
        '    controller_plugins: ["FollowPath"]\n'
        "    FollowPath:\n      vx_max: 0.6\n      vx_min: -0.2\n      wz_max: 1.9\n"
    )
    params = parse_params(text)
    assert params.forward is not None
    assert params.reverse is not None
    assert params.yaw_rate is not None
    assert params.control_period is not None
    assert params.forward.value == Fraction(0.6)
    assert "FollowPath.vx_max" in params.forward.source
    assert params.reverse.value == Fraction(0.35)
    assert params.yaw_rate.value == 2
    # The monitor runs as often as the slower of the two feeds it.
    assert params.control_period.value == Fraction(1, 10)


def test_velocity_polygons_and_unlisted_zones() -> None:
    text = HEAD.replace('["Stop"]', '["Vel"]') + (
        '    Vel:\n      type: "velocity_polygon"\n      action_type: "stop"\n'
        '      velocity_polygons: ["slow", "fast"]\n'
        '      slow:\n        points: "[[0.3, 0.3], [0.3, -0.3], [0.0, -0.3], [0.0, 0.3]]"\n'
        "        linear_min: 0.0\n        linear_max: 0.5\n        theta_min: -1.0\n"
        "        theta_max: 1.0\n"
        '      fast:\n        points: "[[0.6, 0.3], [0.6, -0.3], [0.0, -0.3], [0.0, 0.3]]"\n'
        "        linear_min: 0.5\n        linear_max: 1.0\n        theta_min: -1.0\n"
        "        theta_max: 1.0\n"
        '    Spare:\n      type: "circle"\n      radius: 0.3\n      action_type: "stop"\n'
    )
    params = parse_params(text)
    (vel,) = params.zones
    assert [s.name for s in vel.subpolygons] == ["slow", "fast"]
    assert vel.subpolygons[1].linear_min_mps == Fraction(0.5)
    assert params.unlisted == ("Spare",)


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("a: [", "not valid YAML: "),
        ("- 1\n- 2\n", "the document is list"),
        ("other_node:\n  ros__parameters: {}\n", "no `collision_monitor: ros__parameters:`"),
        ("collision_monitor: 3\n", "collision_monitor = 3: expected a mapping"),
        (HEAD.replace('["Stop"]', "[]"), "collision_monitor.polygons = []: allowed: a list of"),
        (HEAD.replace('["Stop"]', '["Stop", "Stop"]'), "allowed: a list of distinct names"),
        (HEAD, "collision_monitor.Stop = None: allowed: a mapping with the polygon's type"),
        (_zone(STOP.replace('"polygon"', '"square"')), "Stop.type = 'square': allowed: polygon"),
        (_zone(STOP.replace('"stop"', '"halt"')), "Stop.action_type = 'halt': allowed: stop"),
        (_zone(STOP.replace("0.4, 0.3]", "0.4]")), "Stop.points = '[[0.4], [0.4, -0.3]"),
        (_zone(STOP.replace("0.4, 0.3]", "nan, 0.3]")), "Stop.points = '[[nan, 0.3]"),
        (_zone(STOP.replace(", [0.0, -0.3]]", "]")), "with at least 3 vertices"),
        (
            _zone('type: "polygon"\naction_type: "stop"\npoints: [0.4, 0.3, 0.4]'),
            "Stop.points = [0.4, 0.3, 0.4]: allowed:",
        ),
        (
            _zone('type: "polygon"\naction_type: "stop"\npoints: [.inf, 0, 1, 0, 1, 1]'),
            "Stop.points = inf: allowed: a number in",
        ),
        (_zone(STOP.replace("0.4, 0.3]", "1e9, 0.3]")), "coordinates within +-10000 m"),
        (
            _zone(
                'type: "polygon"\naction_type: "stop"\npoints: ['
                + ", ".join(f"{i}, {i * i % 97}" for i in range(257))
                + "]"
            ),
            "allowed: at most 256 vertices",
        ),
        (_zone('type: "circle"\naction_type: "stop"\nradius: -0.3'), "Stop.radius = -0.3: "),
        (_zone('type: "circle"\naction_type: "stop"\nradius: true'), "Stop.radius = True: "),
        (_zone('type: "circle"\naction_type: "stop"'), "Stop.radius = None: allowed: the radius"),
        (_zone('type: "polygon"\naction_type: "stop"'), "Stop.points = None: allowed: the points"),
        (_zone(STOP + "\nmin_points: 0"), "Stop.min_points = 0: allowed: an integer >= 1"),
        (_zone(STOP + "\nenabled: 1"), "Stop.enabled = 1: allowed: true or false"),
        (
            _zone(STOP.replace("stop", "slowdown") + "\nslowdown_ratio: 1.5"),
            "Stop.slowdown_ratio = 1.5: allowed: a number in [0, 1]",
        ),
        (
            _zone('type: "circle"\naction_type: "approach"\nradius: 0.3\ntime_before_collision: 0'),
            "Stop.time_before_collision = 0: allowed: a number in (0,",
        ),
        (
            _zone('type: "velocity_polygon"\naction_type: "stop"\nvelocity_polygons: ["a"]'),
            "collision_monitor.Stop.a = None: allowed: a mapping",
        ),
        (
            _zone(
                'type: "velocity_polygon"\naction_type: "stop"\nvelocity_polygons: ["a"]\na:\n'
                '  points: "[[1, 1], [1, -1], [0, 0]]"\n  linear_min: 0.5\n  linear_max: 0.2\n'
                "  theta_min: -1.0\n  theta_max: 1.0"
            ),
            "Stop.a.linear_max = 0.2: allowed: a number >= linear_min (0.5)",
        ),
        (
            _zone(
                'type: "velocity_polygon"\naction_type: "stop"\nvelocity_polygons: ["a"]\na:\n'
                '  points: "[[1, 1], [1, -1], [0, 0]]"\n  linear_min: 0.0\n  linear_max: 0.2\n'
                "  theta_min: -1.0"
            ),
            "Stop.a.theta_max = None: allowed: a number (required)",
        ),
        (
            _zone(STOP).replace('["scan"]', '"scan"'),
            "collision_monitor.observation_sources = 'scan': allowed: a list of distinct names",
        ),
        (
            _zone(STOP) + "    scan:\n      source_timeout: -1\n",
            "collision_monitor.scan.source_timeout = -1: allowed: a number in [0,",
        ),
        (
            _zone(STOP) + "velocity_smoother:\n  ros__parameters:\n    max_velocity: [0.5, 0]\n",
            "velocity_smoother.max_velocity = [0.5, 0]: allowed: a list of three numbers",
        ),
        (
            _zone(STOP) + "controller_server:\n  ros__parameters:\n    controller_frequency: 0\n",
            "controller_server.controller_frequency = 0: allowed: a number in (0,",
        ),
    ],
)
def test_malformed_files_get_one_line_naming_key_value_and_what_is_allowed(
    tmp_path: Path, text: str, expected: str
) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(text)
    with pytest.raises(Nav2ParamsError) as caught:
        load_params(path)
    message = str(caught.value)
    assert "\n" not in message
    assert expected in message, message


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_unreadable_files_are_named(tmp_path: Path) -> None:
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(b"collision_monitor: \xe9\n")
    cases = {
        tmp_path / "missing.yaml": "cannot read the parameter file: no such file",
        tmp_path: "cannot read the parameter file: not a regular file",
        latin: "not UTF-8 text (byte 19)",
    }
    for path, expected in cases.items():
        with pytest.raises(Nav2ParamsError, match="^" + str(path)) as caught:
            load_params(path)
        assert expected in str(caught.value)
