"""What ``nav2 check`` says about each zone, read whole (SR-NAV-1, SR-NAV-2, SR-NAV-4).

A finding is what a person reads: the zone, the band, the travel it claims, the verdict and the
sentence that explains it. Each test here compares every field of a finding, so a wrong name, a
swapped band edge or a sentence that says the opposite fails as surely as a wrong verdict. The
counterexample's values are z3's choice; they are read from the outcome, checked to be one, and
the text is compared against them.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from pipeline.config import SafecaseConfig, load_config, overridden
from safety.nav2 import Overrides, Verdict, check, load_params
from safety.nav2.geometry import Footprint
from safety.nav2.obligations import coverage, needed_m
from safety.nav2.params import parse_params
from safety.nav2.solver import Outcome
from safety.nav2.verdicts import Finding, Report, _counterexample

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "nav2"
CODE = ["safety/nav2/verdicts.py"]
# The order in which every obligation lists its variables, and so its counterexample.
VARIABLES = ["v_mps", "data_age_s", "control_period_s", "accel_mps2", "decel_mps2", "closing_mps"]


@pytest.fixture(scope="module")
def small() -> SafecaseConfig:
    """The tutorial-sized robot: a 0.3 m square footprint, the default stopping model."""
    return load_config(EXAMPLES / "small-robot.toml")


def _monitor(zones: str, polygons: str, timeout: str = "0.18") -> str:
    return (
        f"collision_monitor:\n  ros__parameters:\n    source_timeout: {timeout}\n"
        f"    polygons: [{polygons}]\n"
        '    observation_sources: ["scan"]\n' + zones
    )


def _fields(f: Finding) -> tuple[object, ...]:
    """Everything of a finding but the z3 objects, which the tests read separately."""
    return (
        f.zone,
        f.part,
        f.action,
        f.travel,
        f.low_mps,
        f.high_mps,
        f.verdict,
        f.gives,
        f.detail,
        f.needed_m,
        f.safe_mps,
        f.why,
    )


def _counterexample_text(outcome: Outcome | None, depth_m: Fraction) -> str:
    """``counterexample v_mps = 1/2 (0.5), ...: separation 0.250546 m beyond the zone``, after
    checking that the values are a counterexample to a zone ``depth_m`` deep."""
    assert outcome is not None
    values = outcome.model
    assert list(values) == VARIABLES
    # The passive-safety bound of Mitsch et al. (IJRR 2017), written out here as an independent
    # reading of the separation the check reports.
    v, b, a, closing = (values[k] for k in ("v_mps", "decel_mps2", "accel_mps2", "closing_mps"))
    t = values["data_age_s"] + values["control_period_s"]
    needed = v * v / (2 * b) + closing * v / b + (a / b + 1) * (a / 2 * t * t + t * (v + closing))
    assert needed > depth_m
    shown = ", ".join(f"{k} = {v} ({float(v):.6g})" for k, v in values.items())
    return f"counterexample {shown}: separation {float(needed):.6g} m beyond the zone"


def _approach_counterexample(outcome: Outcome | None) -> str:
    assert outcome is not None
    assert list(outcome.model) == VARIABLES
    return "counterexample " + ", ".join(
        f"{k} = {v} ({float(v):.6g})" for k, v in outcome.model.items()
    )


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_refuted_stop_zone_names_its_counterexample_and_its_proved_safe_speed(
    small: SafecaseConfig,
) -> None:
    report = check(load_params(EXAMPLES / "tutorial.yaml"), small, latency="project")
    stop = report.findings[0]
    cx = _counterexample_text(stop.outcome, Fraction("0.25"))
    assert _fields(stop) == (
        "PolygonStop",
        "",
        "stop",
        "forward",
        0,
        1,
        Verdict.REFUTED,
        "0.25 m ahead",
        f"{cx}; largest safe speed 0.402 m/s (proved)",
        # T = 0.28 s: 1 m/s needs 0.28 + 0.5 * 0.28^2 / 2 + (1.14)^2 / 2.5 = 0.81944 m.
        Fraction("0.81944"),
        Fraction("0.402"),
        "every forward speed",
    )
    assert stop.obligation is not None
    assert stop.obligation.name == "SR-NAV-1 PolygonStop forward"
    assert stop.safe_outcome is not None
    assert stop.safe_outcome.verdict is Verdict.PROVED
    assert (
        "SR-NAV-1 PolygonStop forward at its safe speed: travelling forward at any speed in "
        "[0, 0.402] m/s" in stop.safe_outcome.smtlib
    )


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_zone_too_short_from_standstill_says_what_standstill_needs(
    small: SafecaseConfig,
) -> None:
    """Nav2's own reaction time is its source_timeout, 5 s here: with the control period,
    T = 5.1 s, and accelerating at 0.5 m/s^2 before braking at 1.25 m/s^2 from standstill needs
    0.5 * 5.1^2 / 2 + (0.5 * 5.1)^2 / 2.5 = 9.1035 m."""
    stop = check(load_params(EXAMPLES / "tutorial.yaml"), small).findings[0]
    cx = _counterexample_text(stop.outcome, Fraction("0.25"))
    assert stop.detail == (
        f"{cx}; no safe speed: even from standstill, acceleration during the reaction time "
        "needs 9.1035 m"
    )
    assert (stop.safe_mps, stop.safe_outcome) == (None, None)


def test_an_unbounded_data_age_is_named_as_the_reason_for_no_safe_speed(
    small: SafecaseConfig,
) -> None:
    box = (
        '    Deep:\n      type: "polygon"\n      action_type: "stop"\n'
        '      points: "[[1.0, 0.2], [1.0, -0.2], [0.0, -0.2], [0.0, 0.2]]"\n'
    )
    (finding,) = check(parse_params(_monitor(box, '"Deep"', timeout="0.0")), small).findings
    assert finding.verdict is Verdict.REFUTED
    assert finding.needed_m is None
    assert finding.detail == (
        f"{_counterexample_text(finding.outcome, Fraction('0.85'))}; no safe speed: the data "
        "age is unbounded (a source_timeout of 0, or no source)"
    )


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_reversing_is_its_own_claim_with_its_own_safe_speed(small: SafecaseConfig) -> None:
    """A box 0.85 m ahead of the footprint and 0.25 m behind it, reversing at up to 1 m/s: the
    rear is the tutorial's 0.25 m, so the same counterexample form and safe speed."""
    box = (
        '    B:\n      type: "polygon"\n      action_type: "stop"\n'
        '      points: "[[1.0, 0.2], [1.0, -0.2], [-0.4, -0.2], [-0.4, 0.2]]"\n'
    )
    report = check(
        parse_params(_monitor(box, '"B"')),
        small,
        overrides=Overrides(max_reverse_speed_mps=Fraction(1)),
    )
    forward, reverse = report.findings
    needed = needed_m(report.model, Fraction(1))
    assert _fields(forward) == (
        "B", "", "stop", "forward", 0, 1, Verdict.PROVED, "0.85 m ahead", "", needed, None,
        "every forward speed",
    )  # fmt: skip
    assert _fields(reverse) == (
        "B",
        "",
        "stop",
        "reverse",
        0,
        1,
        Verdict.REFUTED,
        "0.25 m ahead",
        f"{_counterexample_text(reverse.outcome, Fraction('0.25'))}; largest safe speed "
        "0.402 m/s (proved)",
        needed,
        Fraction("0.402"),
        "every reverse speed",
    )
    assert [f.obligation.name for f in report.findings if f.obligation] == [
        "SR-NAV-1 B forward",
        "SR-NAV-1 B reverse",
    ]
    assert reverse.safe_outcome is not None
    assert "travelling reverse at any speed in [0, 0.402] m/s" in reverse.safe_outcome.smtlib


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_each_band_of_a_velocity_polygon_is_named_and_bounded(small: SafecaseConfig) -> None:
    bands = (
        '    V:\n      type: "velocity_polygon"\n      action_type: "stop"\n'
        '      velocity_polygons: ["slow", "fast"]\n'
    )
    for name, depth, low, high in (("slow", 0.6, 0.0, 0.3), ("fast", 1.0, 0.3, 1.0)):
        bands += (
            f'      {name}:\n        points: "[[{depth}, 0.2], [{depth}, -0.2], [0, -0.2], '
            f'[0, 0.2]]"\n        linear_min: {low}\n        linear_max: {high}\n'
            "        theta_min: -1.0\n        theta_max: 1.0\n"
        )
    report = check(parse_params(_monitor(bands, '"V"')), small)
    slow, fast = report.findings
    cut = Fraction(0.3)  # the file's 0.3, read as the double it is
    assert _fields(slow) == (
        "V", "slow", "stop", "forward", 0, cut, Verdict.PROVED, "0.45 m ahead", "",
        needed_m(report.model, cut), None, "commanded x in [0, 0.3] m/s",
    )  # fmt: skip
    assert _fields(fast) == (
        "V", "fast", "stop", "forward", cut, 1, Verdict.PROVED, "0.85 m ahead", "",
        needed_m(report.model, Fraction(1)), None, "commanded x in [0.3, 1] m/s",
    )  # fmt: skip
    assert [f.obligation.name for f in report.findings if f.obligation] == [
        "SR-NAV-1 V/slow forward",
        "SR-NAV-1 V/fast forward",
    ]
    assert [f.label for f in report.findings] == ["V/slow", "V/fast"]


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_circle_claims_every_direction_of_a_robot_that_moves_sideways(
    small: SafecaseConfig,
) -> None:
    """A 0.5 m circle around a 0.3 m square robot leaves 0.5 - 0.15 * sqrt(2) = 0.287868 m all
    round; sideways travel at 0.2 m/s makes the top speed 1 + 0.2 m/s in any direction."""
    circle = '    C:\n      type: "circle"\n      action_type: "stop"\n      radius: 0.5\n'
    report = check(
        parse_params(_monitor(circle, '"C"')),
        small,
        overrides=Overrides(max_lateral_speed_mps=Fraction("0.2")),
    )
    (c,) = report.findings
    assert _fields(c) == (
        "C",
        "",
        "stop",
        "any",
        0,
        Fraction("1.2"),
        Verdict.REFUTED,
        "0.287868 m all round",
        f"{_counterexample_text(c.outcome, Fraction('0.287868'))}; largest safe speed "
        "0.454 m/s (proved)",
        needed_m(report.model, Fraction("1.2")),
        Fraction("0.454"),
        "every velocity of the robot",
    )
    assert c.obligation is not None
    assert c.obligation.name == "SR-NAV-1 C any"


