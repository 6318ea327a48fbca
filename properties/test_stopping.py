"""Stopping distance against margin (SR-STOP-1, SR-STOP-3, SR-STOP-4): proofs and cross-checks.

Everything here is about the configuration under test (``safecase_config``), so
``safecase certify --config FILE`` checks FILE's numbers. A tier whose margin does not cover
the stopping separation at its speed cap is a required obligation REFUTED: the test fails with
the counterexample and the largest cap that would be safe.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig, validate_config
from pipeline.errors import ConfigError
from pipeline.types import Action
from properties.oracles.stopping import check_against_simulation
from properties.smt import ProofResult, ProofVerdict, decimal_text, prove
from properties.stopping_obligations import (
    horizon_obligation,
    keymaera_obligation,
    margin_monotone_obligation,
    proved_region_mps,
    record_latency_provenance,
    safe_speed_tight_obligation,
    tier_limit,
    tier_obligation,
    tier_result,
    worst_corner_obligation,
)
from safety.model.monitors import Observation, scan_freshness
from safety.model.stopping import (
    ISO13855_WALKING_SPEED_MPS,
    StoppingParams,
    Tier,
    iso13855_distance_m,
    keymaera_separation_m,
    robot_stopping_distance_m,
    separation_m,
    stopping_time_s,
)

STOPPING = ["safety/model/stopping.py"]
unit = st.floats(0.0, 1.0, allow_nan=False)
point = st.tuples(unit, unit, unit, unit, unit)


@pytest.fixture(scope="module")
def params(safecase_config: SafecaseConfig) -> StoppingParams:
    """The configuration's stopping parameters, exact; records which latency T was used."""
    runtime = StoppingParams.from_config(safecase_config)
    record_latency_provenance(runtime)
    return runtime.exact()


def _corner(p: StoppingParams, v: Fraction, tier: Tier) -> Fraction:
    worst: Fraction = separation_m(
        v, p.reaction_s, p.accel_max_mps2, p.decel_min_mps2, p.tier_closing_mps(tier)
    )
    return worst


def _f(x: Fraction) -> str:
    return f"{float(x):.9g}"


@pytest.mark.requirement("SR-STOP-1", kind="proof", code=STOPPING)
@pytest.mark.parametrize("tier", list(Tier), ids=lambda t: t.value)
def test_tier_margin_covers_stopping_up_to_its_cap(params: StoppingParams, tier: Tier) -> None:
    result = tier_result(params, tier)
    result.attach(required=True)
    if result.verdict is ProofVerdict.REFUTED:
        cap, margin = params.cap_mps(tier), params.margin_m(tier)
        ce = {k: v for k, v in result.model.items() if isinstance(v, Fraction)}
        needed = separation_m(*ce.values())
        limit = tier_limit(params, tier)
        safe = (
            f"largest safe cap {float(limit.exact_low):.9f} m/s (exact {limit.exact_text}; "
            f"proof bracket [{_f(limit.bracket.low)}, {_f(limit.bracket.high)}])"
            if limit.bracket is not None
            else "no speed is safe (not even standstill is covered)"
        )
        pytest.fail(
            f"SR-STOP-1 tier {tier.value} (margin {_f(margin)} m, closing "
            f"{_f(params.tier_closing_mps(tier))} m/s) REFUTED at cap {_f(cap)} m/s: "
            f"counterexample {result.describe_model()} needs {_f(needed)} m > {_f(margin)} m "
            f"(worst case at the cap {_f(_corner(params, cap, tier))} m); {safe}",
            pytrace=False,
        )
    assert result.proved, result.reason


@pytest.mark.requirement("SR-STOP-1", kind="proof", code=STOPPING)
def test_tier_speed_limits_exact_and_bracketed(params: StoppingParams, evidence: Recorder) -> None:
    rows = []
    tight = prove(safe_speed_tight_obligation(params))
    tight.attach(required=True)
    for tier in Tier:
        limit = tier_limit(params, tier)
        cap = params.cap_mps(tier)
        if limit.bracket is None:
            rows.append([tier.value, _f(params.margin_m(tier)), "-", "0", "-", "-", _f(cap), "no"])
            continue
        bracket = limit.bracket
        bracket.proved.attach(required=True)
        bracket.refuted.attach(required=False)  # just above the limit: expected REFUTED
        assert bracket.high - bracket.low <= Fraction(1, 10**9)
        # z3's algebraic root lies inside the proof bracket; the runtime's float closed form
        # agrees with it to rounding.
        assert bracket.low <= limit.exact_low <= limit.exact_high <= bracket.high
        assert abs(Fraction(limit.closed_form_mps) - limit.exact_low) <= Fraction(1, 10**14)
        rows.append(
            [
                tier.value,
                _f(params.margin_m(tier)),
                f"{params.tier_class(tier).value} ({_f(params.tier_closing_mps(tier))} m/s)",
                f"{float(limit.exact_low):.12f}",
                limit.exact_text,
                f"[{decimal_text(bracket.low)}, {decimal_text(bracket.high)}] "
                f"({bracket.proofs_run} proofs, "
                f"{bracket.time_s:.2f} s)",
                _f(cap),
                "yes" if cap <= bracket.low else "NO",
            ]
        )
    evidence.table(
        "safe speed per margin tier",
        [
            "tier",
            "margin m",
            "closing class",
            "largest safe cap m/s",
            "exact (z3)",
            "bisection on proofs",
            "configured cap m/s",
            "cap safe",
        ],
        rows,
        caption="Largest speed each tier's margin covers in the worst case: z3 algebraic "
        "number, bracketed to 1e-9 m/s by bisection on proofs, and the runtime closed form.",
    )


