"""Polygon points and velocity bands, refused with the key, the value and what is allowed
(SR-NAV-4).

Each malformed ``points`` and each bad band is met alone; the whole one-line error is compared,
so an error that names the wrong key, drops the value or says nothing of what is allowed is
seen.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np
import pytest

from safety.nav2.params import MAX_VERTICES, PI, SubPolygon, parse_params
from safety.nav2.reader import Nav2ParamsError

CODE = ["safety/nav2/params.py"]
ALLOWED = '"[[x, y], [x, y], ...]" with at least 3 vertices, or a flat list [x1, y1, x2, y2, ...]'
HEAD = """collision_monitor:
  ros__parameters:
    observation_sources: ["scan"]
    polygons: ["Stop"]
    Stop:
      type: "polygon"
      action_type: "stop"
"""


def _refused(points: str) -> str:
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(HEAD + f"      points: {points}\n")
    return str(caught.value)


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("points", "value"),
    [
        ('"[[1, 0], [0, 1]]"', "'[[1, 0], [0, 1]]'"),
        ('"[[1, 0], [0, 1], [1, 0]]"', "'[[1, 0], [0, 1], [1, 0]]'"),
        ('"[[1, 0], [0, 1], [0, 0]"', "'[[1, 0], [0, 1], [0, 0]'"),
        ('"[[1, 0], [0, x], [0, 0]]"', "'[[1, 0], [0, x], [0, 0]]'"),
        ("[1, 0, 0, 1, 0]", "[1, 0, 0, 1, 0]"),
        ("[1, 0, 0, 1]", "[1, 0, 0, 1]"),
        ("7", "7"),
        ("{a: 1}", "{'a': 1}"),
    ],
)
def test_points_that_are_not_three_vertices_are_refused_saying_what_is_allowed(
    points: str, value: str
) -> None:
    assert _refused(points) == f"collision_monitor.Stop.points = {value}: allowed: {ALLOWED}"


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_missing_points_are_refused_naming_the_key() -> None:
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params(HEAD)
    assert str(caught.value) == (
        "collision_monitor.Stop.points = None: allowed: the points of the zone, or a "
        "polygon_sub_topic"
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_points_string_is_read_up_to_its_length_limit() -> None:
    """At most 100,000 characters (without spaces) are read; what fits in them is then held
    to the vertex limit."""

    def points(length: int) -> str:
        """Distinct vertices, the first x padded with zeros to make ``length`` characters."""
        pairs = [f"[{i % 100},{i // 100}]" for i in range(12_000)]
        text = "[" + ",".join(pairs) + "]"
        cut = text.rindex("],[", 0, length - 10) + 1
        text = text[:cut] + "]"
        return "[[0." + "0" * (length - len(text) - 1) + text[3:]

    assert len(points(100_000)) == 100_000
    assert _refused(f'"{points(100_000)}"').endswith(f": allowed: at most {MAX_VERTICES} vertices")
    assert len(points(100_001)) == 100_001
    assert _refused(f'"{points(100_001)}"').endswith(f": allowed: {ALLOWED}")


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_coordinates_beyond_ten_kilometres_are_refused_and_ten_is_allowed() -> None:
    edge = parse_params(HEAD + '      points: "[[10000, 0], [0, 1], [-10000, 0]]"\n')
    assert edge.zones[0].vertices == (
        (Fraction(10000), Fraction(0)),
        (Fraction(0), Fraction(1)),
        (Fraction(-10000), Fraction(0)),
    )
    assert _refused('"[[10000.5, 0], [0, 1], [0, 0]]"') == (
        "collision_monitor.Stop.points = '[[10000.5, 0], [0, 1], [0, 0]]': allowed: coordinates "
        "within +-10000 m"
    )
    assert _refused("[-10000.5, 0, 0, 1, 0, 0]") == (
        "collision_monitor.Stop.points = -10000.5: allowed: a number in [-10000, 10000]"
    )


BAND = """    V:
      type: "velocity_polygon"
      action_type: "stop"
      holonomic: {holonomic}
      velocity_polygons: ["b"]
      b:
        points: "[[1, 0.4], [1, -0.4], [0, -0.4], [0, 0.4]]"
        linear_min: 0.0
        linear_max: 1.0
        theta_min: -1.0
        theta_max: 1.0