def test_a_counterexample_the_exact_reading_does_not_confirm_is_marked() -> None:
    """The solver and the exact Fraction reading must agree; where they do not (values that
    need less than the zone gives), the text says so instead of presenting a counterexample."""
    # A 1 m circle around a 0.6 x 0.8 m robot: 0.5 m all round.
    cov = coverage(None, Fraction(1), Footprint(Fraction("0.6"), Fraction("0.8")), "forward")
    standing = dict.fromkeys(VARIABLES, Fraction(0)) | {"decel_mps2": Fraction(1)}
    assert _counterexample(cov, Outcome(Verdict.REFUTED, "", standing)) == (
        "counterexample v_mps = 0 (0), data_age_s = 0 (0), control_period_s = 0 (0), "
        "accel_mps2 = 0 (0), decel_mps2 = 1 (1), closing_mps = 0 (0): separation 0 m beyond "
        "the zone [NOT confirmed by the exact reading]"
    )
    fast = standing | {"v_mps": Fraction(2)}
    assert _counterexample(cov, Outcome(Verdict.REFUTED, "", fast)) == (
        "counterexample v_mps = 2 (2), data_age_s = 0 (0), control_period_s = 0 (0), "
        "accel_mps2 = 0 (0), decel_mps2 = 1 (1), closing_mps = 0 (0): separation 2 m beyond "
        "the zone"
    )