@pytest.mark.requirement("SR-STOP-1", kind="proof", code=STOPPING)
def test_model_is_the_keymaera_bound_side_by_side_with_iso13855(
    params: StoppingParams, evidence: Recorder
) -> None:
    identity = prove(keymaera_obligation())
    identity.attach(required=True)
    corner = prove(worst_corner_obligation(params))
    corner.attach(required=True)
    T, A, b = params.reaction_s, params.accel_max_mps2, params.decel_min_mps2
    rows = []
    for tier in Tier:
        V, margin = params.tier_closing_mps(tier), params.margin_m(tier)
        for label, v in (("cap", params.cap_mps(tier)), ("robot max", params.robot_max_speed_mps)):
            ours = separation_m(v, T, A, b, V)
            keymaera = keymaera_separation_m(v, T, A, b, V)
            assert ours == keymaera  # exactly, in the Fraction reading
            iso = iso13855_distance_m(
                ISO13855_WALKING_SPEED_MPS,
                stopping_time_s(float(v), float(T), float(A), float(b)),
                robot_stopping_distance_m(float(v), float(T), float(A), float(b)),
            )
            rows.append(
                [
                    tier.value,
                    f"{label} {_f(v)}",
                    _f(margin),
                    _f(V),
                    f"{float(ours):.4f}",
                    f"{float(keymaera):.4f}",
                    f"{iso:.4f}",
                    "yes" if ours <= margin else "NO",
                ]
            )
    evidence.table(
        "stopping model, KeYmaera X bound and ISO 13855 side by side",
        [
            "tier",
            "speed m/s",
            "margin m",
            "closing m/s",
            "ours S(v) m",
            "KeYmaera X bound m",
            "ISO 13855 K=1.6 m/s m",
            "margin covers",
        ],
        rows,
        caption=f"T = {_f(T)} s ({params.latency_source}), A = {_f(A)} m/s^2, b_min = {_f(b)} "
        "m/s^2. ISO 13855 column: S = K T + C with K = 1.6 m/s, T = latency + braking time, "
        "C = the robot's own travel (a moving machine).",
    )


def _sample(
    p: StoppingParams, tier: Tier, region: Fraction, u: tuple[float, ...]
) -> list[Fraction]:
    f = [Fraction(x) for x in u]
    return [
        f[0] * region,
        f[1] * p.reaction_s,
        f[2] * p.accel_max_mps2,
        p.decel_min_mps2 + f[3] * (p.decel_max_mps2 - p.decel_min_mps2),
        f[4] * p.tier_closing_mps(tier),
    ]


@pytest.mark.requirement("SR-STOP-1", kind="property", code=STOPPING)
@settings(max_examples=examples(100))
@given(tier=st.sampled_from(list(Tier)), points=st.lists(point, min_size=1, max_size=32))
def test_float_numpy_and_exact_readings_hold_over_the_proved_region(
    params: StoppingParams, tier: Tier, points: list[tuple[float, ...]], evidence: Recorder
) -> None:
    region = proved_region_mps(params, tier)
    assume(region is not None)
    assert region is not None
    margin = params.margin_m(tier)
    exact = [_sample(params, tier, region, u) for u in points]
    floats = [[float(x) for x in row] for row in exact]
    by_float = [separation_m(*row) for row in floats]
    by_numpy = separation_m(*np.array(floats).T)
    for row, value in zip(exact, by_float, strict=True):
        assert separation_m(*row) <= margin, row  # what the proof claims, sampled
        assert value <= float(margin) + 1e-12, row  # the float reading, up to rounding
    assert np.array_equal(by_numpy, np.array(by_float))  # same operations, same IEEE results
    evidence.count("samples per tier", tier.value, len(points))


