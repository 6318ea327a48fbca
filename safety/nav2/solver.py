"""The z3 call of ``safecase nav2 check``: decide one obligation, PROVED / REFUTED / UNKNOWN.

The command line may not import :mod:`properties` (the layers: pipeline < safety < evidence <
properties), so the runtime check carries this minimal solver call. It asks z3 (``QF_NRA``, fixed
seed, a timeout) for a model of ``hypotheses and not goal``: ``unsat`` is PROVED, ``sat`` is
REFUTED with the model as exact rationals, anything else is UNKNOWN and never a pass. The goals
are polynomial (no square roots), so the text :attr:`Outcome.smtlib` is plain ``QF_NRA`` that any
SMT-LIB solver re-runs. ``properties/test_nav2.py`` decides the same obligations with
:func:`properties.smt.prove` and checks that both agree.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from fractions import Fraction

import z3

__all__ = ["Obligation", "Outcome", "Verdict", "decide"]

DEFAULT_TIMEOUT_MS = 10_000
_SEED = 0
_LOGIC = "QF_NRA"


class Verdict(enum.Enum):
    """The outcome of an obligation; only PROVED is a pass."""

    PROVED = "PROVED"
    REFUTED = "REFUTED"
    UNKNOWN = "UNKNOWN"


@dataclass(frozen=True, slots=True)
class Obligation:
    """A claim (``goal``) for every assignment of ``variables`` that meets the ``hypotheses``."""

    name: str
    statement: str
    hypotheses: tuple[z3.BoolRef, ...]
    goal: z3.BoolRef
    variables: tuple[z3.ArithRef, ...]


@dataclass(frozen=True, slots=True)
class Outcome:
    """What z3 said, the counterexample (exact rationals) and the SMT-LIB text it was given."""

    verdict: Verdict
    smtlib: str
    model: dict[str, Fraction] = field(default_factory=dict)
    reason: str = ""


def _fraction(value: z3.ExprRef) -> Fraction | None:
    if z3.is_rational_value(value):
        return Fraction(value.as_fraction())
    if z3.is_int_value(value):
        return Fraction(value.as_long())
    return None


def _rational_model(obligation: Obligation, model: z3.ModelRef) -> dict[str, Fraction]:
    """The model as rationals; an algebraic value is replaced by its 20-digit approximation.

    z3 gives an algebraic value where the constraints pin a variable to an irrational point,
    so the approximation (within 1e-20) need not be a counterexample itself; the exact reading
    of the check in :mod:`safety.nav2.verdicts` says whether it is confirmed.
    """
    rationals: dict[str, Fraction] = {}
    for var in obligation.variables:
        value = model.eval(var, model_completion=True)
        rational = _fraction(value.approx(20) if z3.is_algebraic_value(value) else value)
        assert rational is not None
        rationals[str(var)] = rational
    return rationals


def decide(obligation: Obligation, timeout_ms: int = DEFAULT_TIMEOUT_MS) -> Outcome:
    """PROVED (no model of hypotheses and not goal), REFUTED (with a model) or UNKNOWN."""
    solver = z3.SolverFor(_LOGIC)
    solver.set("random_seed", _SEED)
    solver.set("timeout", timeout_ms)
    solver.add(*obligation.hypotheses, z3.Not(obligation.goal))
    answer = solver.check()
    if answer == z3.unsat:
        verdict, model, reason = Verdict.PROVED, {}, ""
    elif answer == z3.sat:
        verdict, model, reason = Verdict.REFUTED, _rational_model(obligation, solver.model()), ""
    else:
        verdict, model, reason = Verdict.UNKNOWN, {}, f"z3: {solver.reason_unknown()}"
    header = [
        f"; safecase nav2 obligation: {obligation.name}",
        *(f"; claim: {line}" for line in obligation.statement.splitlines()),
        "; asserted: the hypotheses and the NEGATED claim (unsat = PROVED, sat = counterexample)",
        f"; z3 {z3.get_version_string()} said: {verdict.value}",
        f"(set-logic {_LOGIC})",
    ]
    # z3's text ends with "(check-sat)" and a newline.
    text = "\n".join(header) + "\n" + solver.to_smt2() + "(exit)\n"
    return Outcome(verdict, text, model, reason)
