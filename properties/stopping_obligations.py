"""The SR-STOP-* proof obligations, built from the runtime's own functions and a configuration.

Each builder takes the stopping parameters in their exact reading
(:meth:`safety.model.stopping.StoppingParams.exact`) and returns a
:class:`properties.smt.Obligation` over z3 reals whose claim is written with the very functions the
runtime evaluates (:func:`safety.model.stopping.separation_m`,
:func:`safety.model.stopping.safe_speed_mps`,
:func:`safety.model.governor.governed_speed_mps`, :meth:`StoppingParams.margin_for`). The model
function is a parameter so that a test can hand in a deliberately weakened copy and check that
the harness notices.

:func:`tier_limit` computes, per margin tier, the largest speed cap for which the tier's
obligation holds, three ways: as an exact algebraic number (z3), bracketed to 1e-9 m/s by
bisection on proofs, and by the runtime's closed form in floats.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

import z3

from evidence.record import current
from properties.smt import (
    Bracket,
    Obligation,
    ProofResult,
    bisect_largest,
    decimal_text,
    exact_value,
    prove,
)
from safety.model.governor import governed_speed_mps
from safety.model.readings import Real
from safety.model.stopping import (
    StoppingParams,
    Tier,
    keymaera_separation_m,
    safe_speed_mps,
    separation_m,
    stopping_time_s,
)

__all__ = [
    "SeparationModel",
    "TierLimit",
    "governor_monotone_obligation",
    "governor_sound_obligation",
    "horizon_obligation",
    "keymaera_obligation",
    "margin_monotone_obligation",
    "proved_region_mps",
    "record_latency_provenance",
    "safe_speed_tight_obligation",
    "tier_limit",
    "tier_obligation",
    "tier_result",
    "worst_corner_obligation",
]

# separation(v, reaction_s, accel, decel, closing) -> metres
SeparationModel = Callable[[Real, Real, Real, Real, Real], Real]


def record_latency_provenance(params: StoppingParams) -> None:
    """Record in the evidence which reaction latency T the model used and where it came from."""
    current().provenance("stopping.reaction_latency", params.latency_provenance())


def _num(value: Fraction) -> str:
    return f"{float(value):g}"


def _domain(
    p: StoppingParams, closing_max: Real, v_max: Real | None
) -> tuple[tuple[z3.ArithRef, ...], tuple[z3.BoolRef, ...]]:
    """Speed, latency, acceleration, braking and closing speed over their configured ranges."""
    v, t, a, b, c = z3.Reals("v_mps reaction_s accel_mps2 decel_mps2 closing_mps")
    hyps = [
        v >= 0,
        t >= 0,
        t <= p.reaction_s,
        a >= 0,
        a <= p.accel_max_mps2,
        b >= p.decel_min_mps2,
        b <= p.decel_max_mps2,
        c >= 0,
        c <= closing_max,
    ]
    if v_max is not None:
        hyps.append(v <= v_max)
    return (v, t, a, b, c), tuple(hyps)


def _ranges(p: StoppingParams) -> str:
    return (
        f"reaction latency T <= {_num(p.reaction_s)} s ({p.latency_source}), "
        f"acceleration <= {_num(p.accel_max_mps2)} m/s^2 during it, braking in "
        f"[{_num(p.decel_min_mps2)}, {_num(p.decel_max_mps2)}] m/s^2"
    )


def tier_obligation(
    p: StoppingParams,
    tier: Tier,
    cap_mps: Fraction | None = None,
    model: SeparationModel = separation_m,
) -> Obligation:
    """SR-STOP-1: the tier's margin covers the separation needed from every speed up to its cap."""
    cap = p.cap_mps(tier) if cap_mps is None else cap_mps
    margin = p.margin_m(tier)
    closing = p.tier_closing_mps(tier)
    variables, hyps = _domain(p, closing, cap)
    statement = (
        f"tier {tier.value}: the {_num(margin)} m margin covers the stopping separation for "
        f"every speed up to {decimal_text(cap)} m/s, obstacle closing at up to {_num(closing)} m/s "
        f"({p.tier_class(tier).value}), {_ranges(p)}"
    )
    return Obligation(
        name=f"SR-STOP-1 tier {tier.value} at {decimal_text(cap)} m/s",
        statement=statement,
        hypotheses=hyps,
        goal=model(*variables) <= margin,
        variables=variables,
    )


