"""The SR-NAV obligations, written with the project's one stopping formula and read by z3.

A stop zone in use while travelling in one direction at speeds ``[low, high]`` is **proved** when,
for every speed in the band and every parameter in its range (data age, control period,
acceleration during the reaction time, braking, the obstacle's closing speed), the separation
:func:`safety.model.stopping.separation_m` needs to stop lies within what the zone gives in that
direction (:class:`Coverage`): its depth ahead of the footprint, or for any direction its
clearance around the footprint. The reaction time is ``T = data age + control period``
(:class:`Reaction`): Nav2's own bound (the largest ``source_timeout`` of the enabled sources plus
the period at which the monitor runs) or the project's (``stopping.perception_latency_s +
stopping.control_cycle_s``).

An approach zone makes Nav2 scale the command so that the time to collision at the commanded
speed is at least ``time_before_collision`` ``t_b``: the commanded speed is at most ``d / t_b``
for the distance ``d`` to the nearest reading along the path. That guarantees a stop exactly when
``separation(v) <= v t_b`` for every speed the robot travels at (:func:`approach_obligation`).

Every value here is exact (Fractions, z3 rationals), except that a square root (a clearance, a
circle's reach) is replaced by a rational at most 1e-9 m on the safe side; floats appear only in
the closed-form safe speed, which is then proved with z3 at a speed rounded down to 1 mm/s
(:func:`safe_speed`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import z3

from safety.model.stopping import ClosingClass, StoppingParams, safe_speed_mps, separation_m
from safety.nav2.geometry import Footprint, Vertex, axis_depth_m, clearance_sq_m2
from safety.nav2.solver import Obligation, Outcome, Verdict, decide
from safety.nav2.usage import Use

__all__ = [
    "Coverage",
    "Model",
    "Reaction",
    "approach_interval_mps",
    "approach_obligation",
    "coverage",
    "needed_m",
    "safe_speed",
    "sqrt_high",
    "sqrt_low",
    "stop_obligation",
]

_SAFE_SPEED_STEP = Fraction(1, 1000)


def _q(value: Fraction) -> z3.RatNumRef:
    return z3.Q(value.numerator, value.denominator)


def _g(value: Fraction | float) -> str:
    return f"{float(value):.6g}"


@dataclass(frozen=True, slots=True)
class Reaction:
    """Reaction time ``T = data age + control period`` [s], each bound with its source."""

    age_bound_s: Fraction | None  # None: no bound (a source_timeout of 0, or no source)
    age_source: str
    period_s: Fraction
    period_source: str

    @property
    def worst_s(self) -> Fraction | None:
        """The largest T [s], or None when the data age is unbounded."""
        return None if self.age_bound_s is None else self.age_bound_s + self.period_s

    def describe(self) -> str:
        """``data age <= 0.18 s (...) + control period <= 0.1 s (...)``."""
        age = "unbounded" if self.age_bound_s is None else f"<= {_g(self.age_bound_s)} s"
        return (
            f"data age {age} ({self.age_source}) + control period <= {_g(self.period_s)} s "
            f"({self.period_source})"
        )


@dataclass(frozen=True, slots=True)
class Model:
    """The stopping model (exact parameters), the reaction time, the obstacle and the footprint."""

    stopping: StoppingParams
    reaction: Reaction
    closing: ClosingClass
    footprint: Footprint

    @property
    def closing_mps(self) -> Fraction:
        """The closing speed of the assumed obstacle class [m/s]."""
        value: Fraction = self.stopping.closing_speed_mps(self.closing)
        return value

    def worst_separation_m(self, v_mps: Fraction) -> Fraction | None:
        """The separation at the worst corner of the parameter ranges [m] (None: unbounded)."""
        worst = self.reaction.worst_s
        if worst is None:
            return None
        s = self.stopping
        value: Fraction = separation_m(
            v_mps, worst, s.accel_max_mps2, s.decel_min_mps2, self.closing_mps
        )
        return value


# Square roots (a clearance, a circle's reach) are bounded by rationals this fine [m].
SQRT_RESOLUTION = 10**9


def sqrt_low(value: Fraction) -> Fraction:
    """The largest multiple of 1e-9 whose square is at most ``value >= 0`` (exact)."""
    scaled = value * SQRT_RESOLUTION**2
    return Fraction(math.isqrt(scaled.numerator // scaled.denominator), SQRT_RESOLUTION)


def sqrt_high(value: Fraction) -> Fraction:
    """The smallest multiple of 1e-9 whose square is at least ``value >= 0`` (exact)."""
    low = sqrt_low(value)
    return low if low * low == value else low + Fraction(1, SQRT_RESOLUTION)


@dataclass(frozen=True, slots=True)
class Coverage:
    """What a zone gives against an obstacle met while travelling one way: a distance [m].

    ``depth_m`` is exact for a polygon met going forward or in reverse (its depth ahead of the
    footprint). Where the exact value is a square root (a polygon's clearance all round the
    footprint, a circle's reach ahead of it or all round) it is a rational at most 1e-9 m
    below it, so every claim stays polynomial and rational (z3 decides those fast; an
    auxiliary root can make it time out). ``kind`` (depth | clearance | circle_axis |
    circle_any) and ``radius_m`` say where it came from.
    """

    kind: str
    depth_m: Fraction
    radius_m: Fraction | None = None

    def goal(self, distance: z3.ArithRef) -> z3.BoolRef:
        """The claim that ``distance`` [m] is covered."""
        claim: z3.BoolRef = distance <= _q(self.depth_m)
        return claim

    def covers(self, distance: Fraction) -> bool:
        """The same claim for one exact distance."""
        return distance <= self.depth_m

    def effective_m(self) -> float:
        """The distance covered [m], as a float."""
        return float(self.depth_m)

    @property
    def all_round(self) -> bool:
        """True when the distance holds in every direction (a clearance), not only ahead."""
        return self.kind in ("clearance", "circle_any")

    def short(self) -> str:
        """What the zone gives, in a few words (``0.25 m ahead``)."""
        return f"{_g(self.depth_m)} m {'all round' if self.all_round else 'ahead'}"

    def describe(self) -> str:
        """Human-readable: what the zone gives."""
        where = "around the footprint" if self.all_round else "ahead of the footprint"
        circle = f"radius {_g(self.radius_m)} m: " if self.radius_m is not None else ""
        what = "clearance" if self.all_round else "depth"
        return f"{circle}{what} {_g(self.depth_m)} m {where}"


def coverage(
    vertices: tuple[Vertex, ...] | None,
    radius_m: Fraction | None,
    footprint: Footprint,
    travel: str,
) -> Coverage:
    """What a polygon (``vertices``) or a circle (``radius_m``) gives for ``travel``."""
    zero = Fraction(0)
    if vertices is not None:
        if travel == "any":
            return Coverage("clearance", sqrt_low(clearance_sq_m2(vertices, footprint)))
        return Coverage("depth", axis_depth_m(vertices, footprint, travel))
    assert radius_m is not None
    if travel == "any":
        # A centred circle's nearest boundary point to the footprint is beyond a corner.
        clear = radius_m - sqrt_high(footprint.half_diagonal_sq_m2)
        return Coverage("circle_any", max(clear, zero), radius_m)
    front, across = footprint.ahead()
    # Along the footprint's sides (offset +-across) the circle reaches least far ahead.
    inside = radius_m * radius_m - across * across
    reach = sqrt_low(inside) - front if inside >= 0 else zero
    return Coverage("circle_axis", max(reach, zero), radius_m)


def _domain(
    model: Model, low: Fraction, high: Fraction
) -> tuple[tuple[z3.ArithRef, ...], tuple[z3.BoolRef, ...], z3.ArithRef]:
    """Variables, their ranges, and the separation term read by z3."""
    v, age, period, a, b, c = z3.Reals(
        "v_mps data_age_s control_period_s accel_mps2 decel_mps2 closing_mps"
    )
    s, r = model.stopping, model.reaction
    hyps = [
        v >= _q(low),
        v <= _q(high),
        age >= 0,
        period >= 0,
        period <= _q(r.period_s),
        a >= 0,
        a <= _q(s.accel_max_mps2),
        b >= _q(s.decel_min_mps2),
        b <= _q(s.decel_max_mps2),
        c >= 0,
        c <= _q(model.closing_mps),
    ]
    if r.age_bound_s is not None:
        hyps.append(age <= _q(r.age_bound_s))
    return (v, age, period, a, b, c), tuple(hyps), separation_m(v, age + period, a, b, c)


def _ranges(model: Model) -> str:
    s = model.stopping
    return (
        f"reaction T = {model.reaction.describe()}, acceleration <= {_g(s.accel_max_mps2)} m/s^2 "
        f"during T, braking in [{_g(s.decel_min_mps2)}, {_g(s.decel_max_mps2)}] m/s^2, obstacle "
        f"{model.closing.value} closing at up to {_g(model.closing_mps)} m/s"
    )


def stop_obligation(model: Model, cov: Coverage, use: Use, name: str) -> Obligation:
    """SR-NAV-1: the zone covers the stopping separation at every speed of its band."""
    variables, hyps, separation = _domain(model, use.low_mps, use.high_mps)
    goal = cov.goal(separation)
    statement = (
        f"{name}: travelling {use.travel} at any speed in [{_g(use.low_mps)}, "
        f"{_g(use.high_mps)}] m/s ({use.why}), the stopping separation stays within the zone's "
        f"{cov.describe()}; {_ranges(model)}"
    )
    return Obligation(name, statement, hyps, goal, variables)


def approach_obligation(
    model: Model, before_s: Fraction, high: Fraction, name: str, low: Fraction = Fraction(0)
) -> Obligation:
    """SR-NAV-2: keeping ``before_s`` to collision leaves room to stop at every speed."""
    variables, hyps, separation = _domain(model, low, high)
    statement = (
        f"{name}: at any speed v in [{_g(low)}, {_g(high)}] m/s, keeping time_before_collision "
        f"{_g(before_s)} s (distance >= v * {_g(before_s)}) covers the stopping separation; "
        f"{_ranges(model)}"
    )
    goal = separation <= variables[0] * _q(before_s)
    return Obligation(name, statement, hyps, goal, variables)


def needed_m(model: Model, v_mps: Fraction) -> Fraction | None:
    """Worst-case separation at ``v_mps`` [m], exact (None: the data age is unbounded)."""
    return model.worst_separation_m(v_mps)


def safe_speed(
    model: Model, cov: Coverage, travel: str, name: str, step: Fraction = _SAFE_SPEED_STEP
) -> tuple[Fraction | None, Outcome | None]:
    """The largest speed the zone covers, rounded down to ``step`` (1 mm/s) and proved with z3.

    The closed form is the project's :func:`safety.model.stopping.safe_speed_mps` at the worst
    corner of the ranges; the result is the obligation over ``[0, speed]``, PROVED. None when
    no speed is covered (not even standstill, or an unbounded data age).
    """
    standstill = model.worst_separation_m(Fraction(0))
    if standstill is None or not cov.covers(standstill):
        return None, None
    worst = model.reaction.worst_s
    assert worst is not None  # the separation is bounded only when the reaction time is
    s = model.stopping
    closed = safe_speed_mps(
        cov.effective_m(),
        float(worst),
        float(s.accel_max_mps2),
        float(s.decel_min_mps2),
        float(model.closing_mps),
    )
    speed = Fraction(math.floor(Fraction(closed) / step)) * step
    for _ in range(3):
        if speed < 0:
            break
        use = Use(travel, Fraction(0), speed, "the largest safe speed")
        outcome = decide(stop_obligation(model, cov, use, f"{name} at its safe speed"))
        if outcome.verdict is Verdict.PROVED:
            return speed, outcome
        speed -= step
    return None, None


def approach_interval_mps(model: Model, before_s: Fraction) -> tuple[float, float] | None:
    """Speeds [m/s] where ``separation(v) <= v * before_s`` at the worst corner (None: none)."""
    worst = model.reaction.worst_s
    if worst is None:
        return None
    s = model.stopping
    b, accel, closing, t = (
        float(s.decel_min_mps2),
        float(s.accel_max_mps2),
        float(model.closing_mps),
        float(worst),
    )
    alpha = 1.0 / (2.0 * b)
    beta = t + (accel * t + closing) / b - float(before_s)
    gamma = float(separation_m(0.0, t, accel, b, closing))
    disc = beta * beta - 4.0 * alpha * gamma
    if disc < 0:
        return None
    low = (-beta - math.sqrt(disc)) / (2.0 * alpha)
    high = (-beta + math.sqrt(disc)) / (2.0 * alpha)
    return (max(low, 0.0), high) if high >= 0 else None
