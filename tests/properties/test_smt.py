"""The z3 helpers: verdicts, exact counterexamples, SMT-LIB export that another z3 re-runs."""

from __future__ import annotations

import shutil
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest
import z3

from evidence.record import current
from properties.smt import (
    Obligation,
    ProofVerdict,
    bisect_largest,
    decimal_text,
    exact_value,
    make_solver,
    prove,
    purify_roots,
    to_fraction,
    to_z3,
)
from safety.model.readings import sqrt

x, y = z3.Reals("x y")


def _z3_binary() -> str | None:
    beside = Path(sys.executable).with_name("z3")
    return str(beside) if beside.exists() else shutil.which("z3")


def test_proved_refuted_and_unknown() -> None:
    proved = prove(Obligation("square", "x^2 >= 0", (), x * x >= 0))
    assert proved.verdict is ProofVerdict.PROVED
    assert proved.model == {}
    refuted = prove(Obligation("half", "x <= 1/2 on [0, 1]", (x >= 0, x <= 1), x <= Fraction(1, 2)))
    assert refuted.verdict is ProofVerdict.REFUTED
    (value,) = refuted.model.values()
    assert isinstance(value, Fraction)
    assert Fraction(1, 2) < value <= 1
    assert refuted.model_floats() == {"x": float(value)}
    # A variable exponent is outside what z3's real arithmetic decides: never a pass.
    unknown = prove(Obligation("power", "x^y != 3", (x > 0, y > 0), x**y != 3))
    assert unknown.verdict is ProofVerdict.UNKNOWN
    assert not unknown.proved
    assert "unknown" in unknown.reason


def test_irrational_counterexample_is_shown_as_root_object() -> None:
    result = prove(Obligation("no sqrt 2", "x^2 != 2", (x >= 0,), x * x != 2))
    assert result.verdict is ProofVerdict.REFUTED
    text = result.model["x"]
    assert isinstance(text, str)
    assert text.startswith("(root-obj")
    assert result.model_floats()["x"] != result.model_floats()["x"]  # NaN: no rational value
    assert "irrational" in result.describe_model()


def test_counterexample_is_rationalised_when_a_rational_one_exists() -> None:
    # The boundary sits at an irrational point, but any x a bit above sqrt(2) violates too.
    result = prove(Obligation("below sqrt 2", "x^2 <= 2", (x >= 0, x <= 2), x * x <= 2))
    assert result.verdict is ProofVerdict.REFUTED
    value = result.model["x"]
    assert isinstance(value, Fraction)
    assert value * value > 2


@pytest.mark.parametrize(
    ("goal", "expected"), [(x * x + 1 > 0, "unsat"), (x * x > 1, "sat")], ids=["proved", "refuted"]
)
def test_exported_smtlib_reruns_with_the_same_verdict(
    tmp_path: Path, goal: z3.BoolRef, expected: str
) -> None:
    result = prove(Obligation("rerun", "export", (x >= 0, y == sqrt(x)), z3.Or(goal, y < 0)))
    assert result.smtlib.splitlines()[0] == "; safecase proof obligation: rerun"
    assert "(set-logic QF_NRA)" in result.smtlib
    assert "^" not in result.smtlib  # roots purified: plain QF_NRA for any solver
    reparsed = z3.Solver()
    reparsed.add(z3.parse_smt2_string(result.smtlib))
    assert str(reparsed.check()) == expected
    binary = _z3_binary()
    if binary is None:
        pytest.skip("no z3 command-line binary to re-run the exported text with")
    path = tmp_path / "obligation.smt2"
    path.write_text(result.smtlib)
    done = subprocess.run([binary, str(path)], capture_output=True, text=True, check=False)
    assert done.stdout.strip().splitlines()[0] == expected


def test_purified_roots_are_sound_for_negative_radicands() -> None:
    # z3 leaves (-1)^(1/2) unspecified; the purification leaves the root free there, so a
    # claim that depends on it is refuted rather than proved vacuously.
    unguarded = prove(Obligation("root", "sqrt(x) >= 0", (), sqrt(x) >= 0))
    assert unguarded.verdict is ProofVerdict.REFUTED
    assert unguarded.model["x"] < 0  # type: ignore[operator]
    guarded = prove(Obligation("root", "sqrt(x) >= 0", (x >= 0,), sqrt(x) >= 0))
    assert guarded.verdict is ProofVerdict.PROVED
    nested = prove(
        Obligation("nested", "sqrt(sqrt(x))^4 = x", (x >= 0,), (sqrt(sqrt(x)) ** 4) == x)
    )
    assert nested.verdict is ProofVerdict.PROVED
    formulas, side, fresh = purify_roots([sqrt(x) + sqrt(x) >= sqrt(y)])
    assert len(fresh) == 2  # the shared sqrt(x) is replaced once
    assert len(side) == 2
    assert "^" not in formulas[0].sexpr()


def test_bisection_brackets_the_largest_value_by_proofs() -> None:
    def holds_up_to(c: Fraction) -> object:
        return prove(
            Obligation("square", f"x^2 <= 2 on [0, {c}]", (x >= 0, x <= to_z3(c)), x * x <= 2)
        )

    bracket = bisect_largest(holds_up_to, Fraction(0), Fraction(1))  # type: ignore[arg-type]
    assert bracket.high - bracket.low <= Fraction(1, 10**9)
    assert bracket.low * bracket.low <= 2 < bracket.high * bracket.high
    assert bracket.proved.proved
    assert bracket.refuted.verdict is ProofVerdict.REFUTED
    with pytest.raises(ValueError, match="REFUTED at the low end"):
        bisect_largest(holds_up_to, Fraction(2), Fraction(3))  # type: ignore[arg-type]


def test_exact_values_and_conversions() -> None:
    text, low, high = exact_value(x, [x >= 0, x * x == 2])
    assert text.startswith("(root-obj")
    assert low * low < 2 < high * high
    assert high - low <= Fraction(2, 10**21)
    assert exact_value(x, [3 * x == 1]) == ("1/3", Fraction(1, 3), Fraction(1, 3))
    with pytest.raises(ValueError, match="no model"):
        exact_value(x, [x > 1, x < 0])
    assert [
        decimal_text(v) for v in (Fraction(7198309035, 10**10), Fraction(-5, 4), Fraction(1, 3))
    ] == [
        "0.7198309035",
        "-1.25",
        "1/3",
    ]
    assert to_fraction(to_z3(0.1)) == Fraction(1, 10)  # the decimal, not the binary float
    assert to_fraction(to_z3(Fraction(2, 3))) == Fraction(2, 3)
    with pytest.raises(ValueError, match="positive"):
        make_solver(timeout_ms=0)


def test_attach_records_the_obligation_in_the_evidence() -> None:
    result = prove(Obligation("attached", "x^2 >= 0", (), x * x >= 0))
    result.attach(required=False)
    record = current().peek()
    assert record is not None
    detail = record.details[-1]
    assert detail["type"] == "smt"
    assert detail["verdict"] == "PROVED"
    assert detail["smtlib"] == result.smtlib
    assert detail["solver"].startswith("z3 ")
