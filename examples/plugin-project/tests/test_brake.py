"""Evidence for NAV-BRK-001 and NAV-BRK-002."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from navlib import stopping_distance_m


@pytest.mark.requirement("NAV-BRK-001")
def test_known_value(evidence):
    evidence.table("cases", ["v_mps", "a_mps2", "d_m"], [[2.0, 1.0, 2.0]])
    assert stopping_distance_m(2.0, 1.0) == 2.0


@pytest.mark.requirement("NAV-BRK-002")
@settings(max_examples=30, derandomize=True, database=None)
@given(st.floats(0, 5), st.floats(0, 5))
def test_monotone(v1, v2):
    lo, hi = sorted((v1, v2))
    assert stopping_distance_m(lo, 1.5) <= stopping_distance_m(hi, 1.5)
