"""The governor never commands a speed it cannot stop from within the free distance (SR-STOP-2).

The proofs are about :func:`safety.model.governor.governed_speed_mps` itself (the function the
runtime evaluates, read by z3); the properties drive the run-time :class:`Governor` with floats
and check its commands in exact rational arithmetic, for random distances, closing speeds,
confidences and parameters anywhere in their configured ranges.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import Recorder
from pipeline.config import SafecaseConfig
from pipeline.types import Action
from properties.smt import prove
from properties.stopping_obligations import (
    governor_monotone_obligation,
    governor_sound_obligation,
    record_latency_provenance,
    worst_corner_obligation,
)
from safety.model.governor import Governor
from safety.model.stopping import separation_m

GOVERNOR = ["safety/model/governor.py", "safety/model/stopping.py"]
unit = st.floats(0.0, 1.0, allow_nan=False)
# Mostly near the robot, where the governor has to slow or stop; sometimes far.
distance = st.one_of(st.floats(0.0, 3.0), st.floats(0.0, 50.0))


@pytest.fixture(scope="module")
def governor(safecase_config: SafecaseConfig) -> Governor:
    """The run-time governor of the configuration under test."""
    built = Governor.from_config(safecase_config)
    record_latency_provenance(built.params)
    return built


@pytest.mark.requirement("SR-STOP-2", kind="proof", code=GOVERNOR)
def test_governor_speed_stops_within_the_free_distance(
    governor: Governor, evidence: Recorder
) -> None:
    exact = governor.params.exact()
    min_moving = Fraction(repr(governor.min_moving_mps))
    corner = prove(worst_corner_obligation(exact))
    sound = prove(governor_sound_obligation(exact, min_moving))
    corner.attach(required=True)
    sound.attach(required=True)
    evidence.note(
        "SR-STOP-2 = corner lemma (every parameter in range needs at most the separation at "
        "(T, A, b_min, V)) + governor obligation at that corner; both over real arithmetic."
    )
    assert corner.proved, corner.describe_model()
    assert sound.proved, sound.describe_model()


@pytest.mark.requirement("SR-STOP-2", kind="proof", code=GOVERNOR)
def test_governor_speed_is_monotone_in_free_distance(governor: Governor) -> None:
    exact = governor.params.exact()
    result = prove(governor_monotone_obligation(exact, Fraction(repr(governor.min_moving_mps))))
    result.attach(required=True)
    assert result.proved, result.describe_model()


@st.composite
def obstacles(draw: st.DrawFn) -> dict[str, npt.NDArray[Any]]:
    n = draw(st.integers(1, 8))
    return {
        "free_distance_m": np.array(draw(st.lists(distance, min_size=n, max_size=n))),
        "closing_speed_mps": np.array(
            draw(st.lists(st.floats(0.0, 3.0, allow_nan=False), min_size=n, max_size=n))
        ),
        "confidence": np.array(draw(st.lists(unit, min_size=n, max_size=n))),
        "near_reversal": np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n))),
    }


@pytest.mark.requirement("SR-STOP-2", kind="property", code=GOVERNOR)
@settings(max_examples=examples(200))
@given(obs=obstacles(), actual=st.tuples(unit, unit, unit, unit))
def test_governor_never_faster_than_it_can_stop(
    governor: Governor,
    obs: dict[str, npt.NDArray[Any]],
    actual: tuple[float, float, float, float],
    evidence: Recorder,
) -> None:
    command = governor.command(1.0, **obs)
    assert command.action is not Action.STOP or command.reasons
    speed = command.speed_mps
    p = governor.params.exact()
    assert speed <= float(p.robot_max_speed_mps)
    evidence.count("actions", command.action.value)
    if speed == 0.0:
        return
    # The actual latency, acceleration, braking and closing speed: anywhere in range.
    t = Fraction(actual[0]) * p.reaction_s
    a = Fraction(actual[1]) * p.accel_max_mps2
    b = p.decel_min_mps2 + Fraction(actual[2]) * (p.decel_max_mps2 - p.decel_min_mps2)
    v = Fraction(speed)  # the float command, exactly
    T, A, b_min = p.reaction_s, p.accel_max_mps2, p.decel_min_mps2
    for d, closing in zip(obs["free_distance_m"], obs["closing_speed_mps"], strict=True):
        V, free = Fraction(float(closing)), Fraction(float(d))
        # The worst case (where the proof is tight) and a random point of the parameter box.
        assert separation_m(v, T, A, b_min, V) <= free, (command, d, closing)
        assert separation_m(v, t, a, b, Fraction(actual[3]) * V) <= free, (command, d, closing)


@pytest.mark.requirement("SR-STOP-2", kind="property", code=GOVERNOR)
@settings(max_examples=examples(200))
@given(
    d1=distance, extra=distance, closing=st.floats(0.0, 3.0), confidence=unit, near=st.booleans()
)
def test_governor_speed_grows_with_free_distance(
    governor: Governor, d1: float, extra: float, closing: float, confidence: float, near: bool
) -> None:
    d2 = d1 + extra
    slow = governor.command(0.0, [d1], [closing], [confidence], [near]).speed_mps
    fast = governor.command(0.0, [d2], [closing], [confidence], [near]).speed_mps
    # Proved exactly for the real-valued function; the float closed form may wobble by rounding
    # (a quotient of two rounded increasing terms), bounded here by 1e-12 m/s.
    assert slow <= fast + 1e-12, (d1, d2, slow, fast)


bad_value = st.sampled_from([math.nan, math.inf, -math.inf, -1.0, -1e-12])


@pytest.mark.requirement("SR-STOP-2", kind="property", code=GOVERNOR)
@given(
    field=st.sampled_from(["free_distance_m", "closing_speed_mps", "confidence"]),
    bad=bad_value,
    values=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=6),
    where=st.integers(0, 5),
)
def test_bad_inputs_give_stop_with_the_reason(
    governor: Governor, field: str, bad: float, values: list[float], where: int
) -> None:
    inputs = {k: list(values) for k in ("free_distance_m", "closing_speed_mps", "confidence")}
    inputs[field][where % len(values)] = bad
    command = governor.command(2.0, **inputs)
    assert command.action is Action.STOP
    assert command.speed_mps == 0.0
    assert any(field in reason for reason in command.reasons), command.reasons
