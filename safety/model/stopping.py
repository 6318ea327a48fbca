"""Stopping distance, margin tiers and safe speed: ONE definition, read by the runtime and by z3.

Requirements served: SR-STOP-1 (each margin tier covers the stopping distance up to its speed
cap), SR-STOP-2 (the governor's speed needs at most the free distance; see
:mod:`safety.model.governor`), SR-STOP-3 (prediction horizon >= worst-case stopping time), SR-STOP-4
(margins never shrink as classification confidence drops).

The model
---------
When the perception pipeline sees an obstacle, the robot moving at ``v`` [m/s] only starts to
brake after the reaction latency ``T = perception latency bound + control cycle`` [s]. During
``T`` it may still accelerate at up to ``A`` [m/s^2] (the command of the previous cycle), then it
brakes at ``b`` [m/s^2], anywhere in the configured range ``[b_min, b_max]`` (load, floor,
tyres; the worst case is ``b_min``). Meanwhile the obstacle closes in at up to ``V`` [m/s],
which depends on its class: 0 for static structure, the reversal speed for a reversing forklift,
1.6 m/s for a walking person (the ISO 13855 approach speed K). So

* robot travel ``D_r(v) = v T + A T^2 / 2 + (v + A T)^2 / (2 b)``,
* stopping time ``t_s(v) = T + (v + A T) / b``,
* separation needed ``S(v) = D_r(v) + V t_s(v)``  (:func:`separation_m`).

Relation to the KeYmaera X passive-safety condition (Mitsch et al., IJRR 2017): with the
control cycle ``eps`` in the role of ``T``, their condition is
``separation > v^2/(2b) + V v/b + (A/b + 1) (A/2 eps^2 + eps (v + V))``. Expanding
``S(v)`` with ``T = eps`` gives exactly that right-hand side (a z3 obligation proves the two
are the same polynomial), so ``S(v)`` is the verified ground-robot bound, with the perception
latency added to the cycle time. :func:`keymaera_separation_m` writes their form literally.

Relation to ISO 13855 ``S = K T + C``: ISO 13855 sizes the distance between a protective
device and a hazard as the approach speed ``K`` (1600 mm/s walking) times the overall stopping
time ``T`` plus an intrusion allowance ``C``. For a moving machine the overall stopping time is
``t_s(v)`` and the machine's own travel ``D_r(v)`` must be added, so ``S = K t_s(v) + D_r(v) +
C``, which is ``S(v)`` with ``V = K`` and ``C = 0``. :func:`iso13855_distance_m` is the
standard's form; the evidence shows all three side by side for the configured parameters.

Direction-aware closing speed (SR-AVL-5): the obstacle's speed ``V`` above is how fast it closes
in along the robot's path. An object whose velocity lies in a cone of half-angle ``gamma`` about
its heading, at speed at most ``s``, has no velocity whose component along a unit direction ``d``
exceeds ``s max(0, cos(max(0, theta - gamma)))``, with ``theta`` the angle between the heading
and ``d`` (:func:`directed_closing_mps`, written with cosines and sines so that it stays
arithmetic; z3 proves the bound for every velocity in the cone, and that it never exceeds
``max(static, s)``, the closing speed without direction). A forklift driving away along the
path closes at 0.

Person floor (SR-CLS-8): an obstacle that may be a person, whatever its class says, closes in
at least at the person speed: ``max(V, K)`` where it is person-compatible, ``V`` elsewhere
(:func:`person_floor_mps`; z3 proves the floor, properties/test_person_floor.py).

Every function here uses only ``+ - * /``, comparisons and the helpers of
:mod:`safety.model.readings`, so it evaluates with floats, Fractions, numpy arrays and z3 terms.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any

from pipeline.config import SafecaseConfig
from safety.model.readings import Real, maximum, minimum, select, sqrt

__all__ = [
    "ISO13855_WALKING_SPEED_MPS",
    "ClosingClass",
    "StoppingParams",
    "Tier",
    "directed_closing_mps",
    "iso13855_distance_m",
    "keymaera_separation_m",
    "person_floor_mps",
    "robot_stopping_distance_m",
    "safe_speed_mps",
    "separation_m",
    "stopping_time_s",
    "tier_value",
]

# ISO 13855 approach speed of a walking person (K = 1600 mm/s).
ISO13855_WALKING_SPEED_MPS = 1.6


class ClosingClass(enum.Enum):
    """Obstacle classes by how fast they may close in on the robot."""

    STATIC = "static"
    PERSON = "person"
    FORKLIFT_REVERSING = "forklift_reversing"


class Tier(enum.Enum):
    """Margin tiers of the source material (0.4 / 0.7 / 1.0 m by default)."""

    HIGH = "high"
    MEDIUM = "medium"
    NEAR_REVERSAL = "near_reversal"


# -- the formulas (one definition, every reading) -----------------------------------------------


def robot_stopping_distance_m(
    v_mps: Real, reaction_s: Real, accel_mps2: Real, decel_mps2: Real
) -> Real:
    """Robot travel [m] from the moment of detection to standstill (latency, then braking)."""
    v_brake = v_mps + accel_mps2 * reaction_s
    return (
        v_mps * reaction_s
        + accel_mps2 * reaction_s * reaction_s / 2
        + v_brake * v_brake / (2 * decel_mps2)
    )


def stopping_time_s(v_mps: Real, reaction_s: Real, accel_mps2: Real, decel_mps2: Real) -> Real:
    """Time [s] from detection to standstill (SR-STOP-3)."""
    return reaction_s + (v_mps + accel_mps2 * reaction_s) / decel_mps2


def separation_m(
    v_mps: Real, reaction_s: Real, accel_mps2: Real, decel_mps2: Real, closing_mps: Real
) -> Real:
    """Separation [m] needed to stop before an obstacle closing in at ``closing_mps`` (SR-STOP-1).

    Robot travel plus the obstacle's travel during the whole stop; equal to the KeYmaera X
    passive-safety bound with ``eps = reaction_s`` (see the module docstring).
    """
    return robot_stopping_distance_m(
        v_mps, reaction_s, accel_mps2, decel_mps2
    ) + closing_mps * stopping_time_s(v_mps, reaction_s, accel_mps2, decel_mps2)


def keymaera_separation_m(
    v_mps: Real, eps_s: Real, accel_mps2: Real, decel_mps2: Real, closing_mps: Real
) -> Real:
    """The passive-safety bound of Mitsch et al. (IJRR 2017), written in their form [m]."""
    b, A, V, v = decel_mps2, accel_mps2, closing_mps, v_mps
    return v * v / (2 * b) + V * v / b + (A / b + 1) * (A / 2 * eps_s * eps_s + eps_s * (v + V))


def iso13855_distance_m(approach_mps: Real, overall_stop_s: Real, intrusion_m: Real) -> Real:
    """ISO 13855 minimum distance ``S = K T + C`` [m]."""
    return approach_mps * overall_stop_s + intrusion_m


def safe_speed_mps(
    distance_m: Real, reaction_s: Real, accel_mps2: Real, decel_mps2: Real, closing_mps: Real
) -> Real:
    """The largest speed [m/s] whose separation :func:`separation_m` fits in ``distance_m``.

    ``separation_m`` is ``alpha v^2 + beta v + gamma`` in ``v``; the root of ``= distance`` is
    taken in the cancellation-free form ``2 s / (beta + sqrt(beta^2 + 4 alpha s))`` with the
    slack ``s = max(distance - gamma, 0)``, so it is 0 when not even standstill fits (gamma is
    what acceleration during the latency and the obstacle's approach need). Used for the tier
    caps (``distance`` = margin, SR-STOP-1) and by the governor (free distance, SR-STOP-2).
    Needs ``reaction_s > 0`` (the control cycle is always positive), which keeps the
    denominator positive.
    """
    beta = reaction_s + (accel_mps2 * reaction_s + closing_mps) / decel_mps2
    gamma = separation_m(0 * reaction_s, reaction_s, accel_mps2, decel_mps2, closing_mps)
    slack = maximum(distance_m - gamma, 0 * reaction_s)
    return 2 * slack / (beta + sqrt(beta * beta + 2 * slack / decel_mps2))


def directed_closing_mps(
    speed_mps: Real,
    cos_offset: Real,
    sin_offset_abs: Real,
    cos_half: Real,
    sin_half: Real,
    static_mps: Real,
) -> Real:
    """Largest component [m/s] along a direction ``d`` of any velocity of speed at most
    ``speed_mps`` whose direction lies within a cone about a heading, at least ``static_mps``
    (SR-AVL-5; module docstring).

    ``cos_offset`` and ``sin_offset_abs`` are the cosine and the absolute sine of the angle
    ``theta`` from the heading to ``d``; ``cos_half`` and ``sin_half`` (``>= 0``) those of the
    cone's half-angle ``gamma`` in ``[0, pi]``. When ``d`` lies inside the cone a velocity may
    point straight along it; otherwise the nearest edge of the cone is at ``theta - gamma``,
    and ``cos(theta - gamma) = cos theta cos gamma + sin theta sin gamma``.
    """
    inside = cos_offset >= cos_half
    edge = cos_offset * cos_half + sin_offset_abs * sin_half
    along = select(inside, 1 + 0 * edge, edge)
    return maximum(static_mps, speed_mps * maximum(along, 0 * along))


def person_floor_mps(closing_mps: Real, person_compatible: Any, person_mps: Real) -> Real:
    """The closing speed [m/s] an obstacle is given: at least ``person_mps`` where it may be a
    person (``person_compatible``), ``closing_mps`` (its class's) unchanged elsewhere (SR-CLS-8)."""
    return select(person_compatible, maximum(closing_mps, person_mps), closing_mps)


def tier_value(
    confidence: Real,
    near_reversal: Any,
    high_confidence_min: Real,
    medium_confidence_min: Real,
    values: tuple[Real, Real, Real],
) -> Real:
    """The per-tier value (high, medium, near-reversal) that applies to an obstacle.

    Near-reversal obstacles get the near-reversal tier whatever their confidence; below
    ``medium_confidence_min`` the class is not trusted and the near-reversal tier (the largest
    margin and worst closing speed by design) applies too (SR-STOP-4).
    """
    high, medium, near = values
    by_confidence = select(
        confidence >= high_confidence_min,
        high,
        select(confidence >= medium_confidence_min, medium, near),
    )
    return select(near_reversal, near, by_confidence)


# -- the parameters, from the configuration ------------------------------------------------------


def _exact(value: Any) -> Any:
    # The decimal the configuration states (what z3 makes of a float too), not the binary float.
    return Fraction(repr(value)) if isinstance(value, float) else value


def _exact_triple(values: tuple[Real, Real, Real]) -> tuple[Real, Real, Real]:
    return (_exact(values[0]), _exact(values[1]), _exact(values[2]))


@dataclass(frozen=True, slots=True)
class StoppingParams:
    """Everything the stopping model needs, with units; floats, or Fractions (:meth:`exact`).

    ``latency_source`` says where ``perception_latency_s`` came from ("config" today; a
    measured p99/pWCET bound from the timing work later): the seam for measured latency.
    """

    perception_latency_s: Real
    control_cycle_s: Real
    latency_source: str
    decel_min_mps2: Real
    decel_max_mps2: Real
    accel_max_mps2: Real
    robot_max_speed_mps: Real
    margins_m: tuple[Real, Real, Real]
    caps_mps: tuple[Real, Real, Real]
    tier_classes: tuple[ClosingClass, ClosingClass, ClosingClass]
    static_speed_mps: Real
    person_speed_mps: Real
    forklift_speed_mps: Real
    high_confidence_min: Real
    medium_confidence_min: Real
    horizon_s: Real

    @classmethod
    def from_config(
        cls,
        config: SafecaseConfig,
        *,
        perception_latency_s: float | None = None,
        latency_source: str | None = None,
    ) -> StoppingParams:
        """Parameters of ``config``; pass a measured latency bound to override the configured one.

        The forklift's closing speed is the larger of ``stopping.forklift_reversing_speed_mps``
        and the predictor's ``predict.reversal_speed_mps``, so the two can never disagree in the
        unsafe direction.
        """
        s = config.stopping
        if perception_latency_s is not None and not (
            perception_latency_s >= 0.0 and perception_latency_s < float("inf")
        ):
            raise ValueError(
                f"perception_latency_s = {perception_latency_s!r}: expected a finite value >= 0"
            )
        return cls(
            perception_latency_s=(
                s.perception_latency_s if perception_latency_s is None else perception_latency_s
            ),
            control_cycle_s=s.control_cycle_s,
            latency_source=s.latency_source if latency_source is None else latency_source,
            decel_min_mps2=s.decel_min_mps2,
            decel_max_mps2=s.decel_max_mps2,
            accel_max_mps2=s.accel_max_mps2,
            robot_max_speed_mps=s.robot_max_speed_mps,
            margins_m=(s.margin_high_m, s.margin_medium_m, s.margin_near_reversal_m),
            caps_mps=(s.speed_cap_high_mps, s.speed_cap_medium_mps, s.speed_cap_near_reversal_mps),
            tier_classes=(
                ClosingClass(s.closing_class_high),
                ClosingClass(s.closing_class_medium),
                ClosingClass(s.closing_class_near_reversal),
            ),
            static_speed_mps=s.static_speed_mps,
            person_speed_mps=s.person_speed_mps,
            forklift_speed_mps=max(
                s.forklift_reversing_speed_mps, config.predict.reversal_speed_mps
            ),
            high_confidence_min=config.classify.high_confidence_min,
            medium_confidence_min=config.classify.medium_confidence_min,
            horizon_s=config.predict.horizon_s,
        )

    def exact(self) -> StoppingParams:
        """The same parameters as exact Fractions of the configured decimals (proof reading)."""
        return replace(
            self,
            perception_latency_s=_exact(self.perception_latency_s),
            control_cycle_s=_exact(self.control_cycle_s),
            decel_min_mps2=_exact(self.decel_min_mps2),
            decel_max_mps2=_exact(self.decel_max_mps2),
            accel_max_mps2=_exact(self.accel_max_mps2),
            robot_max_speed_mps=_exact(self.robot_max_speed_mps),
            margins_m=_exact_triple(self.margins_m),
            caps_mps=_exact_triple(self.caps_mps),
            static_speed_mps=_exact(self.static_speed_mps),
            person_speed_mps=_exact(self.person_speed_mps),
            forklift_speed_mps=_exact(self.forklift_speed_mps),
            high_confidence_min=_exact(self.high_confidence_min),
            medium_confidence_min=_exact(self.medium_confidence_min),
            horizon_s=_exact(self.horizon_s),
        )

    @property
    def reaction_s(self) -> Real:
        """Reaction latency T = perception latency bound + control cycle [s]."""
        return self.perception_latency_s + self.control_cycle_s

    def latency_provenance(self) -> dict[str, Any]:
        """Which T the model used and where it came from (recorded in the evidence)."""
        return {
            "perception_latency_s": float(self.perception_latency_s),
            "control_cycle_s": float(self.control_cycle_s),
            "reaction_s": float(self.reaction_s),
            "perception_latency_source": self.latency_source,
        }

    def closing_speed_mps(self, closing: ClosingClass) -> Real:
        """The closing speed assumed for an obstacle class [m/s]."""
        return {
            ClosingClass.STATIC: self.static_speed_mps,
            ClosingClass.PERSON: self.person_speed_mps,
            ClosingClass.FORKLIFT_REVERSING: self.forklift_speed_mps,
        }[closing]

    @property
    def worst_closing_speed_mps(self) -> Real:
        """The largest closing speed of any class [m/s] (used when the class is unknown)."""
        return maximum(
            maximum(self.static_speed_mps, self.person_speed_mps), self.forklift_speed_mps
        )

    def _index(self, tier: Tier) -> int:
        return (Tier.HIGH, Tier.MEDIUM, Tier.NEAR_REVERSAL).index(tier)

    def margin_m(self, tier: Tier) -> Real:
        """The tier's margin [m]."""
        return self.margins_m[self._index(tier)]

    def cap_mps(self, tier: Tier) -> Real:
        """The tier's effective speed cap [m/s]: its configured cap, at most the robot's maximum."""
        return minimum(self.caps_mps[self._index(tier)], self.robot_max_speed_mps)

    def tier_class(self, tier: Tier) -> ClosingClass:
        """The obstacle class whose closing speed the tier's margin must absorb."""
        return self.tier_classes[self._index(tier)]

    def tier_closing_mps(self, tier: Tier) -> Real:
        """The closing speed the tier's margin must absorb [m/s]."""
        return self.closing_speed_mps(self.tier_class(tier))

    def tier_limit_mps(self, tier: Tier) -> Real:
        """The largest speed the tier's margin covers in the worst case [m/s] (before capping)."""
        return safe_speed_mps(
            self.margin_m(tier),
            self.reaction_s,
            self.accel_max_mps2,
            self.decel_min_mps2,
            self.tier_closing_mps(tier),
        )

    def margin_for(self, confidence: Real, near_reversal: Any) -> Real:
        """Margin [m] for an obstacle of classification ``confidence`` in [0, 1] (SR-STOP-4)."""
        return tier_value(
            confidence,
            near_reversal,
            self.high_confidence_min,
            self.medium_confidence_min,
            self.margins_m,
        )

    def cap_for(self, confidence: Real, near_reversal: Any) -> Real:
        """Speed cap [m/s] of the tier an obstacle of ``confidence`` falls in."""
        caps = tuple(self.cap_mps(t) for t in Tier)
        return tier_value(
            confidence,
            near_reversal,
            self.high_confidence_min,
            self.medium_confidence_min,
            (caps[0], caps[1], caps[2]),
        )