def keymaera_obligation(model: SeparationModel = separation_m) -> Obligation:
    """The model equals the KeYmaera X passive-safety bound (eps = T), for all values."""
    v, t, a, b, c = z3.Reals("v_mps reaction_s accel_mps2 decel_mps2 closing_mps")
    return Obligation(
        name="separation model = KeYmaera X passive-safety bound",
        statement=(
            "for all v, T, A >= 0, b > 0, V >= 0: v T + A T^2/2 + (v + A T)^2/(2b) + V (T + (v + "
            "A T)/b) = v^2/(2b) + V v/b + (A/b + 1)(A/2 T^2 + T (v + V))  (Mitsch et al. 2017)"
        ),
        hypotheses=(v >= 0, t >= 0, a >= 0, b > 0, c >= 0),
        goal=model(v, t, a, b, c) == keymaera_separation_m(v, t, a, b, c),
        variables=(v, t, a, b, c),
    )


def worst_corner_obligation(p: StoppingParams, model: SeparationModel = separation_m) -> Obligation:
    """Lemma: the worst case over the parameter box is (T, A, b_min, V), for every speed."""
    big_v = z3.Real("closing_bound_mps")
    (v, t, a, b, c), hyps = _domain(p, big_v, None)
    return Obligation(
        name="worst case is the corner (T, A, b_min, V)",
        statement=(
            "for every speed v >= 0 and closing bound V >= 0, the separation with any parameter "
            f"in range is at most the one at the corner: {_ranges(p)}, closing in [0, V]"
        ),
        hypotheses=(*hyps, big_v >= 0),
        goal=model(v, t, a, b, c)
        <= model(v, p.reaction_s, p.accel_max_mps2, p.decel_min_mps2, big_v),
        variables=(v, t, a, b, c, big_v),
    )


GovernorFn = Callable[[Real, Real, Real, Real, StoppingParams, Real], Real]


def _governor_vars() -> tuple[z3.ArithRef, z3.ArithRef, z3.ArithRef, z3.ArithRef]:
    d, c, m, cap = z3.Reals("free_distance_m closing_mps margin_m tier_cap_mps")
    return d, c, m, cap


def governor_sound_obligation(
    p: StoppingParams,
    min_moving_mps: Fraction,
    model: SeparationModel = separation_m,
    speed_fn: GovernorFn = governed_speed_mps,
) -> Obligation:
    """SR-STOP-2 (with the corner lemma): a moving command stops within the free distance."""
    d, c, m, cap = _governor_vars()
    v = speed_fn(d, c, m, cap, p, min_moving_mps)
    return Obligation(
        name="SR-STOP-2 governor speed stops within the free distance",
        statement=(
            "for every free distance d >= 0, closing speed V >= 0, margin and tier cap >= 0: "
            "if the governor commands v > 0 then the worst-case separation from v (T = "
            f"{_num(p.reaction_s)} s, A = {_num(p.accel_max_mps2)} m/s^2, b = "
            f"{_num(p.decel_min_mps2)} m/s^2, closing V) is at most d"
        ),
        hypotheses=(d >= 0, c >= 0, m >= 0, cap >= 0),
        goal=z3.Implies(v > 0, model(v, p.reaction_s, p.accel_max_mps2, p.decel_min_mps2, c) <= d),
        variables=(d, c, m, cap),
    )


def governor_monotone_obligation(
    p: StoppingParams, min_moving_mps: Fraction, speed_fn: GovernorFn = governed_speed_mps
) -> Obligation:
    """SR-STOP-2: more free distance never gives a lower commanded speed."""
    d, c, m, cap = _governor_vars()
    d2 = z3.Real("free_distance_2_m")
    return Obligation(
        name="SR-STOP-2 governor speed is monotone in the free distance",
        statement=(
            "for all 0 <= d1 <= d2, closing speed, margin and tier cap >= 0: speed(d1) <= speed(d2)"
        ),
        hypotheses=(d >= 0, d2 >= d, c >= 0, m >= 0, cap >= 0),
        goal=speed_fn(d, c, m, cap, p, min_moving_mps)
        <= speed_fn(d2, c, m, cap, p, min_moving_mps),
        variables=(d, d2, c, m, cap),
    )


