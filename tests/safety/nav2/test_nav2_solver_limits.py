"""The z3 call of ``nav2 check`` at its edges (SR-NAV-1, SR-NAV-4): integers, algebraic
counterexamples, and a claim z3 cannot decide."""

from __future__ import annotations

from fractions import Fraction

import pytest
import z3

from safety.nav2.solver import Obligation, Verdict, decide

CODE = ["safety/nav2/solver.py"]


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_an_integer_counterexample_is_a_whole_fraction() -> None:
    i = z3.Int("i")
    outcome = decide(Obligation("int", "i < 3 on [3, 5]", (i >= 3, i <= 5), i < 3, (i,)))
    assert outcome.verdict is Verdict.REFUTED
    value = outcome.model["i"]
    assert isinstance(value, Fraction)
    assert value.denominator == 1
    assert 3 <= value <= 5


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_counterexample_only_at_an_irrational_point_is_approximated_to_twenty_digits() -> None:
    """The only counterexample is x = sqrt(2): no rational point is one, so the report gives
    its 20-digit approximation, which the exact reading says is not confirmed."""
    x = z3.Real("x")
    obligation = Obligation("thin", "x <= 1 where x^2 = 2", (x >= 0, x * x == 2), x <= 1, (x,))
    outcome = decide(obligation)
    assert outcome.verdict is Verdict.REFUTED
    value = outcome.model["x"]
    assert isinstance(value, Fraction)
    assert value * value != 2
    # 20 digits leave |x^2 - 2| near 1e-24; 19 would leave near 1e-23.
    assert abs(value * value - 2) < Fraction(1, 10**24)
    assert value == Fraction(3419358580004036860274167, 2417851639229258349412352)
    assert outcome.reason == ""
    said = f"; z3 {z3.get_version_string()} said: REFUTED\n(set-logic QF_NRA)\n"
    assert said in outcome.smtlib


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_beside_an_algebraic_value_integers_and_rationals_are_kept_exact() -> None:
    """Only the irrational value is approximated: the integer and the rational of the same
    counterexample are z3's own."""
    x, q = z3.Reals("x q")
    i = z3.Int("i")
    hypotheses = (x >= 0, x * x == 2, i == 7, q == z3.Q(1, 3))
    outcome = decide(Obligation("mixed", "x <= 1 where x^2 = 2", hypotheses, x <= 1, (i, x, q)))
    assert outcome.verdict is Verdict.REFUTED
    assert outcome.model == {
        "i": Fraction(7),
        "x": Fraction(3419358580004036860274167, 2417851639229258349412352),
        "q": Fraction(1, 3),
    }


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_claim_z3_cannot_decide_is_unknown_with_its_reason() -> None:
    """i^2 = 2 j^2 has no positive integer solution (sqrt(2) is irrational), which z3's
    nonlinear integer reasoning can neither refute nor prove: the answer is UNKNOWN, never a
    pass, and the text says so."""
    i, j = z3.Ints("i j")
    obligation = Obligation(
        "undecided", "no i, j > 0 with i^2 = 2 j^2", (i > 0, j > 0), i * i != 2 * j * j, (i, j)
    )
    outcome = decide(obligation, timeout_ms=100)
    assert outcome.verdict is Verdict.UNKNOWN
    assert outcome.reason == "z3: timeout"
    assert outcome.model == {}
    assert " said: UNKNOWN\n" in outcome.smtlib
    assert outcome.smtlib.endswith("(exit)\n")


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_a_variable_the_claim_does_not_constrain_still_gets_a_value() -> None:
    """A counterexample names every variable of the obligation, also one no hypothesis or goal
    mentions (z3 completes the model with 0)."""
    x, y = z3.Reals("x y")
    obligation = Obligation("free", "x <= 1 on [0, 2]", (x >= 0, x <= 2), x <= 1, (x, y))
    outcome = decide(obligation)
    assert outcome.verdict is Verdict.REFUTED
    assert outcome.model == {"x": Fraction(3, 2), "y": Fraction(0)}


@pytest.mark.requirement("SR-NAV-1", kind="example", code=CODE)
def test_the_smtlib_text_says_what_was_asserted_and_ends_with_the_check() -> None:
    x = z3.Real("x")
    outcome = decide(Obligation("p", "x <= 1 on [0, 1]", (x >= 0, x <= 1), x <= 1, (x,)))
    assert outcome.verdict is Verdict.PROVED
    assert outcome.reason == ""
    lines = outcome.smtlib.splitlines()
    assert lines[:3] == [
        "; safecase nav2 obligation: p",
        "; claim: x <= 1 on [0, 1]",
        "; asserted: the hypotheses and the NEGATED claim (unsat = PROVED, sat = counterexample)",
    ]
    assert outcome.smtlib.endswith(")\n(check-sat)\n(exit)\n")
