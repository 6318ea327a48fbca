"""z3 helpers for proof obligations: deterministic solver, verdicts, SMT-LIB2 export, exact models.

Used by every family whose claim is arithmetic (SR-STOP-* first). An :class:`Obligation` is a
claim (``goal``) under assumptions (``hypotheses``, the domain: configured ranges). Proving it
means asking z3 for a model of ``hypotheses and not goal``:

* ``unsat``: no counterexample exists, the verdict is **PROVED**;
* ``sat``: the model is a counterexample, the verdict is **REFUTED**, and the model is reported
  as exact rationals (``fractions.Fraction``; irrational algebraic values as z3 ``root-obj``
  text when no rational counterexample nearby can be found) and as floats;
* ``unknown`` or a timeout: **UNKNOWN**, which never counts as a pass.

Square roots written ``x ** (1/2)`` (what :func:`safety.model.readings.sqrt` gives in the z3
reading) are replaced by fresh variables ``r`` with ``x >= 0 => (r >= 0 and r * r = x)`` before
solving, so the solver sees, and the exported text holds, plain ``QF_NRA``: any SMT-LIB solver can
re-run the obligation. The exported text is exactly what z3 was given (same assertions, same order).
:meth:`ProofResult.attach` adds the obligation to the running test's evidence.
"""

from __future__ import annotations

import enum
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import z3

from evidence.record import current

__all__ = [
    "DEFAULT_TIMEOUT_MS",
    "Bracket",
    "Obligation",
    "ProofResult",
    "ProofVerdict",
    "bisect_largest",
    "decimal_text",
    "exact_value",
    "make_solver",
    "prove",
    "purify_roots",
    "solver_version",
    "to_fraction",
    "to_z3",
]

DEFAULT_TIMEOUT_MS = 10_000
DEFAULT_SEED = 0
LOGIC = "QF_NRA"
_ROOT_PREFIX = "sqrt!"


class ProofVerdict(enum.Enum):
    """The outcome of an obligation; only PROVED is a pass."""

    PROVED = "PROVED"
    REFUTED = "REFUTED"
    UNKNOWN = "UNKNOWN"


@dataclass(frozen=True, slots=True)
class Obligation:
    """A claim to prove for every assignment satisfying the hypotheses.

    ``variables`` are the quantified variables shown in a counterexample (default: every
    uninterpreted constant of the formula except the square-root auxiliaries).
    """

    name: str
    statement: str
    hypotheses: tuple[z3.BoolRef, ...]
    goal: z3.BoolRef
    variables: tuple[z3.ArithRef, ...] = ()


@dataclass(frozen=True, slots=True)
class ProofResult:
    """What z3 said about one obligation, with everything needed to re-run it elsewhere."""

    name: str
    statement: str
    verdict: ProofVerdict
    smtlib: str
    model: dict[str, Fraction | str] = field(default_factory=dict)
    solver: str = ""
    time_s: float = 0.0
    reason: str = ""

    @property
    def proved(self) -> bool:
        """True iff the verdict is PROVED."""
        return self.verdict is ProofVerdict.PROVED

    def model_floats(self) -> dict[str, float]:
        """The counterexample as floats (NaN for an irrational value shown as ``root-obj``)."""
        return {
            k: float(v) if isinstance(v, Fraction) else float("nan") for k, v in self.model.items()
        }

    def describe_model(self) -> str:
        """``v = 15/16 (0.9375), b = 21/16 (1.3125)``: exact and float side by side."""
        parts = []
        for name, value in self.model.items():
            shown = f"{float(value):.9g}" if isinstance(value, Fraction) else "irrational"
            parts.append(f"{name} = {value} ({shown})")
        return ", ".join(parts)

    def attach(self, *, required: bool = True) -> None:
        """Attach to the running test's evidence (SMT-LIB text, model, solver, time)."""
        current().smt(
            self.name,
            self.verdict.value,
            self.smtlib,
            model=dict(self.model),
            solver=self.solver,
            time_s=self.time_s,
            required=required,
            statement=self.statement + (f" [{self.reason}]" if self.reason else ""),
        )