def safe_speed_tight_obligation(
    p: StoppingParams, model: SeparationModel = separation_m
) -> Obligation:
    """The safe speed is the largest: where any speed fits, its separation equals the distance."""
    d, c = z3.Reals("distance_m closing_mps")
    T, A, b = p.reaction_s, p.accel_max_mps2, p.decel_min_mps2
    return Obligation(
        name="safe speed is the largest speed that fits",
        statement=(
            "for every distance d and closing speed V >= 0 with d >= separation(0): "
            "separation(safe_speed(d)) = d (so no larger cap can hold), and safe_speed(d) >= 0"
        ),
        hypotheses=(c >= 0, d >= model(0, T, A, b, c)),
        goal=z3.And(
            model(safe_speed_mps(d, T, A, b, c), T, A, b, c) == d,
            safe_speed_mps(d, T, A, b, c) >= 0,
        ),
        variables=(d, c),
    )


def horizon_obligation(p: StoppingParams) -> Obligation:
    """SR-STOP-3: the prediction horizon covers the worst-case stopping time."""
    (v, t, a, b, _), hyps = _domain(p, 0, p.robot_max_speed_mps)
    return Obligation(
        name="SR-STOP-3 horizon covers the stopping time",
        statement=(
            f"for every speed up to {_num(p.robot_max_speed_mps)} m/s and {_ranges(p)}: the "
            f"stopping time is at most the {_num(p.horizon_s)} s prediction horizon"
        ),
        hypotheses=hyps,
        goal=stopping_time_s(v, t, a, b) <= p.horizon_s,
        variables=(v, t, a, b),
    )


def margin_monotone_obligation(p: StoppingParams) -> Obligation:
    """SR-STOP-4: lower confidence (or a near-reversal flag) never gives a smaller margin."""
    c1, c2 = z3.Reals("confidence_low confidence_high")
    r1, r2 = z3.Bools("near_reversal_low near_reversal_high")
    return Obligation(
        name="SR-STOP-4 margin never shrinks as confidence drops",
        statement=(
            "for confidences 0 <= c1 <= c2 <= 1 and near-reversal flags with r2 => r1: "
            f"margin(c1, r1) >= margin(c2, r2) (thresholds {_num(p.high_confidence_min)} / "
            f"{_num(p.medium_confidence_min)}, margins {', '.join(_num(m) for m in p.margins_m)} m)"
        ),
        hypotheses=(c1 >= 0, c1 <= c2, c2 <= 1, z3.Implies(r2, r1)),
        goal=p.margin_for(c1, r1) >= p.margin_for(c2, r2),
        variables=(c1, c2),
    )


@dataclass(frozen=True, slots=True)
class TierLimit:
    """The largest speed cap that keeps a tier's obligation PROVED, computed three ways."""

    tier: Tier
    closed_form_mps: float  # the runtime's safe_speed_mps in floats
    exact_text: str  # z3 algebraic number (root-obj) or rational
    exact_low: Fraction  # enclosure of the exact value, width <= 2e-21
    exact_high: Fraction
    bracket: Bracket | None  # bisection on proofs (None when not even standstill is covered)


@functools.lru_cache(maxsize=64)
def tier_limit(p: StoppingParams, tier: Tier, model: SeparationModel = separation_m) -> TierLimit:
    """Largest cap for ``tier`` (``p`` exact): z3 algebraic root, proof bisection, closed form."""
    margin, closing = p.margin_m(tier), p.tier_closing_mps(tier)
    T, A, b = p.reaction_s, p.accel_max_mps2, p.decel_min_mps2
    closed = float(safe_speed_mps(float(margin), float(T), float(A), float(b), float(closing)))
    v = z3.Real("v_mps")
    if model(0, T, A, b, closing) > margin:
        return TierLimit(
            tier, closed, "0 (not even standstill is covered)", Fraction(0), Fraction(0), None
        )
    text, low, high = exact_value(v, [v >= 0, model(v, T, A, b, closing) == margin])

    def at(cap: Fraction) -> ProofResult:
        return prove(tier_obligation(p, tier, cap, model))

    bracket = bisect_largest(at, Fraction(0), Fraction(1))
    return TierLimit(tier, closed, text, low, high, bracket)


@functools.lru_cache(maxsize=64)
def tier_result(
    p: StoppingParams, tier: Tier, model: SeparationModel = separation_m
) -> ProofResult:
    """The tier's obligation at its configured cap (``p`` exact), proved once per session."""
    return prove(tier_obligation(p, tier, None, model))


def proved_region_mps(p: StoppingParams, tier: Tier) -> Fraction | None:
    """Speeds ``[0, result]`` for which the tier is PROVED: the cap, else the bracket's low end.

    None when not even standstill is covered.
    """
    if tier_result(p, tier).proved:
        cap: Fraction = p.cap_mps(tier)
        return cap
    limit = tier_limit(p, tier)
    return limit.bracket.low if limit.bracket is not None else None