@pytest.mark.requirement("SR-STOP-1", kind="cross-check", code=STOPPING)
def test_every_counterexample_violates_when_replayed(
    params: StoppingParams, evidence: Recorder
) -> None:
    rows = []
    for tier in Tier:
        margin = params.margin_m(tier)
        refuted: list[ProofResult] = []
        if tier_result(params, tier).verdict is ProofVerdict.REFUTED:
            refuted.append(tier_result(params, tier))
        limit = tier_limit(params, tier)
        above = Fraction(1, 10)
        if limit.bracket is not None:
            refuted.append(limit.bracket.refuted)
            above = limit.bracket.high
        for factor in (Fraction(11, 10), Fraction(3, 2), Fraction(2)):
            over = prove(tier_obligation(params, tier, above * factor))
            over.attach(required=False)
            refuted.append(over)
        for result in refuted:
            assert result.verdict is ProofVerdict.REFUTED, result.name
            values = list(result.model.values())
            assert all(isinstance(x, Fraction) for x in values), result.model
            exact = separation_m(*values)
            by_float = separation_m(*(float(x) for x in values))
            assert exact > margin, result.describe_model()
            assert by_float > float(margin), result.describe_model()
            rows.append([result.name, result.describe_model(), f"{by_float:.6f}", _f(margin)])
    evidence.counts("counterexamples replayed", {"replayed": len(rows), "violating": len(rows)})
    evidence.table(
        "z3 counterexamples replayed numerically",
        ["obligation", "counterexample (exact, float)", "separation m (float)", "margin m"],
        rows,
    )


@pytest.mark.requirement("SR-STOP-1", kind="cross-check", code=STOPPING)
@settings(max_examples=examples(100))
@given(u=point)
def test_closed_form_matches_kinematic_integration(
    params: StoppingParams, u: tuple[float, ...]
) -> None:
    check_against_simulation(separation_m, params, u)


@pytest.mark.requirement("SR-STOP-3", kind="proof", code=STOPPING)
def test_horizon_covers_worst_case_stopping_time(params: StoppingParams) -> None:
    result = prove(horizon_obligation(params))
    result.attach(required=True)
    worst = stopping_time_s(
        params.robot_max_speed_mps, params.reaction_s, params.accel_max_mps2, params.decel_min_mps2
    )
    assert result.proved, (
        f"horizon {_f(params.horizon_s)} s < worst-case stopping time {_f(worst)} s: "
        f"{result.describe_model()}"
    )


@pytest.mark.requirement("SR-STOP-4", kind="proof", code=STOPPING)
def test_margin_never_shrinks_as_confidence_drops(params: StoppingParams) -> None:
    result = prove(margin_monotone_obligation(params))
    result.attach(required=True)
    assert result.proved, result.describe_model()


@pytest.mark.requirement("SR-STOP-4", kind="property", code=STOPPING)
@given(
    confidences=st.lists(unit, min_size=1, max_size=64),
    flags=st.lists(st.booleans(), min_size=64, max_size=64),
)
def test_margin_by_confidence_is_monotone_in_every_reading(
    safecase_config: SafecaseConfig, confidences: list[float], flags: list[bool]
) -> None:
    runtime = StoppingParams.from_config(safecase_config)
    order = np.sort(np.array(confidences))[::-1]  # confidence dropping
    near = np.array(flags[: order.size])
    near = np.logical_or.accumulate(near)  # once near-reversal, stays so as confidence drops
    margins = runtime.margin_for(order, near)
    assert np.all(np.diff(margins) >= 0.0), (order, near, margins)
    scalar = [runtime.margin_for(float(c), bool(r)) for c, r in zip(order, near, strict=True)]
    assert np.array_equal(margins, np.array(scalar))


# ------------------------------------------------------------------------- SR-STOP-5
@pytest.mark.requirement(
    "SR-STOP-5", code=["pipeline/config/__init__.py", "safety/model/monitors.py"]
)
@given(
    latency_s=st.floats(0.01, 1.0),
    max_age_s=st.floats(0.01, 1.0),
    skew_s=st.floats(0.0, 0.009),
    age_s=st.floats(-0.05, 1.5),
)
def test_monitor_never_passes_data_older_than_the_proof_assumes(
    latency_s: float, max_age_s: float, skew_s: float, age_s: float
) -> None:
    data = {
        "stopping": {"perception_latency_s": latency_s},
        "monitors": {"scan_max_age_s": max_age_s, "clock_skew_s": skew_s},
    }
    if max_age_s > latency_s:
        with pytest.raises(ConfigError, match=r"monitors\.scan_max_age_s .* must not exceed"):
            validate_config(data)
        current().count("configurations", "rejected (monitor looser than the proof)", 1)
        return
    config = validate_config(data)
    # The stamp may be off by up to the skew, so the true age can be age_s + skew_s.
    now_s = 100.0
    verdict = scan_freshness(Observation(now_s=now_s, scan_stamp_s=now_s - age_s), config.monitors)
    if verdict.action is Action.PROCEED:
        assert age_s + skew_s <= config.stopping.perception_latency_s + 1e-12
        current().count("cycles", "passed, within the proof's latency", 1)
    else:
        current().count("cycles", "stopped as stale", 1)
