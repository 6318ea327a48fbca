"""What ``nav2 check`` says about zones it makes no claim for, and what it assumes
(SR-NAV-1, SR-NAV-2, SR-NAV-4).

A zone that slows, limits, reports, is switched off or is never listed is a finding without a
verdict; its sentence is all a reader gets, so each is compared whole. The assumptions are the
first thing the report prints under the verdict: each source of each number is named.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from pipeline.config import SafecaseConfig, load_config
from safety.nav2 import Overrides, Verdict, check
from safety.nav2.params import parse_params
from safety.nav2.verdicts import Finding, build_model

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "nav2"
CODE = ["safety/nav2/verdicts.py"]
CIRCLE = '    {name}:\n      type: "circle"\n      radius: 1.0\n      action_type: "{action}"\n'
AGE = (
    "the largest source_timeout of the enabled observation sources; 0 or no source leaves it "
    "unbounded"
)


@pytest.fixture(scope="module")
def small() -> SafecaseConfig:
    """The tutorial-sized robot: a 0.3 m square footprint, the default stopping model."""
    return load_config(EXAMPLES / "small-robot.toml")


def _monitor(zones: str, polygons: str, extra: str = "") -> str:
    return (
        "collision_monitor:\n  ros__parameters:\n    source_timeout: 0.25\n"
        f"    polygons: [{polygons}]\n"
        '    observation_sources: ["scan"]\n' + extra + zones
    )


def _note(zone: str, action: str, detail: str, verdict: Verdict | None = None) -> Finding:
    return Finding(zone, "", action, "-", None, None, verdict, "", detail)


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_zones_that_stop_nothing_say_what_they_do_and_that_nothing_stops_the_robot(
    small: SafecaseConfig,
) -> None:
    zones = (
        CIRCLE.format(name="Slow", action="slowdown")
        + "      slowdown_ratio: 0.0\n      min_points: 3\n"
        + CIRCLE.format(name="Cap", action="limit")
        + "      linear_limit: 0.0\n      angular_limit: 0.5\n"
        + CIRCLE.format(name="Look", action="none")
        + CIRCLE.format(name="Off", action="stop")
        + "      enabled: false\n"
        + CIRCLE.format(name="Spare", action="stop")
    )
    report = check(parse_params(_monitor(zones, '"Slow", "Cap", "Look", "Off"')), small)
    assert report.findings == (
        _note(
            "Slow",
            "slowdown",
            "scales the commanded velocity by slowdown_ratio 0 while >= 3 readings are inside: "
            "it bounds no speed and stops nothing; nothing to prove",
        ),
        _note(
            "Cap",
            "limit",
            "caps the commanded linear speed at 0 m/s while >= 4 readings are inside: it stops "
            "nothing, and an obstacle may appear inside a stop zone without crossing it first; "
            "nothing to prove",
        ),
        _note("Look", "none", "reports only (no action): nothing to prove"),
        _note(
            "Off",
            "stop",
            "disabled (enabled: false): not checked; check it again if it is switched on",
        ),
        _note(
            "(all zones)",
            "-",
            "no enabled stop or approach zone in use: nothing makes the robot stop",
            Verdict.REFUTED,
        ),
        _note("Spare", "-", "defined but not listed in polygons: Nav2 ignores it"),
    )
    assert report.verdict is Verdict.REFUTED


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_a_slowdown_and_a_limit_name_their_own_ratio_and_limit(small: SafecaseConfig) -> None:
    zones = (
        CIRCLE.format(name="Slow", action="slowdown")
        + "      slowdown_ratio: 0.25\n"
        + CIRCLE.format(name="Cap", action="limit")
        + "      linear_limit: 0.4\n      min_points: 2\n"
    )
    slow, cap, _ = check(parse_params(_monitor(zones, '"Slow", "Cap"')), small).findings
    assert slow.detail.startswith("scales the commanded velocity by slowdown_ratio 0.25 while >= 4")
    assert cap.detail.startswith("caps the commanded linear speed at 0.4 m/s while >= 2 readings")


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_zones_that_cannot_be_decided_or_are_never_used_say_so(small: SafecaseConfig) -> None:
    dynamic = (
        '    Moving:\n      type: "polygon"\n      action_type: "stop"\n'
        '      polygon_sub_topic: "stop_zone"\n'
    )
    (moving,) = check(parse_params(_monitor(dynamic, '"Moving"')), small).findings
    assert moving == _note(
        "Moving", "stop", "shape set at run time from stop_zone: cannot be checked", Verdict.UNKNOWN
    )
    bands = (
        '    V:\n      type: "velocity_polygon"\n      action_type: "stop"\n'
        '      velocity_polygons: ["all", "inner"]\n'
    )
    for name, low, high in (("all", 0.0, 1.0), ("inner", 0.2, 0.5)):
        bands += (
            f'      {name}:\n        points: "[[2, 0.4], [2, -0.4], [0, -0.4], [0, 0.4]]"\n'
            f"        linear_min: {low}\n        linear_max: {high}\n"
            "        theta_min: -1.0\n        theta_max: 1.0\n"
        )
    _, inner = check(parse_params(_monitor(bands, '"V"')), small).findings
    assert inner == Finding(
        "V", "inner", "stop", "-", None, None, None, "", "never selected for the robot's velocities"
    )
    assert inner.label == "V/inner"


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_the_assumptions_name_every_number_and_where_it_came_from(small: SafecaseConfig) -> None:
    params = parse_params(_monitor(CIRCLE.format(name="Stop", action="stop"), '"Stop"'))
    assert check(params, small).assumptions() == [
        "footprint: the robot lies in the 0.3 x 0.3 m rectangle centred on base_footprint "
        "(geometry.footprint_length_m, geometry.footprint_width_m)",
        f"reaction time T = data age <= 0.25 s ({AGE}) + control period <= 0.1 s "
        "(stopping.control_cycle_s: the file gives no controller or smoother frequency)",
        "obstacle: static, closing head-on at up to 0 m/s; it gives at least min_points "
        "readings inside a zone it is in",
        "travel: straight-line translation (the sweep of a turning robot is not covered); "
        "velocity polygons are selected by the commanded velocity, and the robot is taken to "
        "move no faster than that command",
        "forward speed: 1 m/s (stopping.robot_max_speed_mps; the file gives none)",
        "reverse speed: 0 m/s (the file gives none: no reversing; check it with "
        "--max-reverse-speed)",
        "sideways speed: 0 m/s (the file gives none: no sideways travel)",
        "yaw rate: 1 rad/s (geometry.max_yaw_rate_radps; the file gives none)",
    ]
    told = check(
        params,
        small,
        latency="project",
        overrides=Overrides(
            max_speed_mps=Fraction("0.8"),
            max_reverse_speed_mps=Fraction("0.3"),
            max_lateral_speed_mps=Fraction("0.2"),
            max_yaw_rate_radps=Fraction("1.5"),
        ),
    ).assumptions()
    assert told[1].startswith("reaction time T = data age <= 0.18 s (stopping.perception_latency")
    assert told[-4:] == [
        "forward speed: 0.8 m/s (--max-speed)",
        "reverse speed: 0.3 m/s (--max-reverse-speed)",
        "sideways speed: 0.2 m/s (--max-lateral-speed)",
        "yaw rate: 1.5 rad/s (--max-yaw-rate)",
    ]


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_the_control_period_comes_from_the_option_then_the_file_then_the_configuration(
    small: SafecaseConfig,
) -> None:
    circle = CIRCLE.format(name="Stop", action="stop")
    params = parse_params(_monitor(circle, '"Stop"'))
    # Nav2's latency is the default: the data age is the file's source_timeout.
    model, _ = build_model(params, small)
    assert (model.reaction.age_bound_s, model.reaction.age_source) == (Fraction(0.25), AGE)
    assert (model.reaction.period_s, model.reaction.period_source) == (
        Fraction("0.1"),
        "stopping.control_cycle_s: the file gives no controller or smoother frequency",
    )
    smoother = "velocity_smoother:\n  ros__parameters:\n    smoothing_frequency: 20.0\n"
    filed = parse_params(_monitor(circle, '"Stop"') + smoother)
    model, _ = build_model(filed, small)
    assert (model.reaction.period_s, model.reaction.period_source) == (
        Fraction(1, 20),
        "1 / velocity_smoother.smoothing_frequency",
    )
    told = Overrides(control_period_s=Fraction("0.2"))
    for given in (params, filed):
        model, _ = build_model(given, small, overrides=told)
        assert (model.reaction.period_s, model.reaction.period_source) == (
            Fraction("0.2"),
            "--control-period",
        )
