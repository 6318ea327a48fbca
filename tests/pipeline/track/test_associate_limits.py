"""Gates and assignment where the mutation campaign found them unwatched (SR-TRK-4).

The gaps (SR-EVD-6, docs/findings/mutation.md): no test put a detection exactly on either
gate's edge, or beyond the Euclidean gate along y alone with a covariance wide enough for the
Mahalanobis gate to pass it; no assignment had a unique optimum that differs from pairing row
i with column i, or a cheaper pairing with fewer feasible pairs (the penalty's job); and the
cascade's mask of free detections was only ever read as truth values.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.track.associate import assign, cascade, gated_costs

ASSOCIATE = ["pipeline/track/associate.py"]
INF = np.inf


@pytest.mark.requirement("SR-TRK-4", kind="example", code=ASSOCIATE)
def test_both_gates_are_closed_and_the_euclidean_one_counts_both_axes() -> None:
    """A detection exactly ``gate_m`` away (2 m, exact in binary) passes the Euclidean gate,
    one exactly at ``gate_chi2`` passes the Mahalanobis gate; 2 m away along y alone is
    outside a 1.5 m gate even when the covariance is wide enough for the Mahalanobis gate."""
    predicted = np.zeros((1, 2))
    wide = np.array([[[0.25, 0.0], [0.0, 0.25]]])  # S = 4 I: d^2 = |y|^2 / 4
    on_edge = gated_costs(predicted, wide, np.array([[2.0, 0.0], [0.0, -2.0]]), 2.0, 9.0)
    assert on_edge.tolist() == [[1.0, 1.0]]
    tight = np.array([[[1.0, 0.0], [0.0, 1.0]]])  # d^2 = |y|^2: 4 exactly at chi2 = 4
    assert gated_costs(predicted, tight, np.array([[2.0, 0.0]]), 3.0, 4.0).tolist() == [[4.0]]
    assert gated_costs(predicted, tight, np.array([[2.0, 0.0]]), 3.0, 3.5).tolist() == [[INF]]
    beyond = gated_costs(predicted, wide, np.array([[0.0, 2.0], [2.0, 0.0]]), 1.5, 9.0)
    assert beyond.tolist() == [[INF, INF]]


@pytest.mark.requirement("SR-TRK-4", kind="example", code=ASSOCIATE)
def test_the_assignment_is_the_optimum_not_the_diagonal() -> None:
    """Row 0 is cheapest with column 1 and row 1 with column 0: the optimum crosses."""
    rows, cols = assign(np.array([[5.0, 1.0], [1.0, 5.0]]))
    assert (rows.tolist(), cols.tolist()) == ([0, 1], [1, 0])
    rows, cols = assign(np.array([[5.0, 1.0, INF], [1.0, 5.0, INF], [INF, INF, 2.0]]))
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 1), (1, 0), (2, 2)]


@pytest.mark.requirement("SR-TRK-4", kind="example", code=ASSOCIATE)
def test_more_feasible_pairs_win_over_a_cheaper_total() -> None:
    """Row 0 with column 0 costs 0 but leaves row 1 nothing feasible; the two feasible pairs
    (0, 1) and (1, 0) cost 20 together: the assignment takes both (the infeasible pair's
    penalty must exceed any feasible total)."""
    rows, cols = assign(np.array([[0.0, 10.0], [10.0, INF]]))
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 1), (1, 0)]
    rows, cols = assign(np.array([[0.0, 10.0, 10.0], [10.0, INF, INF], [10.0, INF, INF]]))
    assert len(rows) == 2
    assert 0 in rows.tolist()
    assert cols[rows.tolist().index(0)] != 0


@pytest.mark.requirement("SR-TRK-4", kind="example", code=ASSOCIATE)
def test_the_cascade_returns_an_integer_match_and_a_boolean_mask() -> None:
    """Confirmed row 1 chooses first and takes column 0; row 0 then gets column 1; the mask of
    free columns is a bool array (callers index detections with it)."""
    cost = np.array([[1.0, 2.0, INF], [0.5, INF, INF]])
    match, free = cascade(cost, [np.array([False, True]), np.array([True, False])])
    assert match.dtype == np.int64
    assert match.tolist() == [1, 0]
    assert free.dtype == np.bool_
    assert free.tolist() == [False, False, True]
    match, free = cascade(cost, [np.array([True, True])], available=np.array([False, True, True]))
    assert match.tolist() == [1, -1]
    assert free.dtype == np.bool_
    assert free.tolist() == [False, False, True]
