"""Weaken a COPY of the model and check that the harness notices (SR-STOP-1, SR-STOP-2).

A proof is only as good as the model it is about. These tests hand the harness plausible
slips (the reaction latency forgotten in the separation; the perception latency forgotten in
the governor) and require that the independent checks catch each one: the KeYmaera X identity
is refuted, the kinematic integration disagrees, the weak model's "safe" cap is refuted by the
real model, and the weak governor's soundness obligation is refuted with a counterexample that
replays numerically.
"""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from pipeline.config import SafecaseConfig
from properties.oracles.stopping import check_against_simulation
from properties.smt import ProofVerdict, prove
from properties.stopping_obligations import (
    governor_sound_obligation,
    keymaera_obligation,
    tier_limit,
    tier_obligation,
)
from safety.model.governor import governed_speed_mps
from safety.model.readings import Real
from safety.model.stopping import StoppingParams, Tier, keymaera_separation_m, separation_m

unit = st.floats(0.0, 1.0, allow_nan=False)


def separation_without_latency_m(
    v_mps: Real, reaction_s: Real, accel_mps2: Real, decel_mps2: Real, closing_mps: Real
) -> Real:
    """A copy of ``separation_m`` with the reaction-latency terms dropped: braking only."""
    return v_mps * v_mps / (2 * decel_mps2) + closing_mps * v_mps / decel_mps2


def governor_without_perception_latency(
    free_distance_m: Real,
    closing_mps: Real,
    margin_m: Real,
    tier_cap_mps: Real,
    params: StoppingParams,
    min_moving_mps: Real,
) -> Real:
    """The governor as if the perception latency were zero (only the control cycle counted)."""
    forgetful = replace(params, perception_latency_s=0 * params.perception_latency_s)
    return governed_speed_mps(
        free_distance_m, closing_mps, margin_m, tier_cap_mps, forgetful, min_moving_mps
    )


@pytest.fixture(scope="module")
def params(safecase_config: SafecaseConfig) -> StoppingParams:
    return StoppingParams.from_config(safecase_config).exact()


@pytest.mark.requirement("SR-STOP-1", kind="example", code=["safety/model/stopping.py"])
def test_weakened_model_is_caught_by_the_keymaera_identity(params: StoppingParams) -> None:
    result = prove(keymaera_obligation(separation_without_latency_m))
    result.attach(required=False)  # expected REFUTED: the weakened copy is wrong
    assert result.verdict is ProofVerdict.REFUTED
    values = list(result.model.values())
    assert all(isinstance(x, Fraction) for x in values)
    assert separation_without_latency_m(*values) != keymaera_separation_m(*values)


@pytest.mark.requirement("SR-STOP-1", kind="example", code=["safety/model/stopping.py"])
def test_weakened_model_is_caught_by_the_kinematic_integration(params: StoppingParams) -> None:
    # No shrinking: one disagreeing example is the whole point.
    @settings(max_examples=100, derandomize=True, database=None, phases=[Phase.generate])
    @given(u=st.tuples(unit, unit, unit, unit, unit))
    def weak_cross_check(u: tuple[float, ...]) -> None:
        check_against_simulation(separation_without_latency_m, params, u)

    with pytest.raises(AssertionError, match="closed form"):
        weak_cross_check()


@pytest.mark.requirement("SR-STOP-1", kind="example", code=["safety/model/stopping.py"])
def test_weakened_models_safe_cap_is_refuted_by_the_real_model(params: StoppingParams) -> None:
    weak = tier_limit(params, Tier.HIGH, separation_without_latency_m)
    real = tier_limit(params, Tier.HIGH)
    assert weak.bracket is not None
    assert real.bracket is not None
    assert weak.bracket.low > real.bracket.high  # the slip promises a higher speed ...
    result = prove(tier_obligation(params, Tier.HIGH, weak.bracket.low))
    result.attach(required=False)
    assert result.verdict is ProofVerdict.REFUTED  # ... which the real model refutes
    values = list(result.model.values())
    assert separation_m(*values) > params.margin_m(Tier.HIGH)


@pytest.mark.requirement("SR-STOP-2", kind="example", code=["safety/model/governor.py"])
def test_weakened_governor_is_refuted_with_a_replayable_counterexample(
    params: StoppingParams,
) -> None:
    if params.perception_latency_s == 0:
        pytest.skip("the configuration has no perception latency to forget")
    min_moving = Fraction(1, 20)
    result = prove(
        governor_sound_obligation(params, min_moving, speed_fn=governor_without_perception_latency)
    )
    result.attach(required=False)
    assert result.verdict is ProofVerdict.REFUTED
    d, closing, margin, cap = (result.model[k] for k in result.model)
    assert all(isinstance(x, Fraction) for x in (d, closing, margin, cap))
    v = governor_without_perception_latency(
        float(d), float(closing), float(margin), float(cap), params, float(min_moving)
    )
    assert v > 0
    needed = separation_m(
        Fraction(v), params.reaction_s, params.accel_max_mps2, params.decel_min_mps2, closing
    )
    assert needed > d
