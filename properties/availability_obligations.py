"""The SR-AVL-5 proof obligations: direction-aware closing speed, about the runtime's function.

The claim: for every heading ``h`` and direction ``d`` (unit vectors), every cone half-angle
``gamma`` in ``[0, pi]`` and every velocity ``v = sigma R(phi) h`` with ``|phi| <= gamma`` and
``0 <= sigma <= s``, ``v . d`` is at most
:func:`safety.model.stopping.directed_closing_mps` ``(s, cos theta, |sin theta|, cos gamma,
sin gamma, static)``, ``theta`` the angle from ``h`` to ``d``. Dot products do not change under
rotation, so it is stated in the heading's frame: ``h = (1, 0)``, ``d = (cos theta, sin theta)``,
``v = sigma (cos phi, sin phi)`` with ``cos phi >= cos gamma``. z3 does not decide the whole
claim within its timeout; it decides three lemmas whose conjunction is the claim:

* :func:`closing_inside_obligation`: with ``d`` inside the cone (``cos theta >= cos gamma``),
  ``cos phi cos theta + sin phi sin theta <= 1`` (geometry only);
* :func:`closing_outside_obligation`: with ``d`` outside it, that component is at most
  ``cos theta cos gamma + |sin theta| sin gamma``, the cone's nearer edge (geometry only);
* :func:`closing_combination_obligation`: any component ``a`` bounded as the two lemmas say,
  scaled by ``0 <= sigma <= s``, is at most the runtime's function (this one is about the
  function, which is passed in so a test can hand in a weakened copy).

:func:`closing_bound_obligation` states the whole claim in one piece: too hard to prove here,
but a weakened copy of the function is refuted by it at once, with a counterexample.
:func:`closing_never_above_obligation`: the directed speed lies between the static speed and
``max(static, s)``, the closing speed without direction: it can only lower what the governor
assumes.
"""

from __future__ import annotations

from collections.abc import Callable

import z3

from properties.smt import Obligation
from safety.model.readings import Real, maximum, select
from safety.model.stopping import directed_closing_mps

__all__ = [
    "ClosingFn",
    "closing_bound_obligation",
    "closing_combination_obligation",
    "closing_inside_obligation",
    "closing_never_above_obligation",
    "closing_obligations",
    "closing_outside_obligation",
]

# (speed, cos_offset, sin_offset_abs, cos_half, sin_half, static) -> m/s
ClosingFn = Callable[[Real, Real, Real, Real, Real, Real], Real]


def _geometry() -> tuple[tuple[z3.ArithRef, ...], tuple[z3.BoolRef, ...]]:
    """(cos theta, sin theta, cos gamma, sin gamma, cos phi, sin phi) on their unit circles,
    gamma in [0, pi], |phi| <= gamma."""
    c, x, cg, sg, cp, sp = z3.Reals("cos_offset sin_offset cos_half sin_half cos_turn sin_turn")
    hyps = (
        c * c + x * x == 1,
        cg * cg + sg * sg == 1,
        sg >= 0,
        cp * cp + sp * sp == 1,
        cp >= cg,
    )
    return (c, x, cg, sg, cp, sp), hyps


def _abs(x: z3.ArithRef) -> z3.ArithRef:
    value: z3.ArithRef = select(x >= 0, x, -x)
    return value


def closing_inside_obligation() -> Obligation:
    """Lemma: with ``d`` inside the cone, no unit velocity direction has a component above 1."""
    (c, x, cg, sg, cp, sp), hyps = _geometry()
    return Obligation(
        name="SR-AVL-5 lemma: direction inside the cone",
        statement=(
            "in the heading's frame, for unit (cos theta, sin theta), (cos gamma, sin gamma) with "
            "sin gamma >= 0 and (cos phi, sin phi) with cos phi >= cos gamma: if cos theta >= cos "
            "gamma then cos phi cos theta + sin phi sin theta <= 1"
        ),
        hypotheses=(*hyps, c >= cg),
        goal=cp * c + sp * x <= 1,
        variables=(c, x, cg, sg, cp, sp),
    )


