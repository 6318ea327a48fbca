"""The governor at its exact limits: the margin band's edge, the least moving speed, the
robot's maximum and the input ranges, on both sides of each threshold (SR-STOP-2).

The mutation campaign (SR-EVD-5, docs/findings/mutation.md) showed these boundaries unwatched:
``free_distance <= margin`` and ``speed >= min_moving`` could become strict, and the range
checks could lose a bound, without any test failing.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from pipeline.config import default_config
from pipeline.types import Action, Command
from safety.model.governor import Governor, governed_speed_mps
from safety.model.stopping import StoppingParams

GOVERNOR = ["safety/model/governor.py"]
CONFIG = default_config()
PARAMS = StoppingParams.from_config(CONFIG)
UP = math.inf


@pytest.fixture
def governor() -> Governor:
    return Governor.from_config(CONFIG)


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_the_tier_cap_applies_from_the_margin_itself_for_floats_and_arrays() -> None:
    margin, cap = 1.0, 0.651
    assert governed_speed_mps(1.0, 0.0, margin, cap, PARAMS, 0.05) == cap
    beyond = governed_speed_mps(math.nextafter(1.0, UP), 0.0, margin, cap, PARAMS, 0.05)
    assert beyond == PARAMS.robot_max_speed_mps
    array = governed_speed_mps(
        np.array([1.0, math.nextafter(1.0, UP)]), 0.0, margin, cap, PARAMS, 0.05
    )
    assert array.tolist() == [cap, 1.0]


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_the_band_edge_in_the_command(governor: Governor) -> None:
    at = governor.command(0.0, [1.0], closing_speed_mps=0.0, near_reversal=[True])
    assert at == Command(
        Action.SLOW,
        0.651,
        0.0,
        (
            "obstacle 0: free distance 1.000 m, closing 0.00 m/s, margin 1.00 m, "
            "tier cap 0.651 m/s: limit 0.651 m/s",
        ),
    )
    past = governor.command(0.0, [math.nextafter(1.0, UP)], 0.0, near_reversal=[True])
    assert past == Command(Action.PROCEED, 1.0, 0.0)


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_a_limit_of_exactly_the_least_moving_speed_moves_and_one_float_less_stops() -> None:
    least = 0.05
    assert governed_speed_mps(5.0, 0.0, 10.0, least, PARAMS, least) == least
    below = math.nextafter(least, 0.0)
    assert governed_speed_mps(5.0, 0.0, 10.0, below, PARAMS, least) == 0.0


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_the_robot_maximum_is_a_proceed_without_a_reason(governor: Governor) -> None:
    assert governor.max_speed_mps == 1.0
    far = governor.command(2.0, [30.0], closing_speed_mps=0.0, confidence=1.0)
    assert far == Command(Action.PROCEED, 1.0, 2.0)
    assert governor.command(2.0, []) == Command(Action.PROCEED, 1.0, 2.0)
    assert governor.command(2, [30.0], 0.0, 1.0).stamp_s == 2.0


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_range_checks_accept_their_bounds_and_refuse_one_float_past(governor: Governor) -> None:
    edges = governor.command(0.0, [0.0, 3.0], closing_speed_mps=[0.0, 0.0], confidence=[0.0, 1.0])
    assert edges.action is Action.STOP
    assert edges.reasons == (
        "obstacle 0: free distance 0.000 m, closing 0.00 m/s, margin 1.00 m, tier cap 0.651 m/s: "
        "no speed >= 0.05 m/s can stop within it",
    )
    high = math.nextafter(1.0, UP)
    for kwargs, reason in (
        (
            {"confidence": [high]},
            f"confidence [0] = {high!r}: expected finite values >= 0.0 and <= 1.0",
        ),
        (
            {"confidence": [-5e-324]},
            "confidence [0] = -5e-324: expected finite values >= 0.0 and <= 1.0",
        ),
        ({"closing_speed_mps": [-5e-324]}, "closing_speed_mps [0] = -5e-324: expected finite "),
        ({"closing_speed_mps": [math.inf]}, "closing_speed_mps [0] = inf: expected finite "),
    ):
        command = governor.command(0.0, [3.0], **kwargs)
        assert command.action is Action.STOP
        assert command.stamp_s == 0.0
        assert command.reasons[0].startswith(reason), command.reasons
    distance = governor.command(0.0, [-5e-324])
    assert distance.reasons == ("free_distance_m [0] = -5e-324: expected finite values >= 0.0",)


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_a_bad_input_lists_five_values_then_counts_the_rest(governor: Governor) -> None:
    command = governor.command(0.0, [1.0] * 7, closing_speed_mps=0.0, confidence=[1.5] * 7)
    assert command.reasons == (
        "confidence [0] = 1.5, [1] = 1.5, [2] = 1.5, [3] = 1.5, [4] = 1.5 (+2 more): "
        "expected finite values >= 0.0 and <= 1.0",
    )
    five = governor.command(0.0, [math.nan] * 5)
    assert five.reasons == (
        "free_distance_m [0] = nan, [1] = nan, [2] = nan, [3] = nan, [4] = nan: "
        "expected finite values >= 0.0",
    )


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_every_problem_of_a_bad_cycle_is_listed_and_the_stamp_kept(governor: Governor) -> None:
    command = governor.command(4.0, None, closing_speed_mps="fast", near_reversal=np.array([0.5]))  # type: ignore[arg-type]
    assert command == Command(
        Action.STOP,
        0.0,
        4.0,
        (
            "free_distance_m is missing: expected distances in metres",
            "closing_speed_mps = 'fast': expected numbers (could not convert string to "
            "float: 'fast')",
            "near_reversal = array([0.5]): expected booleans",
        ),
    )
    bad_stamp = governor.command(math.inf, [5.0])
    assert bad_stamp.reasons == ("stamp_s = inf: expected a finite time in seconds",)
    assert math.isinf(bad_stamp.stamp_s)
    text_stamp = governor.command("soon", [5.0])  # type: ignore[arg-type]
    assert text_stamp.reasons == ("stamp_s = 'soon': expected a finite time in seconds",)
    assert math.isnan(text_stamp.stamp_s)


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_fractions_are_refused_rather_than_rounded_through_the_float_guard() -> None:
    """The exact reading subtracts the exact 1/10^9 m guard and so reaches the square root,
    which refuses a Fraction; a float guard would turn the exact reading into a rounded one."""
    with pytest.raises(TypeError, match="no exact square root of the Fraction"):
        governed_speed_mps(
            Fraction(2),
            Fraction(0),
            Fraction(1),
            Fraction(651, 1000),
            PARAMS.exact(),
            Fraction(1, 20),
        )


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_a_near_reversal_flag_outranks_a_high_confidence(governor: Governor) -> None:
    flagged = governor.command(
        0.0, [0.95], closing_speed_mps=0.0, confidence=[0.95], near_reversal=[True]
    )
    assert flagged == Command(
        Action.SLOW,
        0.651,
        0.0,
        (
            "obstacle 0: free distance 0.950 m, closing 0.00 m/s, margin 1.00 m, "
            "tier cap 0.651 m/s: limit 0.651 m/s",
        ),
    )
    trusted = governor.command(0.0, [0.95], 0.0, confidence=[0.95], near_reversal=[False])
    assert trusted == Command(Action.PROCEED, 1.0, 0.0)


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_mismatched_shapes_and_internal_errors_stop_with_the_stamp(
    governor: Governor, monkeypatch: pytest.MonkeyPatch
) -> None:
    shapes = governor.command(3.0, [1.0, 2.0], confidence=[0.5] * 3)
    assert shapes == Command(
        Action.STOP,
        0.0,
        3.0,
        (
            "input shapes do not match: free_distance_m (2,), closing_speed_mps (), "
            "confidence (3,), near_reversal ()",
        ),
    )

    def broken(*_args: object) -> None:
        raise ArithmeticError("simulated")

    monkeypatch.setattr(governor, "speed_limits_mps", broken)
    failed = governor.command(6.0, [5.0])
    assert failed == Command(
        Action.STOP, 0.0, 6.0, ("governor error (ArithmeticError): simulated",)
    )
