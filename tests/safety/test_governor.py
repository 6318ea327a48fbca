"""The governor by example: actions, reasons, the tier band, fail-safe STOP on bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pytest_benchmark.fixture import BenchmarkFixture

from evidence.timing import compare
from pipeline.config import default_config, overridden
from pipeline.types import Action
from safety.model.governor import Governor, governed_speed_mps
from safety.model.stopping import StoppingParams, safe_speed_mps

GOVERNOR = ["safety/model/governor.py"]


@pytest.fixture
def governor() -> Governor:
    return Governor.from_config(default_config())


def _expected(distance_m: float, closing_mps: float) -> float:
    reaction_s = StoppingParams.from_config(default_config()).reaction_s  # 0.18 + 0.1 s
    return float(safe_speed_mps(distance_m - 1e-9, reaction_s, 0.5, 1.25, closing_mps))


def test_far_obstacles_and_no_obstacles_proceed(governor: Governor) -> None:
    for distances in ([], [25.0], [3.0, 40.0]):
        command = governor.command(5.0, distances, closing_speed_mps=0.0, confidence=0.95)
        assert command.action is Action.PROCEED
        assert command.speed_mps == 1.0
        assert command.reasons == ()
        assert command.stamp_s == 5.0


def test_near_obstacle_slows_to_the_safe_speed_with_the_reason(governor: Governor) -> None:
    command = governor.command(1.5, [4.0, 0.6], closing_speed_mps=[0.0, 0.6], confidence=[0.9, 0.9])
    assert command.action is Action.SLOW
    assert command.speed_mps == pytest.approx(_expected(0.6, 0.6), rel=1e-15)
    (reason,) = command.reasons
    assert reason.startswith("obstacle 1: free distance 0.600 m, closing 0.60 m/s")
    assert f"limit {command.speed_mps:.3f} m/s" in reason


def test_tier_cap_applies_inside_the_margin_band_only(governor: Governor) -> None:
    # Near-reversal: margin 1.0 m, cap 0.651 m/s. A static obstacle 1.05 m away allows 1 m/s.
    outside = governor.command(0.0, [1.05], closing_speed_mps=0.0, near_reversal=[True])
    assert outside.action is Action.PROCEED
    inside = governor.command(0.0, [0.95], closing_speed_mps=0.0, near_reversal=[True])
    assert _expected(0.95, 0.0) > 0.651
    assert inside.action is Action.SLOW
    assert inside.speed_mps == 0.651
    assert "tier cap 0.651 m/s" in inside.reasons[0]


def test_unknown_confidence_takes_the_most_cautious_tier(governor: Governor) -> None:
    known = governor.command(0.0, [0.95], closing_speed_mps=0.0, confidence=[0.9])
    unknown = governor.command(0.0, [0.95], closing_speed_mps=0.0)
    assert known.speed_mps == 1.0
    assert unknown.speed_mps == 0.651
    # Unknown closing speed: the worst class (a person at 1.6 m/s).
    assert governor.command(0.0, [2.0]).speed_mps == pytest.approx(_expected(2.0, 1.6))


def test_stop_when_no_moving_speed_fits(governor: Governor) -> None:
    command = governor.command(0.0, [0.02], closing_speed_mps=0.0, confidence=0.9)
    assert command.action is Action.STOP
    assert command.speed_mps == 0.0
    assert "no speed >= 0.05 m/s can stop within it" in command.reasons[0]
    # With no minimum moving speed the governor creeps instead.
    config = overridden(default_config(), {"governor": {"min_moving_speed_mps": 0.0}})
    # 4 cm: more than the 2.7 cm that standstill needs (0.5 m/s^2 for 0.28 s, then braking).
    assert Governor.from_config(config).command(0.0, [0.04], 0.0, 0.9).action is Action.SLOW


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"free_distance_m": [1.0, math.nan]}, "free_distance_m [1] = nan"),
        ({"free_distance_m": [math.inf]}, "free_distance_m [0] = inf"),
        ({"free_distance_m": [-0.1]}, "free_distance_m [0] = -0.1"),
        ({"free_distance_m": "far"}, "free_distance_m = 'far': expected numbers"),
        ({"free_distance_m": None}, "free_distance_m is missing"),
        ({"free_distance_m": [[1.0]]}, "expected one value per obstacle"),
        ({"free_distance_m": [1.0], "closing_speed_mps": [-1.0]}, "closing_speed_mps [0] = -1.0"),
        ({"free_distance_m": [1.0], "confidence": [1.5]}, "confidence [0] = 1.5"),
        ({"free_distance_m": [1.0, 2.0], "confidence": [0.5, 0.5, 0.5]}, "shapes do not match"),
        (
            {"free_distance_m": [1.0], "near_reversal": [1]},
            "near_reversal = [1]: expected booleans",
        ),
    ],
)
def test_bad_input_stops_with_the_reason_and_never_raises(
    governor: Governor, kwargs: dict[str, object], fragment: str
) -> None:
    command = governor.command(3.0, **kwargs)  # type: ignore[arg-type]
    assert command.action is Action.STOP
    assert command.speed_mps == 0.0
    assert any(fragment in reason for reason in command.reasons), command.reasons


@pytest.mark.requirement("SR-STOP-2", kind="example", code=GOVERNOR)
def test_bad_stamp_and_internal_errors_stop(
    governor: Governor, monkeypatch: pytest.MonkeyPatch
) -> None:
    command = governor.command(math.nan, [5.0])
    assert command.action is Action.STOP
    assert "stamp_s = nan" in command.reasons[0]

    def broken(*_args: object) -> None:
        raise FloatingPointError("simulated fault")

    monkeypatch.setattr(governor, "speed_limits_mps", broken)
    command = governor.command(1.0, [5.0])
    assert command.action is Action.STOP
    assert command.reasons == ("governor error (FloatingPointError): simulated fault",)


def test_a_measured_latency_bound_slows_the_robot() -> None:
    config = default_config()
    slower = Governor.from_config(
        config,
        StoppingParams.from_config(config, perception_latency_s=0.3, latency_source="measured"),
    )
    assert (
        slower.command(0.0, [0.6], 0.0, 0.9).speed_mps
        < Governor.from_config(config).command(0.0, [0.6], 0.0, 0.9).speed_mps
    )


def test_vectorised_limits_match_one_obstacle_at_a_time(governor: Governor) -> None:
    rng = np.random.default_rng(7)
    distance = rng.uniform(0.0, 4.0, 64)
    closing = rng.uniform(0.0, 1.6, 64)
    confidence = rng.uniform(0.0, 1.0, 64)
    together = governor.command(0.0, distance, closing, confidence).speed_mps
    alone = [
        governor.command(0.0, [d], [c], [k]).speed_mps
        for d, c, k in zip(distance, closing, confidence, strict=True)
    ]
    assert together == min(alone)


def test_governor_cycle_cost(benchmark: BenchmarkFixture, governor: Governor) -> None:
    """Per-cycle cost for 20 obstacles (the source's ~20 objects), vectorised vs one at a time.

    Reported, not asserted: the reference is the same formula evaluated obstacle by obstacle
    in Python floats, i.e. what the runtime would cost without the numpy reading.
    """
    rng = np.random.default_rng(11)
    distance = rng.uniform(0.0, 6.0, 20)
    closing = rng.uniform(0.0, 1.6, 20)
    confidence = rng.uniform(0.0, 1.0, 20)
    params = governor.params

    def one_at_a_time() -> float:
        return min(
            float(
                governed_speed_mps(
                    float(d),
                    float(c),
                    float(params.margin_for(float(k), False)),
                    float(params.cap_for(float(k), False)),
                    params,
                    governor.min_moving_mps,
                )
            )
            for d, c, k in zip(distance, closing, confidence, strict=True)
        )

    def vectorised() -> float:
        return governor.command(0.0, distance, closing, confidence).speed_mps

    assert vectorised() == pytest.approx(one_at_a_time(), rel=1e-12)
    compare(
        {"vectorised": vectorised, "one at a time": one_at_a_time},
        reference="one at a time",
        rounds=200,
        title="governor, 20 obstacles",
    )
    benchmark(vectorised)