APPROACH = (
    '    A:\n      type: "polygon"\n      action_type: "approach"\n'
    "      time_before_collision: {before}\n"
    '      points: "[[0.5, 0.2], [0.5, -0.2], [{back}, -0.2], [{back}, 0.2]]"\n'
)


def _approach(
    config: SafecaseConfig, before: str = "2.0", back: str = "-0.2", **kw: Fraction
) -> tuple[Finding, Report]:
    params = parse_params(_monitor(APPROACH.format(before=before, back=back), '"A"'))
    report = check(params, config, overrides=Overrides(**kw))
    (finding,) = report.findings
    return finding, report


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_an_approach_zone_says_at_which_speeds_its_time_suffices(small: SafecaseConfig) -> None:
    """Accelerating during the reaction time, a crawl never keeps 2 s: refuted, with the
    speeds at which it does hold."""
    finding, report = _approach(small)
    assert _fields(finding) == (
        "A",
        "",
        "approach",
        "forward/reverse",
        0,
        1,
        Verdict.REFUTED,
        "keeps 2 s to collision",
        f"{_approach_counterexample(finding.outcome)}; time_before_collision 2 s suffices for "
        "speeds in [0.01714, 4.003] m/s",
        needed_m(report.model, Fraction(1)),
        None,
        "",
    )
    assert finding.obligation is not None
    assert finding.obligation.name == "SR-NAV-2 A approach"
    # Sideways travel: the claim is over every direction, up to forward + sideways speed.
    sideways, _ = _approach(small, max_lateral_speed_mps=Fraction("0.3"))
    assert (sideways.travel, sideways.low_mps, sideways.high_mps) == (
        "any",
        Fraction(0),
        Fraction("1.3"),
    )
    # Too short a time: no speed keeps it.
    short, _ = _approach(small, before="0.1")
    assert short.detail == (
        f"{_approach_counterexample(short.outcome)}; time_before_collision 0.1 s suffices at "
        "no speed"
    )


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_a_proved_approach_zone_says_so_without_a_counterexample(small: SafecaseConfig) -> None:
    calm = overridden(small, {"stopping": {"accel_max_mps2": 0.0}})
    finding, report = _approach(calm)
    assert _fields(finding) == (
        "A", "", "approach", "forward/reverse", 0, 1, Verdict.PROVED, "keeps 2 s to collision",
        "time_before_collision 2 s suffices for speeds in [0, 4.3] m/s",
        needed_m(report.model, Fraction(1)), None, "",
    )  # fmt: skip
    dynamic = (
        '    A:\n      type: "polygon"\n      action_type: "approach"\n'
        "      time_before_collision: 2.0\n"
        '      footprint_topic: "local_costmap/published_footprint"\n'
    )
    (finding,) = check(parse_params(_monitor(dynamic, '"A"')), calm).findings
    assert finding.verdict is Verdict.PROVED
    assert finding.detail == (
        "time_before_collision 2 s suffices for speeds in [0, 4.3] m/s; footprint from "
        "local_costmap/published_footprint, taken to be the robot's"
    )