"""
BAND_HEAD = """collision_monitor:
  ros__parameters:
    observation_sources: ["scan"]
    polygons: ["V"]
"""


def _band(*, holonomic: bool = False, **changes: Any) -> SubPolygon:
    text = BAND.format(holonomic=str(holonomic).lower())
    for key, value in changes.items():
        line = f"        {key}: {value}\n"
        if f"        {key}:" in text:
            start = text.index(f"        {key}:")
            end = text.index("\n", start) + 1
            text = text[:start] + ("" if value is None else line) + text[end:]
        elif value is not None:
            text += line
    zone = parse_params(BAND_HEAD + text).zones[0]
    (band,) = zone.subpolygons
    return band


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_band_reads_its_speeds_and_directions() -> None:
    band = _band()
    y = Fraction(float(np.float32(0.4)))  # Nav2 reads a points string into single precision
    assert band == SubPolygon(
        "b",
        ((Fraction(1), y), (Fraction(1), -y), (Fraction(0), -y), (Fraction(0), y)),
        Fraction(0),
        Fraction(1),
        Fraction(-1),
        Fraction(1),
        -PI,
        PI,
    )
    # Directions are read only for a holonomic robot; Nav2 ignores them otherwise.
    turned: dict[str, Any] = {"direction_start_angle": -0.5, "direction_end_angle": 0.5}
    assert (_band(**turned).direction_start_rad, _band(**turned).direction_end_rad) == (-PI, PI)
    holo = _band(holonomic=True, **turned)
    assert (holo.direction_start_rad, holo.direction_end_rad) == (Fraction(-0.5), Fraction(0.5))
    plain = _band(holonomic=True)
    assert (plain.direction_start_rad, plain.direction_end_rad) == (-PI, PI)
    # An empty band (min == max) is a band; max below min is refused.
    assert _band(linear_min=0.5, linear_max=0.5).linear_max_mps == Fraction(0.5)


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"linear_max": -0.5},
            "collision_monitor.V.b.linear_max = -0.5: allowed: a number >= linear_min (0)",
        ),
        (
            {"theta_min": 0.5, "theta_max": 0.25},
            "collision_monitor.V.b.theta_max = 0.25: allowed: a number >= theta_min (0.5)",
        ),
        (
            {"theta_min": None},
            "collision_monitor.V.b.theta_min = None: allowed: a number (required)",
        ),
        (
            {"linear_min": "fast"},
            "collision_monitor.V.b.linear_min = 'fast': allowed: a number in [-10000, 10000]",
        ),
        ({"points": None}, f"collision_monitor.V.b.points = None: allowed: {ALLOWED}"),
    ],
)
def test_a_bad_band_is_refused_naming_its_key(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(Nav2ParamsError) as caught:
        _band(**changes)
    assert str(caught.value) == message


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_text_that_is_no_parameter_file_is_named_as_text_or_by_the_name_given() -> None:
    with pytest.raises(Nav2ParamsError) as caught:
        parse_params("x: 1")
    assert str(caught.value) == (
        "<text>: no `collision_monitor: ros__parameters:` section: allowed: a Nav2 collision "
        "monitor parameter file"
    )
    with pytest.raises(Nav2ParamsError, match=r"^robot\.yaml: the document is list: "):
        parse_params("[]", "robot.yaml")


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_polygon_has_at_most_256_vertices() -> None:
    ring = [f"[{i % 16},{i // 16}]" for i in range(MAX_VERTICES + 1)]
    most = parse_params(HEAD + f'      points: "[{",".join(ring[:-1])}]"\n')
    assert most.zones[0].vertices is not None
    assert len(most.zones[0].vertices) == MAX_VERTICES
    assert most.zones[0].vertices[:2] == ((Fraction(0), Fraction(0)), (Fraction(1), Fraction(0)))
    text = "[" + ",".join(ring) + "]"
    assert _refused(f'"{text}"') == (
        f"collision_monitor.Stop.points = '{text[:56]}...: allowed: at most 256 vertices"
    )