def solver_version() -> str:
    """``z3 4.x.y`` as reported by the linked library."""
    return f"z3 {z3.get_version_string()}"


def make_solver(timeout_ms: int = DEFAULT_TIMEOUT_MS, seed: int = DEFAULT_SEED) -> z3.Solver:
    """A ``QF_NRA`` solver with a fixed random seed and a timeout (deterministic runs)."""
    if timeout_ms <= 0:
        raise ValueError(f"timeout_ms = {timeout_ms}: expected a positive number of milliseconds")
    solver = z3.SolverFor(LOGIC)
    solver.set("random_seed", seed)
    solver.set("timeout", timeout_ms)
    return solver


def to_z3(value: Fraction | int | float) -> z3.ArithRef:
    """An exact z3 real: Fractions and ints exactly, floats as the decimal they print as."""
    if isinstance(value, float):
        value = Fraction(repr(value))
    fraction = Fraction(value)
    return z3.Q(fraction.numerator, fraction.denominator)


def to_fraction(value: z3.ExprRef) -> Fraction | str:
    """A model value as a Fraction, or the ``root-obj`` text of an irrational algebraic one."""
    if z3.is_rational_value(value):
        return Fraction(value.as_fraction())
    if z3.is_int_value(value):
        return Fraction(value.as_long())
    if z3.is_algebraic_value(value):
        return str(value.sexpr())
    if z3.is_true(value):
        return Fraction(1)
    if z3.is_false(value):
        return Fraction(0)
    raise ValueError(f"to_fraction: {value.sexpr()} is not a numeric model value")


def _is_square_root(expr: z3.ExprRef) -> bool:
    if not z3.is_app_of(expr, z3.Z3_OP_POWER):
        return False
    exponent = expr.arg(1)
    return bool(z3.is_rational_value(exponent)) and Fraction(exponent.as_fraction()) == Fraction(
        1, 2
    )


def purify_roots(
    formulas: Sequence[z3.BoolRef],
) -> tuple[list[z3.BoolRef], list[z3.BoolRef], list[z3.ArithRef]]:
    """Replace every ``x ** (1/2)`` by a fresh ``r`` with ``x >= 0 => (r >= 0 and r*r = x)``.

    Returns the rewritten formulas, the side constraints and the fresh variables. Innermost
    roots are replaced first, so nested roots work. Sound whatever the sign of ``x``: for
    negative ``x``, ``r`` is unconstrained, i.e. every value z3 might give ``x ** (1/2)`` there.
    """
    side: list[z3.BoolRef] = []
    fresh: list[z3.ArithRef] = []
    cache: dict[int, z3.ExprRef] = {}

    def rewrite(expr: z3.ExprRef) -> z3.ExprRef:
        key = expr.get_id()
        if key in cache:
            return cache[key]
        if z3.is_app(expr) and expr.num_args() > 0:
            args = [rewrite(expr.arg(i)) for i in range(expr.num_args())]
            changed = any(not a.eq(expr.arg(i)) for i, a in enumerate(args))
            rebuilt = expr.decl()(*args) if changed else expr
            if _is_square_root(rebuilt):
                radicand = rebuilt.arg(0)
                root = z3.Real(f"{_ROOT_PREFIX}{len(fresh)}")
                fresh.append(root)
                side.append(z3.Implies(radicand >= 0, z3.And(root >= 0, root * root == radicand)))
                rebuilt = root
            cache[key] = rebuilt
            return rebuilt
        cache[key] = expr
        return expr

    rewritten = [rewrite(f) for f in formulas]
    return rewritten, side, fresh


def _constants(formulas: Iterable[z3.ExprRef]) -> list[z3.ExprRef]:
    seen: dict[str, z3.ExprRef] = {}
    stack = list(formulas)
    visited: set[int] = set()
    while stack:
        expr = stack.pop()
        if expr.get_id() in visited:
            continue
        visited.add(expr.get_id())
        if z3.is_const(expr) and expr.decl().kind() == z3.Z3_OP_UNINTERPRETED:
            seen.setdefault(expr.decl().name(), expr)
        elif z3.is_app(expr):
            stack.extend(expr.arg(i) for i in range(expr.num_args()))
    return [seen[k] for k in sorted(seen)]


