"""Per-zone verdicts of ``nav2 check`` (SR-NAV-1, SR-NAV-2, SR-NAV-4)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from pipeline.config import SafecaseConfig, load_config, overridden
from safety.nav2 import Overrides, Verdict, check, load_params
from safety.nav2.params import parse_params

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "nav2"
CODE = ["safety/nav2/verdicts.py", "safety/nav2/obligations.py"]


@pytest.fixture(scope="module")
def small() -> SafecaseConfig:
    """The tutorial-sized robot: a 0.3 m square footprint, the default stopping model."""
    return load_config(EXAMPLES / "small-robot.toml")


def _monitor(zones: str, polygons: str, extra: str = "") -> str:
    return (
        "collision_monitor:\n  ros__parameters:\n    source_timeout: 0.18\n"
        f"    polygons: [{polygons}]\n"
        '    observation_sources: ["scan"]\n' + zones + extra
    )


BOX_1M = (
    '    Deep:\n      type: "polygon"\n      action_type: "stop"\n'
    '      points: "[[1.0, 0.2], [1.0, -0.2], [0.0, -0.2], [0.0, 0.2]]"\n'
)


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_the_tutorial_stop_box_is_refuted_with_a_counterexample_and_a_safe_speed(
    small: SafecaseConfig,
) -> None:
    report = check(load_params(EXAMPLES / "tutorial.yaml"), small, latency="project")
    stop, slow = report.findings
    assert stop.verdict is Verdict.REFUTED
    assert report.exit_code == 1
    # 0.25 m beyond the front of a 0.3 m robot; 1 m/s needs 0.81944 m (T = 0.28 s).
    assert stop.gives == "0.25 m ahead"
    assert stop.needed_m == Fraction("0.81944")
    assert "counterexample v_mps = " in stop.detail
    assert "NOT confirmed" not in stop.detail
    assert stop.safe_mps == Fraction("0.402")
    assert stop.safe_outcome is not None
    assert stop.safe_outcome.verdict is Verdict.PROVED
    assert slow.verdict is None
    assert "bounds no speed and stops nothing" in slow.detail


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_nav2s_own_latency_is_the_source_timeout_and_five_seconds_cover_nothing(
    small: SafecaseConfig,
) -> None:
    report = check(load_params(EXAMPLES / "tutorial.yaml"), small)
    (stop, _) = report.findings
    assert report.model.reaction.age_bound_s == 5
    assert stop.verdict is Verdict.REFUTED
    assert stop.safe_mps is None
    assert "even from standstill" in stop.detail


def test_a_deep_enough_box_is_proved_and_reversing_needs_a_zone_behind(
    small: SafecaseConfig,
) -> None:
    params = parse_params(_monitor(BOX_1M, '"Deep"'))
    report = check(params, small)
    assert [f.verdict for f in report.findings] == [Verdict.PROVED]
    assert report.exit_code == 0
    reversing = check(params, small, overrides=Overrides(max_reverse_speed_mps=Fraction("0.2")))
    forward, reverse = reversing.findings
    assert (forward.travel, forward.verdict) == ("forward", Verdict.PROVED)
    assert (reverse.travel, reverse.verdict) == ("reverse", Verdict.REFUTED)
    assert reverse.gives == "0 m ahead"


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_shape_set_at_run_time_is_unknown_never_a_pass(small: SafecaseConfig) -> None:
    dynamic = (
        '    Moving:\n      type: "polygon"\n      action_type: "stop"\n'
        '      polygon_sub_topic: "stop_zone"\n'
    )
    report = check(parse_params(_monitor(BOX_1M + dynamic, '"Deep", "Moving"')), small)
    assert [f.verdict for f in report.findings] == [Verdict.PROVED, Verdict.UNKNOWN]
    assert report.verdict is Verdict.UNKNOWN
    assert report.exit_code == 3


def test_an_unbounded_data_age_refutes_every_zone(small: SafecaseConfig) -> None:
    params = parse_params(
        _monitor(BOX_1M, '"Deep"').replace("source_timeout: 0.18", "source_timeout: 0.0")
    )
    (finding,) = check(params, small).findings
    assert finding.verdict is Verdict.REFUTED
    assert "the data age is unbounded" in finding.detail


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_no_stopping_zone_is_refuted_and_disabled_zones_make_no_claim(
    small: SafecaseConfig,
) -> None:
    slow = (
        '    Slow:\n      type: "circle"\n      radius: 2.0\n      action_type: "slowdown"\n'
        '    Limit:\n      type: "circle"\n      radius: 2.0\n      action_type: "limit"\n'
    )
    off = BOX_1M + "      enabled: false\n"
    report = check(parse_params(_monitor(slow + off, '"Slow", "Limit", "Deep"')), small)
    assert [f.verdict for f in report.findings[:3]] == [None, None, None]
    assert "disabled" in report.findings[2].detail
    assert report.findings[-1].verdict is Verdict.REFUTED
    assert "nothing makes the robot stop" in report.findings[-1].detail


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_approach_zones(small: SafecaseConfig) -> None:
    approach = (
        '    Approach:\n      type: "circle"\n      radius: {radius}\n'
        '      action_type: "approach"\n      time_before_collision: 2.0\n'
    )
    # A circle smaller than the robot: Nav2 would time collisions from a smaller robot.
    tiny = parse_params(_monitor(approach.format(radius=0.2), '"Approach"'))
    (finding,) = check(tiny, small).findings
    assert finding.verdict is Verdict.REFUTED
    assert "does not hold the robot's footprint" in finding.detail
    # With acceleration during the reaction time, nothing is left at a crawl: refuted near 0.
    fits = parse_params(_monitor(approach.format(radius=0.3), '"Approach"'))
    (finding,) = check(fits, small).findings
    assert finding.verdict is Verdict.REFUTED
    assert finding.outcome is not None
    assert finding.outcome.model["v_mps"] < Fraction(1, 10)
    assert "suffices for speeds in [" in finding.detail
    # Without it (accel_max 0), 2 s to collision leaves room to stop from every speed to 1 m/s:
    # v T + v^2 / 2b <= 2 v holds up to v = 2 b (2 - T) = 4.3 m/s.
    calm = overridden(small, {"stopping": {"accel_max_mps2": 0.0}})
    (finding,) = check(fits, calm).findings
    assert finding.verdict is Verdict.PROVED
