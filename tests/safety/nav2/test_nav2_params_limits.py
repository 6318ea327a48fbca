"""Reading a Nav2 parameter file at its limits (SR-NAV-4): size, nesting, shapes, optional keys."""

from __future__ import annotations

import sys
from fractions import Fraction
from pathlib import Path
from types import FrameType

import pytest

from safety.nav2 import reader
from safety.nav2.params import MAX_BANDS, load_params, parse_params
from safety.nav2.reader import Nav2ParamsError

CODE = ["safety/nav2/params.py", "safety/nav2/reader.py"]

HEAD = """collision_monitor:
  ros__parameters:
    polygons: ["Stop"]
    observation_sources: ["scan"]
"""
STOP = 'type: "polygon"\naction_type: "stop"\npoints: "[[0.4, 0.3], [0.4, -0.3], [0.0, -0.3]]"'


def _zone(body: str) -> str:
    return HEAD + "    Stop:\n" + "".join(f"      {line}\n" for line in body.splitlines())


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_file_over_the_size_limit_is_refused_before_it_is_parsed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The limit is 4 MiB; lowered to the test file's size plus one byte here, so the check of
    both sides of it does not parse megabytes of YAML."""
    assert reader._MAX_FILE_BYTES == 4 * 1024 * 1024
    path = tmp_path / "big.yaml"
    text = _zone(STOP)
    monkeypatch.setattr(reader, "_MAX_FILE_BYTES", len(text) + 1)
    path.write_text(text + "#")
    assert load_params(path).zones[0].name == "Stop"
    path.write_text(text + "##")
    with pytest.raises(Nav2ParamsError) as caught:
        load_params(path)
    assert str(caught.value) == f"{path}: {len(text) + 2} bytes: allowed: at most {len(text) + 1}"


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_nesting_too_deep_for_the_parser_is_one_line_naming_the_file() -> None:
    """600 nested lists under a recursion limit 300 frames above this one: the parser runs out
    of stack on every Python version, and the error is one line."""
    depth = 0
    frame: FrameType | None = sys._getframe()
    while frame is not None:
        depth, frame = depth + 1, frame.f_back
    text = "collision_monitor: " + "[" * 600 + "]" * 600 + "\n"
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(depth + 300)
    try:
        with pytest.raises(Nav2ParamsError) as caught:
            parse_params(text, "deep.yaml")
    finally:
        sys.setrecursionlimit(limit)
    assert str(caught.value) == "deep.yaml: not valid YAML: RecursionError"


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_points_that_are_neither_a_string_nor_a_list_are_refused() -> None:
    with pytest.raises(Nav2ParamsError, match=r"^collision_monitor\.Stop\.points = 3: allowed: "):
        parse_params(_zone('type: "polygon"\naction_type: "stop"\npoints: 3'))


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_velocity_polygon_has_at_most_thirty_two_bands() -> None:
    band = (
        '  points: "[[1, 1], [1, -1], [0, -1], [0, 1]]"\n'
        "  linear_min: {low}\n  linear_max: {high}\n  theta_min: -1.0\n  theta_max: 1.0\n"
    )

    def monitor(n: int) -> str:
        names = ", ".join(f'"b{i}"' for i in range(n))
        body = f'type: "velocity_polygon"\naction_type: "stop"\nvelocity_polygons: [{names}]\n'
        body += "".join(f"b{i}:\n" + band.format(low=i, high=i + 1) for i in range(n))
        return _zone(body)

    assert len(parse_params(monitor(MAX_BANDS)).zones[0].subpolygons) == MAX_BANDS
    with pytest.raises(Nav2ParamsError, match=r"velocity_polygons = \['b0', .*: at most 32 names$"):
        parse_params(monitor(MAX_BANDS + 1))


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_optional_sections_may_be_absent() -> None:
    """A smoother with a frequency but no velocity limits, a controller plugin listed without a
    section beside one with a speed: the limit comes from the plugin that has one, the control
    period from the smoother."""
    text = (
        _zone(STOP)
        + "velocity_smoother:\n  ros__parameters:\n    smoothing_frequency: 20.0\n"
        + "controller_server:\n  ros__parameters:\n"
        + '    controller_plugins: ["Missing", "FollowPath"]\n'
        + "    FollowPath:\n      max_vel_x: 0.8\n"
    )
    params = parse_params(text)
    assert (params.reverse, params.lateral, params.yaw_rate) == (None,) * 3
    assert params.forward is not None
    assert params.forward.value == Fraction(0.8)  # the double Nav2 reads
    assert params.forward.source == "controller_server.FollowPath.max_vel_x"
    assert params.control_period is not None
    assert params.control_period.value == Fraction(1, 20)
    assert params.control_period.source == "1 / velocity_smoother.smoothing_frequency"
