"""Piecewise and root helpers that keep a safety formula ONE definition with several readings.

A safety formula in safecase (stopping distance, safe speed, margin by confidence) is written
once with ``+ - * /`` and comparisons, so that the same Python function evaluates

* with ``float`` (and :class:`fractions.Fraction`, the exact reading used by cross-checks),
* with ``numpy`` arrays (the vectorised runtime reading),
* with z3 arithmetic terms (the symbolic reading that the proofs quantify over).

The few operations that are not plain arithmetic (a choice, a maximum, a square root) go
through the helpers below, which dispatch on the type of their arguments: ``z3.If`` for z3
terms, ``numpy.where`` / ``numpy.maximum`` for arrays, a conditional expression for scalars.
The dispatch changes how an operation is computed, never what it means, so a proof about the
z3 reading is a proof about the runtime function.

:func:`sqrt` returns ``x ** (1/2)`` for z3 terms; :mod:`properties.smt` replaces each such term
by a fresh variable ``r`` constrained by ``x >= 0 => (r >= 0 and r * r = x)`` before solving
and exporting, which keeps the obligation in standard SMT-LIB ``QF_NRA`` and is sound for
negative ``x`` too (``r`` is then left free).
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any, TypeAlias

import numpy as np
import z3

__all__ = ["Real", "is_symbolic", "maximum", "minimum", "select", "sqrt"]

# float, Fraction, numpy array or z3 arithmetic term: whatever supports + - * / and comparison.
# Kept as Any on purpose: the readings share operators, not a common nominal type.
Real: TypeAlias = Any


def is_symbolic(*values: Any) -> bool:
    """True when any value is a z3 expression (the proof reading)."""
    return any(isinstance(v, z3.ExprRef) for v in values)


def _z3(value: Any) -> Any:
    # z3 coerces ints and floats itself, but not Fractions (the exact reading's parameters).
    return z3.Q(value.numerator, value.denominator) if isinstance(value, Fraction) else value


def _is_array(*values: Any) -> bool:
    return any(isinstance(v, np.ndarray) for v in values)


def select(condition: Any, if_true: Real, if_false: Real) -> Real:
    """``if_true`` where ``condition`` holds, else ``if_false`` (z3.If / numpy.where / ternary).

    Both branches are evaluated in every reading, so each must be defined (no division by
    zero) whatever the condition.
    """
    if is_symbolic(condition, if_true, if_false):
        return z3.If(condition, _z3(if_true), _z3(if_false))
    if _is_array(condition, if_true, if_false):
        return np.where(condition, if_true, if_false)
    return if_true if condition else if_false


def maximum(a: Real, b: Real) -> Real:
    """The larger of ``a`` and ``b`` (elementwise for arrays)."""
    if is_symbolic(a, b):
        return z3.If(a >= b, _z3(a), _z3(b))
    if _is_array(a, b):
        return np.maximum(a, b)
    return a if a >= b else b


def minimum(a: Real, b: Real) -> Real:
    """The smaller of ``a`` and ``b`` (elementwise for arrays)."""
    if is_symbolic(a, b):
        return z3.If(a <= b, _z3(a), _z3(b))
    if _is_array(a, b):
        return np.minimum(a, b)
    return a if a <= b else b


def sqrt(x: Real) -> Real:
    """Non-negative square root of ``x >= 0``.

    Floats and arrays use the correctly rounded IEEE square root; z3 terms become
    ``x ** (1/2)`` (see the module docstring for how proofs treat it). A Fraction has no exact
    square root in general, so the exact reading refuses rather than silently rounding.
    """
    if is_symbolic(x):
        return x ** z3.Q(1, 2)
    if isinstance(x, Fraction):
        raise TypeError(f"sqrt: no exact square root of the Fraction {x}; use floats or z3")
    if _is_array(x):
        return np.sqrt(x)
    return math.sqrt(x)
