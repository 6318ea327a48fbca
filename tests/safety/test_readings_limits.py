"""The reading helpers dispatch on every argument, in every reading (SR-STOP-1, SR-STOP-2).

One safety formula is evaluated with floats, Fractions, numpy arrays and z3 terms
(safety/model/readings.py); a proof about the z3 reading is a proof about the runtime only if
each helper picks the z3 (or numpy) form whichever of its arguments carries the z3 term (or
the array). These tests put the term or the array in each position in turn.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np
import pytest
import z3

from safety.model.readings import is_symbolic, maximum, minimum, select, sqrt

READINGS = ["safety/model/readings.py"]
x = z3.Real("x")


def _at(term: Any, value: Fraction) -> Fraction:
    """The z3 term with x = value, as an exact Fraction."""
    assert isinstance(term, z3.ExprRef)
    done = z3.simplify(z3.substitute(term, (x, z3.Q(value.numerator, value.denominator))))
    assert isinstance(done, z3.RatNumRef)
    return Fraction(done.numerator_as_long(), done.denominator_as_long())


@pytest.mark.requirement("SR-STOP-1", kind="example", code=READINGS)
def test_select_is_z3_if_whichever_argument_is_symbolic() -> None:
    half, third = Fraction(1, 2), Fraction(1, 3)
    by_condition = select(x > 0, half, third)
    assert (_at(by_condition, Fraction(1)), _at(by_condition, Fraction(-1))) == (half, third)
    assert _at(select(False, x, third), Fraction(5)) == third
    assert _at(select(True, half, x), Fraction(5)) == half
    assert _at(select(True, x, third), Fraction(5)) == 5


@pytest.mark.requirement("SR-STOP-1", kind="example", code=READINGS)
def test_select_is_numpy_where_whichever_argument_is_an_array() -> None:
    np.testing.assert_array_equal(select(np.array([True, False]), 1.0, 2.0), [1.0, 2.0])
    # The scalar branch broadcast to the array's shape: an array, not the bare scalar.
    picked = select(False, np.array([1.0, 1.5]), 2.0)
    assert isinstance(picked, np.ndarray)
    assert picked.tolist() == [2.0, 2.0]
    picked = select(True, 1.0, np.array([2.0, 2.5]))
    assert isinstance(picked, np.ndarray)
    assert picked.tolist() == [1.0, 1.0]
    assert select(True, 1.0, 2.0) == 1.0
    assert select(False, 1.0, 2.0) == 2.0


@pytest.mark.requirement("SR-STOP-1", kind="example", code=READINGS)
@pytest.mark.parametrize("first_symbolic", [True, False])
def test_maximum_and_minimum_are_exact_in_z3_in_either_position(first_symbolic: bool) -> None:
    third = Fraction(1, 3)
    pair = (x, third) if first_symbolic else (third, x)
    assert is_symbolic(maximum(*pair))
    assert is_symbolic(minimum(*pair))
    for value in (Fraction(0), third, Fraction(1)):
        assert _at(maximum(*pair), value) == max(value, third)
        assert _at(minimum(*pair), value) == min(value, third)


@pytest.mark.requirement("SR-STOP-1", kind="example", code=READINGS)
def test_maximum_and_minimum_are_elementwise_whichever_argument_is_an_array() -> None:
    a = np.array([1.0, 4.0])
    b = np.array([3.0, 2.0])
    np.testing.assert_array_equal(maximum(a, b), [3.0, 4.0])
    np.testing.assert_array_equal(minimum(a, b), [1.0, 2.0])
    np.testing.assert_array_equal(maximum(2.0, a), [2.0, 4.0])
    np.testing.assert_array_equal(maximum(a, 2.0), [2.0, 4.0])
    np.testing.assert_array_equal(minimum(2.0, a), [1.0, 2.0])
    np.testing.assert_array_equal(minimum(a, 2.0), [1.0, 2.0])


@pytest.mark.requirement("SR-STOP-1", kind="example", code=READINGS)
def test_maximum_and_minimum_of_scalars_pick_the_right_one() -> None:
    assert (maximum(1.0, 2.0), maximum(2.0, 1.0)) == (2.0, 2.0)
    assert (minimum(1.0, 2.0), minimum(2.0, 1.0)) == (1.0, 1.0)
    assert minimum(Fraction(1, 3), Fraction(1, 2)) == Fraction(1, 3)


@pytest.mark.requirement("SR-STOP-1", kind="example", code=READINGS)
def test_sqrt_in_each_reading() -> None:
    assert sqrt(6.25) == 2.5
    np.testing.assert_array_equal(sqrt(np.array([4.0, 9.0])), [2.0, 3.0])
    assert is_symbolic(sqrt(x))
    with pytest.raises(TypeError, match="no exact square root of the Fraction 1/2"):
        sqrt(Fraction(1, 2))