def closing_outside_obligation() -> Obligation:
    """Lemma: with ``d`` outside the cone, the nearer edge of the cone has the largest component."""
    (c, x, cg, sg, cp, sp), hyps = _geometry()
    return Obligation(
        name="SR-AVL-5 lemma: direction outside the cone",
        statement=(
            "in the heading's frame, for unit (cos theta, sin theta), (cos gamma, sin gamma) with "
            "sin gamma >= 0 and (cos phi, sin phi) with cos phi >= cos gamma: if cos theta < cos "
            "gamma then cos phi cos theta + sin phi sin theta <= cos theta cos gamma + |sin theta| "
            "sin gamma"
        ),
        hypotheses=(*hyps, c < cg),
        goal=cp * c + sp * x <= c * cg + _abs(x) * sg,
        variables=(c, x, cg, sg, cp, sp),
    )


def closing_combination_obligation(fn: ClosingFn = directed_closing_mps) -> Obligation:
    """Lemma about ``fn``: a component bounded as the two geometric lemmas say, times a speed
    in ``[0, s]``, is at most ``fn``."""
    a, c, xa, cg, sg, sigma, speed, static = z3.Reals(
        "component cos_offset sin_offset_abs cos_half sin_half speed_mps speed_bound_mps static_mps"
    )
    edge = select(c >= cg, 1 + 0 * c, c * cg + xa * sg)
    return Obligation(
        name="SR-AVL-5 lemma: the runtime's directed closing speed covers the bound",
        statement=(
            "for every component a <= (1 if cos theta >= cos gamma else cos theta cos gamma + "
            "|sin theta| sin gamma), speed 0 <= sigma <= s and static >= 0: sigma a <= "
            "directed_closing(s, cos theta, |sin theta|, cos gamma, sin gamma, static)"
        ),
        hypotheses=(a <= edge, sigma >= 0, sigma <= speed, static >= 0),
        goal=sigma * a <= fn(speed, c, xa, cg, sg, static),
        variables=(a, c, xa, cg, sg, sigma, speed, static),
    )


def closing_obligations(fn: ClosingFn = directed_closing_mps) -> tuple[Obligation, ...]:
    """The three lemmas whose conjunction is the SR-AVL-5 bound (module docstring)."""
    return (
        closing_inside_obligation(),
        closing_outside_obligation(),
        closing_combination_obligation(fn),
    )


def closing_bound_obligation(fn: ClosingFn = directed_closing_mps) -> Obligation:
    """The whole bound in one obligation (module docstring: for refuting weakened copies)."""
    (c, x, cg, sg, cp, sp), hyps = _geometry()
    sigma, speed, static = z3.Reals("speed_mps speed_bound_mps static_mps")
    return Obligation(
        name="SR-AVL-5 directed closing speed bounds every velocity in the cone",
        statement=(
            "in the heading's frame, every velocity sigma (cos phi, sin phi) with cos phi >= cos "
            "gamma and 0 <= sigma <= s has a component along (cos theta, sin theta) of at most "
            "directed_closing(s, cos theta, |sin theta|, cos gamma, sin gamma, static)"
        ),
        hypotheses=(*hyps, sigma >= 0, sigma <= speed, static >= 0),
        goal=sigma * (cp * c + sp * x) <= fn(speed, c, _abs(x), cg, sg, static),
        variables=(c, x, cg, sg, cp, sp, sigma, speed, static),
    )


def closing_never_above_obligation(fn: ClosingFn = directed_closing_mps) -> Obligation:
    """SR-AVL-5: static <= directed closing <= max(static, s) (module docstring)."""
    c, x, cg, sg = z3.Reals("cos_offset sin_offset_abs cos_half sin_half")
    speed, static = z3.Reals("speed_bound_mps static_mps")
    value = fn(speed, c, x, cg, sg, static)
    return Obligation(
        name="SR-AVL-5 directed closing speed never above the undirected one",
        statement=(
            "for every speed bound s >= 0, static speed >= 0, offset angle (cos, |sin|) and cone "
            "half-angle in [0, pi]: static <= directed_closing <= max(static, s)"
        ),
        hypotheses=(
            c * c + x * x == 1,
            cg * cg + sg * sg == 1,
            x >= 0,
            sg >= 0,
            speed >= 0,
            static >= 0,
        ),
        goal=z3.And(value >= static, value <= maximum(static, speed)),
        variables=(c, x, cg, sg, speed, static),
    )