SMALLER = (
    "the approach {shape} does not hold the robot's footprint: Nav2 would measure the time to "
    "collision from a smaller robot"
)


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_an_approach_zone_smaller_than_the_robot_is_refuted_by_its_shape(
    small: SafecaseConfig,
) -> None:
    """Nav2 times the collision from the zone; a zone that misses part of the footprint times it
    from a smaller robot. A circle exactly through the footprint's corners does hold it."""
    polygon, _ = _approach(small, back="-0.1")
    assert _fields(polygon) == (
        "A", "", "approach", "forward/reverse", 0, 1, Verdict.REFUTED, "footprint polygon",
        SMALLER.format(shape="polygon"), None, None, "",
    )  # fmt: skip
    assert polygon.obligation is None
    # A 0.3 x 0.4 m footprint: its corners lie 0.25 m from the centre.
    wide = overridden(small, {"geometry": {"footprint_width_m": 0.4}, "sim": {"ego_width_m": 0.4}})
    circle = (
        '    A:\n      type: "circle"\n      action_type: "approach"\n'
        "      time_before_collision: 2.0\n      radius: {radius}\n"
    )
    (inside,) = check(parse_params(_monitor(circle.format(radius=0.249), '"A"')), wide).findings
    assert _fields(inside) == (
        "A", "", "approach", "forward/reverse", 0, 1, Verdict.REFUTED, "footprint circle",
        SMALLER.format(shape="circle"), None, None, "",
    )  # fmt: skip
    (through,) = check(parse_params(_monitor(circle.format(radius=0.25), '"A"')), wide).findings
    assert through.gives == "keeps 2 s to collision"
