"""The runtime z3 call of ``nav2 check`` (SR-NAV-1, SR-NAV-4): verdicts, models, UNKNOWN."""

from __future__ import annotations

import importlib
from fractions import Fraction
from pathlib import Path

import pytest
import z3

from pipeline.config import load_config
from safety.nav2 import Verdict, check, load_params
from safety.nav2.solver import Obligation, Outcome, decide

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "nav2"


def _square(high: int, goal_max: int) -> Obligation:
    x = z3.Real("x")
    return Obligation(
        "square", f"x^2 <= {goal_max} on [0, {high}]", (x >= 0, x <= high), x * x <= goal_max, (x,)
    )


def test_proved_refuted_and_the_text_of_the_obligation() -> None:
    proved = decide(_square(1, 1))
    assert proved.verdict is Verdict.PROVED
    assert proved.model == {}
    assert "(check-sat)" in proved.smtlib
    assert "; claim: x^2 <= 1 on [0, 1]" in proved.smtlib
    refuted = decide(_square(2, 1))
    assert refuted.verdict is Verdict.REFUTED
    x = refuted.model["x"]
    assert 1 < x <= 2
    assert isinstance(x, Fraction)


def test_an_algebraic_counterexample_is_replaced_by_a_rational_one() -> None:
    # x^2 > 2 on [0, 2] with x > 1.4142: z3 may answer sqrt(2)-ish points; any rational
    # counterexample is checked again by z3 before it is reported.
    x = z3.Real("x")
    obligation = Obligation(
        "root", "x^3 <= 2", (x >= 0, x <= 2, x * x * x >= 2), x * x * x <= 2, (x,)
    )
    outcome = decide(obligation)
    assert outcome.verdict is Verdict.REFUTED
    value = outcome.model["x"]
    assert value**3 > 2


@pytest.mark.requirement("SR-NAV-4", kind="example", code=["safety/nav2/verdicts.py"])
def test_an_unknown_answer_is_never_a_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    def undecided(obligation: Obligation, timeout_ms: int = 0) -> Outcome:
        return Outcome(Verdict.UNKNOWN, "", reason="z3: timeout")

    verdicts = importlib.import_module("safety.nav2.verdicts")
    monkeypatch.setattr(verdicts, "decide", undecided)
    config = load_config(EXAMPLES / "small-robot.toml")
    report = check(load_params(EXAMPLES / "tutorial.yaml"), config)
    assert report.findings[0].verdict is Verdict.UNKNOWN
    assert report.findings[0].detail == "z3: timeout"
    assert report.exit_code == 3
