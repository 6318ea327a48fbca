"""The stopping model at its exact thresholds, and the ISO 13855 form it is compared with.

The mutation campaign (SR-EVD-5, docs/findings/mutation.md) showed the ISO 13855 comparison
computed but never checked, and the confidence thresholds of the margin tiers checked on one
side only.
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

import numpy as np
import pytest

from pipeline.config import default_config
from safety.model.stopping import (
    ISO13855_WALKING_SPEED_MPS,
    StoppingParams,
    Tier,
    iso13855_distance_m,
    robot_stopping_distance_m,
    separation_m,
    stopping_time_s,
    tier_value,
)

STOPPING = ["safety/model/stopping.py"]
PARAMS = StoppingParams.from_config(default_config())


@pytest.mark.requirement("SR-STOP-1", kind="example", code=STOPPING)
def test_iso13855_is_approach_speed_times_stopping_time_plus_allowance() -> None:
    assert iso13855_distance_m(Fraction(8, 5), Fraction(3, 4), Fraction(1, 10)) == Fraction(13, 10)
    assert iso13855_distance_m(2.0, 0.5, 0.0) == 1.0
    assert iso13855_distance_m(0.0, 5.0, 0.25) == 0.25


@pytest.mark.requirement("SR-STOP-1", kind="example", code=STOPPING)
def test_the_model_is_iso13855_with_a_walking_person_and_the_robots_own_travel() -> None:
    exact = PARAMS.exact()
    T, A, b = exact.reaction_s, exact.accel_max_mps2, exact.decel_min_mps2
    k = Fraction(repr(ISO13855_WALKING_SPEED_MPS))
    assert k == Fraction(8, 5)
    for v in (Fraction(0), Fraction(1, 2), exact.robot_max_speed_mps):
        overall = stopping_time_s(v, T, A, b)
        travel = robot_stopping_distance_m(v, T, A, b)
        assert iso13855_distance_m(k, overall, travel) == separation_m(v, T, A, b, k)
    # By hand at v = 1 m/s: T = 0.28 s, v_brake = 1.14 m/s, t_s = 1.192 s,
    # D_r = 0.28 + 0.0196 + 0.51984 = 0.81944 m, S = 1.6 * 1.192 + 0.81944 = 2.72664 m.
    assert separation_m(Fraction(1), T, A, b, k) == Fraction(272664, 100000)


@pytest.mark.requirement("SR-STOP-4", kind="example", code=STOPPING)
def test_each_confidence_threshold_belongs_to_the_higher_tier() -> None:
    high, medium = PARAMS.high_confidence_min, PARAMS.medium_confidence_min
    assert (high, medium) == (0.8, 0.5)
    below = math.nextafter
    cases = [
        (1.0, 0.4),
        (high, 0.4),
        (below(high, 0.0), 0.7),
        (medium, 0.7),
        (below(medium, 0.0), 1.0),
        (0.0, 1.0),
    ]
    for confidence, margin in cases:
        assert PARAMS.margin_for(confidence, False) == margin, confidence
        assert PARAMS.margin_for(confidence, True) == 1.0, confidence
    confidences = np.array([c for c, _ in cases])
    margins = PARAMS.margin_for(confidences, np.zeros(len(cases), dtype=bool))
    assert margins.tolist() == [m for _, m in cases]
    caps = [PARAMS.cap_for(c, False) for c, _ in cases]
    assert caps == [0.592, 0.592, 0.896, 0.896, 0.651, 0.651]


@pytest.mark.requirement("SR-STOP-4", kind="example", code=STOPPING)
def test_tier_value_picks_by_position() -> None:
    values = ("high", "medium", "near")
    picks = [
        tier_value(c, r, 0.8, 0.5, values)
        for c, r in ((0.9, False), (0.6, False), (0.1, False), (0.9, True))
    ]
    assert picks == ["high", "medium", "near", "near"]
    assert [PARAMS.margin_m(t) for t in Tier] == [0.4, 0.7, 1.0]
    assert [PARAMS.cap_mps(t) for t in Tier] == [0.592, 0.896, 0.651]


@pytest.mark.requirement("SR-STOP-4", kind="example", code=STOPPING)
def test_a_near_reversal_flag_takes_the_near_reversal_cap_at_any_confidence() -> None:
    for confidence in (1.0, 0.8, 0.6, 0.0):
        assert PARAMS.cap_for(confidence, True) == 0.651
        assert PARAMS.margin_for(confidence, True) == 1.0


@pytest.mark.requirement("SR-STOP-1", kind="example", code=STOPPING)
def test_the_exact_parameters_are_the_configured_decimals_field_by_field() -> None:
    """What the proofs read: every number as the Fraction of the decimal the configuration
    states (0.18 s is 9/50 s, not the binary float), the rest unchanged."""
    exact = PARAMS.exact()
    assert dataclasses.asdict(exact) == {
        "perception_latency_s": Fraction(9, 50),
        "control_cycle_s": Fraction(1, 10),
        "latency_source": "config",
        "decel_min_mps2": Fraction(5, 4),
        "decel_max_mps2": Fraction(5, 2),
        "accel_max_mps2": Fraction(1, 2),
        "robot_max_speed_mps": Fraction(1),
        "margins_m": (Fraction(2, 5), Fraction(7, 10), Fraction(1)),
        "caps_mps": (Fraction(74, 125), Fraction(112, 125), Fraction(651, 1000)),
        "tier_classes": PARAMS.tier_classes,
        "static_speed_mps": Fraction(0),
        "person_speed_mps": Fraction(8, 5),
        "forklift_speed_mps": Fraction(3, 5),
        "high_confidence_min": Fraction(4, 5),
        "medium_confidence_min": Fraction(1, 2),
        "horizon_s": Fraction(3, 2),
    }
    numbers = [v for v in dataclasses.astuple(exact) if isinstance(v, int | float | Fraction)]
    assert all(type(v) is Fraction for v in numbers)
    assert exact.exact() == exact
    # Built inside the test (not PARAMS, built at import) so that a mutant of from_config runs.
    built = StoppingParams.from_config(default_config())
    assert built.horizon_s == default_config().predict.horizon_s == 1.5


@pytest.mark.requirement("SR-STOP-1", kind="example", code=STOPPING)
def test_a_measured_latency_of_zero_is_accepted_and_infinity_refused() -> None:
    zero = StoppingParams.from_config(default_config(), perception_latency_s=0.0)
    assert zero.perception_latency_s == 0.0
    assert zero.reaction_s == 0.1
    for bad in (math.inf, -5e-324, math.nan):
        with pytest.raises(ValueError, match="expected a finite value >= 0"):
            StoppingParams.from_config(default_config(), perception_latency_s=bad)