def decimal_text(value: Fraction) -> str:
    """An exact rational as text: a terminating decimal in full (``0.7198309035``), else ``p/q``."""
    value = Fraction(value)
    rest, twos, fives = value.denominator, 0, 0
    while rest % 2 == 0:
        rest, twos = rest // 2, twos + 1
    while rest % 5 == 0:
        rest, fives = rest // 5, fives + 1
    digits = max(twos, fives)
    if rest != 1 or digits > 40:
        return str(value)
    whole = str(abs(value.numerator) * 10**digits // value.denominator).rjust(digits + 1, "0")
    text = whole[: len(whole) - digits] + ("." + whole[len(whole) - digits :] if digits else "")
    return ("-" if value < 0 else "") + text


def _smtlib_text(obligation: Obligation, solver: z3.Solver, verdict: str) -> str:
    header = [
        f"; safecase proof obligation: {obligation.name}",
        *(f"; claim: {line}" for line in obligation.statement.splitlines() or [""]),
        "; the assertions are the hypotheses (domain) and the NEGATED claim:",
        ";   unsat = the claim holds for every assignment (PROVED); sat = counterexample",
        f"; {solver_version()} said: {verdict}",
        f"(set-logic {LOGIC})",
    ]
    body: str = solver.to_smt2()
    return "\n".join(header) + "\n" + body.rstrip("\n") + "\n(exit)\n"


def _counterexample(
    obligation: Obligation,
    solver: z3.Solver,
    negated: Sequence[z3.BoolRef],
    timeout_ms: int,
    seed: int,
) -> dict[str, Fraction | str]:
    model = solver.model()
    shown = list(obligation.variables) or [
        c for c in _constants(negated) if not c.decl().name().startswith(_ROOT_PREFIX)
    ]
    exact = {str(v): to_fraction(model.eval(v, model_completion=True)) for v in shown}
    if all(isinstance(x, Fraction) for x in exact.values()):
        return exact
    # Irrational values (nlsat may pick algebraic points): look for a rational counterexample
    # nearby, confirmed by z3 with every shown variable fixed to the rational value.
    for digits in (6, 10, 15, 20):
        candidate: dict[str, Fraction | str] = {}
        fixed = []
        for var in shown:
            value = model.eval(var, model_completion=True)
            rational = value.approx(digits) if z3.is_algebraic_value(value) else value
            candidate[str(var)] = to_fraction(rational)
            fixed.append(var == rational)
        check = make_solver(timeout_ms, seed)
        check.add(*negated, *fixed)
        if check.check() == z3.sat:
            return candidate
    return exact


def prove(
    obligation: Obligation, *, timeout_ms: int = DEFAULT_TIMEOUT_MS, seed: int = DEFAULT_SEED
) -> ProofResult:
    """Decide ``obligation``: PROVED (negation unsat), REFUTED (with model) or UNKNOWN."""
    negated_raw = [*obligation.hypotheses, z3.Not(obligation.goal)]
    rewritten, side, _ = purify_roots(negated_raw)
    negated = [*rewritten, *side]
    solver = make_solver(timeout_ms, seed)
    solver.add(*negated)
    start = time.perf_counter()
    answer = solver.check()
    elapsed = time.perf_counter() - start
    reason = ""
    model: dict[str, Fraction | str] = {}
    if answer == z3.unsat:
        verdict = ProofVerdict.PROVED
    elif answer == z3.sat:
        verdict = ProofVerdict.REFUTED
        model = _counterexample(obligation, solver, negated, timeout_ms, seed)
    else:
        verdict = ProofVerdict.UNKNOWN
        reason = f"z3 unknown: {solver.reason_unknown()}"
    return ProofResult(
        name=obligation.name,
        statement=obligation.statement,
        verdict=verdict,
        smtlib=_smtlib_text(obligation, solver, verdict.value),
        model=model,
        solver=solver_version(),
        time_s=elapsed,
        reason=reason,
    )


def exact_value(
    target: z3.ArithRef,
    constraints: Sequence[z3.BoolRef],
    *,
    timeout_ms: int = DEFAULT_TIMEOUT_MS,
    seed: int = DEFAULT_SEED,
) -> tuple[str, Fraction, Fraction]:
    """The value of ``target`` in a model of ``constraints`` (which should determine it).

    Returns the exact value as text (a rational ``p/q`` or a z3 ``root-obj``) and a rational
    enclosure ``(low, high)`` no wider than 1e-20. Raises ValueError when z3 finds no model.
    """
    rewritten, side, _ = purify_roots(list(constraints))
    solver = make_solver(timeout_ms, seed)
    solver.add(*rewritten, *side)
    if solver.check() != z3.sat:
        raise ValueError(f"exact_value: no model of the constraints ({solver.reason_unknown()})")
    value = solver.model().eval(target, model_completion=True)
    if z3.is_rational_value(value):
        exact = Fraction(value.as_fraction())
        return str(exact), exact, exact
    if not z3.is_algebraic_value(value):
        raise ValueError(f"exact_value: {value.sexpr()} is not a real number")
    approx = Fraction(value.approx(25).as_fraction())
    radius = Fraction(1, 10**21)
    return str(value.sexpr()), approx - radius, approx + radius


@dataclass(frozen=True, slots=True)
class Bracket:
    """``low`` PROVED and ``high`` REFUTED: the largest safe value lies in ``[low, high)``."""

    low: Fraction
    high: Fraction
    proved: ProofResult
    refuted: ProofResult
    proofs_run: int
    time_s: float


def bisect_largest(
    prove_at: Callable[[Fraction], ProofResult],
    low: Fraction,
    high: Fraction,
    *,
    tolerance: Fraction = Fraction(1, 10**9),
    max_steps: int = 200,
) -> Bracket:
    """Bracket the largest value for which a monotone obligation holds, by bisection on proofs.

    ``prove_at(low)`` must be PROVED and ``prove_at(high)`` REFUTED (``high`` is doubled until it
    is); every step is a proof, so an UNKNOWN anywhere raises rather than guess. Midpoints are
    rounded to short decimals so the SMT-LIB text stays readable.
    """
    start = time.perf_counter()
    runs = 0

    def check(value: Fraction) -> ProofResult:
        nonlocal runs
        runs += 1
        result = prove_at(value)
        if result.verdict is ProofVerdict.UNKNOWN:
            raise RuntimeError(f"bisect_largest: {result.name} UNKNOWN at {value}: {result.reason}")
        return result

    proved = check(low)
    if not proved.proved:
        raise ValueError(f"bisect_largest: {proved.name} is already REFUTED at the low end {low}")
    refuted = check(high)
    while refuted.proved:
        if runs >= max_steps:
            raise RuntimeError(f"bisect_largest: no refuted value found up to {high}")
        low, proved, high = high, refuted, high * 2
        refuted = check(high)
    while high - low > tolerance:
        if runs >= max_steps:
            raise RuntimeError("bisect_largest: tolerance not reached within max_steps")
        mid = _short_midpoint(low, high)
        result = check(mid)
        if result.proved:
            low, proved = mid, result
        else:
            high, refuted = mid, result
    return Bracket(low, high, proved, refuted, runs, time.perf_counter() - start)


def _short_midpoint(low: Fraction, high: Fraction) -> Fraction:
    """A decimal strictly between ``low`` and ``high`` near their midpoint, with few digits."""
    mid = (low + high) / 2
    width = high - low
    digits = 1
    while Fraction(1, 10**digits) * 4 > width:
        digits += 1
    rounded = Fraction(round(mid * 10**digits), 10**digits)
    return rounded if low < rounded < high else mid
