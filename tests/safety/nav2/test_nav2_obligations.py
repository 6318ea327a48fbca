"""The claims ``nav2 check`` decides, and the exact numbers they rest on (SR-NAV-1, SR-NAV-2).

A zone's coverage is exact or a rational at most 1e-9 m short of a square root (never more);
the largest safe speed is the closed form checked by z3, one step less where the closed form's
floats overshoot; the speeds an approach time suffices for are the roots of the separation
against ``v * before``. Each is checked here against the exact worst-case separation
(:meth:`Model.worst_separation_m`, rationals), not against the formula that computed it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from fractions import Fraction

import pytest
import z3
from hypothesis import given
from hypothesis import strategies as st

from pipeline.config import default_config, overridden
from safety.model.stopping import ClosingClass
from safety.nav2 import Nav2Params, Verdict
from safety.nav2.obligations import (
    Coverage,
    Model,
    Reaction,
    approach_interval_mps,
    approach_obligation,
    coverage,
    safe_speed,
    sqrt_high,
    sqrt_low,
    stop_obligation,
)
from safety.nav2.solver import decide
from safety.nav2.usage import Use
from safety.nav2.verdicts import build_model

CODE = ["safety/nav2/obligations.py"]
NANO = Fraction(1, 10**9)
MILLI = Fraction(1, 1000)
_NO_FILE = Nav2Params("test", "base_footprint", (), (), (), None, None, None, None, None)


def _model(closing: ClosingClass = ClosingClass.STATIC, **stopping: float) -> Model:
    """The built-in configuration's stopping model at the project's latency (T = 0.28 s)."""
    config = overridden(default_config(), {"stopping": stopping}) if stopping else default_config()
    model, _ = build_model(_NO_FILE, config, latency="project", closing=closing)
    return model


def _separation(model: Model, v_mps: Fraction) -> Fraction:
    value = model.worst_separation_m(v_mps)
    assert value is not None
    return value


@pytest.mark.requirement("SR-NAV-1", kind="property", code=CODE)
@given(st.fractions(min_value=0, max_value=400, max_denominator=10**12))
def test_square_roots_are_bracketed_to_one_nanometre(value: Fraction) -> None:
    low, high = sqrt_low(value), sqrt_high(value)
    for root in (low, high):
        assert (root / NANO).denominator == 1
    assert low * low <= value < (low + NANO) ** 2
    assert high * high >= value
    assert high == 0 or (high - NANO) ** 2 < value
    assert high - low in (0, NANO)
    assert (high == low) == (low * low == value)


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_an_exact_square_has_one_root() -> None:
    for root in (Fraction(0), Fraction(3, 2), Fraction(12345, 10**9), Fraction(7)):
        assert sqrt_low(root * root) == sqrt_high(root * root) == root
    assert sqrt_high(Fraction(2)) == Fraction(1414213563, 10**9)
    assert sqrt_low(Fraction(2)) == Fraction(1414213562, 10**9)


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_coverage_covers_its_own_depth_exactly() -> None:
    cov = Coverage("depth", Fraction("0.25"))
    assert cov.covers(Fraction("0.25"))
    assert not cov.covers(Fraction("0.25") + NANO)
    distance = z3.Real("distance_m")
    solver = z3.Solver()
    solver.add(distance == z3.Q(1, 4), z3.Not(cov.goal(distance)))
    assert solver.check() == z3.unsat
    assert cov.effective_m() == 0.25


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("cov", "short", "described"),
    [
        (
            Coverage("depth", Fraction("0.25")),
            "0.25 m ahead",
            "depth 0.25 m ahead of the footprint",
        ),
        (
            Coverage("clearance", Fraction("0.1")),
            "0.1 m all round",
            "clearance 0.1 m around the footprint",
        ),
        (
            Coverage("circle_any", Fraction("0.1"), Fraction("0.65")),
            "0.1 m all round",
            "radius 0.65 m: clearance 0.1 m around the footprint",
        ),
        (
            Coverage("circle_axis", Fraction("0.5"), Fraction("1")),
            "0.5 m ahead",
            "radius 1 m: depth 0.5 m ahead of the footprint",
        ),
    ],
    ids=["depth", "clearance", "circle_any", "circle_axis"],
)
def test_a_coverage_says_what_it_gives(cov: Coverage, short: str, described: str) -> None:
    assert cov.short() == short
    assert cov.describe() == described
    assert cov.all_round == ("all round" in short)


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_circle_covers_what_is_left_beyond_the_footprint() -> None:
    """The built-in 0.9 x 0.6 m footprint: a corner at sqrt(0.2925) m, the sides at +-0.3 m."""
    footprint = _model().footprint
    corner_sq = Fraction("0.2925")
    for radius in (Fraction(1), Fraction("0.6"), Fraction("0.5409"), Fraction("0.2")):
        any_way = coverage(None, radius, footprint, "any")
        assert any_way.kind == "circle_any"
        assert any_way.radius_m == radius
        if radius * radius <= corner_sq:
            assert any_way.depth_m == 0
        else:
            corner = radius - any_way.depth_m
            assert corner * corner >= corner_sq > (corner - NANO) ** 2
        ahead = coverage(None, radius, footprint, "forward")
        assert ahead.kind == "circle_axis"
        assert ahead.radius_m == radius
        reach = ahead.depth_m + Fraction("0.45")
        if radius * radius - Fraction("0.09") < Fraction("0.45") ** 2:
            assert ahead.depth_m == 0
        else:
            assert reach * reach <= radius * radius - Fraction("0.09") < (reach + NANO) ** 2
    assert coverage(None, Fraction("0.2"), footprint, "reverse").depth_m == 0


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_polygon_gives_its_depth_one_way_and_its_clearance_all_round() -> None:
    footprint = _model().footprint
    one, half = Fraction(1), Fraction("0.5")
    box = ((one, half), (one, -half), (-one, -half), (-one, half))
    forward = coverage(box, None, footprint, "forward")
    assert (forward.kind, forward.depth_m, forward.radius_m) == ("depth", Fraction("0.55"), None)
    around = coverage(box, None, footprint, "any")
    assert (around.kind, around.depth_m) == ("clearance", Fraction("0.2"))


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
@pytest.mark.parametrize("closing", [ClosingClass.STATIC, ClosingClass.PERSON])
@pytest.mark.parametrize("depth", ["1", "1.5", "2.5"])
def test_the_safe_speed_is_proved_and_one_step_more_is_not(
    closing: ClosingClass, depth: str
) -> None:
    model = _model(closing)
    cov = Coverage("depth", Fraction(depth))
    speed, outcome = safe_speed(model, cov, "reverse", "Zone")
    assert speed is not None
    assert outcome is not None
    assert outcome.verdict is Verdict.PROVED
    assert (speed / MILLI).denominator == 1
    assert _separation(model, speed) <= cov.depth_m < _separation(model, speed + MILLI)
    # The proof is the claim at that speed, named after the zone.
    assert "; safecase nav2 obligation: Zone at its safe speed\n" in outcome.smtlib
    band = (
        f"travelling reverse at any speed in [0, {float(speed):.6g}] m/s (the largest safe speed)"
    )
    assert band in outcome.smtlib
    faster = Use("reverse", Fraction(0), speed + MILLI, "one step more")
    assert decide(stop_obligation(model, cov, faster, "faster")).verdict is Verdict.REFUTED


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_zone_that_covers_only_standstill_is_safe_at_zero() -> None:
    model = _model()
    standstill = _separation(model, Fraction(0))
    assert standstill == Fraction("0.02744")
    speed, outcome = safe_speed(model, Coverage("depth", standstill), "forward", "Zone")
    assert speed == 0
    assert outcome is not None
    assert outcome.verdict is Verdict.PROVED
    assert safe_speed(model, Coverage("depth", standstill - NANO), "forward", "Zone") == (
        None,
        None,
    )


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_where_the_closed_form_overshoots_one_step_less_is_proved() -> None:
    """A depth 1e-18 m short of the separation at 0.094 m/s: in floats the closed form says
    exactly 0.094 m/s; z3 refutes it and proves 0.093 m/s."""
    model = _model()
    depth = _separation(model, Fraction("0.094")) - Fraction(1, 10**18)
    speed, outcome = safe_speed(model, Coverage("depth", depth), "forward", "Zone")
    assert speed == Fraction("0.093")
    assert outcome is not None
    assert outcome.verdict is Verdict.PROVED


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_an_unbounded_data_age_covers_no_speed() -> None:
    model = _model()
    unbounded = dataclasses.replace(
        model, reaction=Reaction(None, "no source_timeout", model.reaction.period_s, "test")
    )
    assert safe_speed(unbounded, Coverage("depth", Fraction(5)), "forward", "Zone") == (None, None)
    assert approach_interval_mps(unbounded, Fraction(2)) is None
    assert unbounded.reaction.describe().startswith("data age unbounded (no source_timeout) + ")


def _check_interval(model: Model, before_s: Fraction, low: float, high: float) -> None:
    """``separation(v) <= v * before`` inside [low, high], not just outside it."""
    assert 0 <= low <= high
    for i in range(11):
        v = Fraction(low) + (Fraction(high) - Fraction(low)) * i / 10
        assert _separation(model, v) <= v * before_s + NANO
    beyond = Fraction(high) + Fraction(1, 10**6)
    assert _separation(model, beyond) > beyond * before_s
    if low > 0:
        below = Fraction(low) - Fraction(1, 10**6)
        assert _separation(model, below) > below * before_s


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("closing", "before"),
    [(ClosingClass.STATIC, b) for b in ("0.7", "1", "2", "5")]
    + [(ClosingClass.PERSON, b) for b in ("3", "5", "10")],
)
def test_an_approach_time_suffices_between_the_two_roots(
    closing: ClosingClass, before: str
) -> None:
    model = _model(closing)
    before_s = Fraction(before)
    interval = approach_interval_mps(model, before_s)
    assert interval is not None
    _check_interval(model, before_s, *interval)


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_an_approach_time_too_short_suffices_at_no_speed() -> None:
    """T = 0.28 s: with 0.3 s to collision the separation stays above ``v * 0.3`` at every
    speed (no real root); with none at all, both roots are negative."""
    model = _model()
    for before in (Fraction("0.3"), Fraction(0)):
        assert approach_interval_mps(model, before) is None
        for i in range(41):
            v = Fraction(i, 10)
            assert _separation(model, v) > v * before


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_without_acceleration_a_still_robot_is_covered_by_any_approach_time() -> None:
    """No acceleration during the reaction time and a static obstacle: standing needs no room,
    so standstill is covered at every time to collision; 0.1 s covers nothing more, 0.5 s
    every speed up to 0.55 m/s."""
    model = _model(accel_max_mps2=0.0)
    assert _separation(model, Fraction(0)) == 0
    assert approach_interval_mps(model, Fraction("0.1")) == (0.0, 0.0)
    low, high = approach_interval_mps(model, Fraction("0.5")) or (-1.0, -1.0)
    assert low == 0.0
    assert high == pytest.approx(0.55, abs=1e-12)
    _check_interval(model, Fraction("0.5"), low, high)


@pytest.mark.requirement("SR-NAV-2", kind="example", code=CODE)
def test_the_approach_claim_is_named_and_holds_exactly_inside_its_interval() -> None:
    """Keeping 2 s to collision covers the separation between the interval's roots (0.017 and
    4.0 m/s): the claim over a band inside them is proved, one reaching past either refuted."""
    model = _model()
    before_s = Fraction(2)
    interval = approach_interval_mps(model, before_s)
    assert interval is not None
    low, high = (Fraction(v).limit_denominator(10**6) for v in interval)
    inside = approach_obligation(model, before_s, high - MILLI, "Approach", low=low + MILLI)
    assert inside.name == "Approach"
    outcome = decide(inside)
    assert outcome.verdict is Verdict.PROVED
    assert "; safecase nav2 obligation: Approach\n" in outcome.smtlib
    assert "keeping time_before_collision 2 s (distance >= v * 2)" in outcome.smtlib
    beyond = approach_obligation(model, before_s, high + MILLI, "Approach", low=low + MILLI)
    assert decide(beyond).verdict is Verdict.REFUTED
    below = approach_obligation(model, before_s, high - MILLI, "Approach", low=low - MILLI)
    assert decide(below).verdict is Verdict.REFUTED


def _no_data_age() -> Model:
    model = _model()
    reaction = Reaction(Fraction(0), "test", model.reaction.period_s, "test")
    return dataclasses.replace(model, reaction=reaction)


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
@pytest.mark.parametrize(
    "make",
    [
        _model,
        lambda: _model(decel_min_mps2=1.25, decel_max_mps2=1.25),
        lambda: _model(accel_max_mps2=0.0),
        _no_data_age,
    ],
    ids=["default", "one-deceleration", "no-acceleration", "no-data-age"],
)
def test_a_range_of_one_value_is_checked_not_vacuously_proved(make: Callable[[], Model]) -> None:
    """A speed band of one speed, a braking range of one deceleration, no acceleration, no data
    age: each range is a single value, which the claim must still hold at. A zone 1 mm short of
    the separation at 0.5 m/s is refuted at exactly 0.5 m/s, and one as deep is proved."""
    model = make()
    speed = Fraction("0.5")
    needed = _separation(model, speed)
    at = Use("forward", speed, speed, "one speed")
    short = stop_obligation(model, Coverage("depth", needed - MILLI), at, "short")
    assert decide(short).verdict is Verdict.REFUTED
    exact = stop_obligation(model, Coverage("depth", needed), at, "exact")
    assert decide(exact).verdict is Verdict.PROVED


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_the_reaction_time_says_where_each_bound_came_from() -> None:
    assert _model().reaction.describe() == (
        "data age <= 0.18 s (stopping.perception_latency_s, config) + control period <= 0.1 s "
        "(stopping.control_cycle_s)"
    )
