"""``nav2 check`` at its edges (SR-NAV-1, SR-NAV-4): a reaction time nobody defined, and a
band Nav2 never selects."""

from __future__ import annotations

import pytest

from pipeline.config import default_config
from safety.nav2.params import parse_params
from safety.nav2.verdicts import build_model, check

CODE = ["safety/nav2/verdicts.py"]


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_an_unknown_latency_is_refused_naming_what_is_allowed() -> None:
    params = parse_params(
        'collision_monitor:\n  ros__parameters:\n    observation_sources: ["scan"]\n'
        '    polygons: ["Stop"]\n    Stop:\n      type: "circle"\n      action_type: "stop"\n'
        "      radius: 1.0\n"
    )
    with pytest.raises(ValueError, match=r"^latency = 'sensor': allowed: nav2 \| project$"):
        build_model(params, default_config(), latency="sensor")


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_band_shadowed_by_an_earlier_one_is_reported_never_selected() -> None:
    """Nav2 takes the first band that matches: ``inner`` lies inside ``all`` and is never
    used, which the check says instead of proving or refuting it."""
    text = (
        'collision_monitor:\n  ros__parameters:\n    observation_sources: ["scan"]\n'
        '    polygons: ["V"]\n    V:\n      type: "velocity_polygon"\n'
        '      action_type: "stop"\n      velocity_polygons: ["all", "inner"]\n'
    )
    for name, low, high in (("all", 0.0, 1.0), ("inner", 0.2, 0.5)):
        text += (
            f'      {name}:\n        points: "[[2, 0.4], [2, -0.4], [0, -0.4], [0, 0.4]]"\n'
            f"        linear_min: {low}\n        linear_max: {high}\n"
            "        theta_min: -1.0\n        theta_max: 1.0\n"
        )
    report = check(parse_params(text), default_config())
    inner = [f for f in report.findings if f.part == "inner"]
    assert len(inner) == 1
    assert inner[0].verdict is None
    assert inner[0].detail == "never selected for the robot's velocities"
    assert [f.part for f in report.findings if f.verdict is not None] == ["all"]
