"""Data association: gates, Hungarian assignment and the cascade (requirement SR-TRK-4).

A track-detection pair is feasible only when it passes both gates: the Euclidean pre-gate
(centroid distance to the predicted position, cheap, rejects most pairs) and then the
Mahalanobis gate ``y' S^-1 y <= chi2`` on the innovation ``y`` with the track's innovation
covariance ``S``. Feasible pairs cost their Mahalanobis distance squared. The assignment is
the optimal one (scipy's ``linear_sum_assignment``, the Hungarian problem) among assignments
with the largest number of feasible pairs; infeasible pairs are never returned, so no
detection feeds two tracks and no track takes two detections.

The cascade runs stages in order (confirmed tracks first, then tentative ones, then dormant
re-identification), each on the detections earlier stages left over.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.types import BoolArray, FloatArray, IntArray

__all__ = ["CascadeAssociator", "assign", "cascade", "gated_costs"]


def gated_costs(
    predicted_xy_m: FloatArray,
    s_inv: FloatArray,
    detections_xy_m: FloatArray,
    gate_m: float,
    gate_chi2: float,
) -> FloatArray:
    """Cost matrix (tracks x detections): Mahalanobis d^2 where both gates pass, else inf.

    ``predicted_xy_m`` (t, 2) predicted positions, ``s_inv`` (t, 2, 2) inverse innovation
    covariances, ``detections_xy_m`` (d, 2); ``gate_m`` the Euclidean pre-gate in metres and
    ``gate_chi2`` the Mahalanobis gate on d^2.
    """
    dx = detections_xy_m[None, :, 0] - predicted_xy_m[:, 0, None]
    dy = detections_xy_m[None, :, 1] - predicted_xy_m[:, 1, None]
    near = dx * dx + dy * dy <= gate_m * gate_m
    a = s_inv[:, 0, 0, None]
    b = (s_inv[:, 0, 1] + s_inv[:, 1, 0])[:, None]
    c = s_inv[:, 1, 1, None]
    d2 = a * dx * dx + b * dx * dy + c * dy * dy
    return np.where(near & (d2 <= gate_chi2), d2, np.inf)


def assign(cost: FloatArray) -> tuple[IntArray, IntArray]:
    """Optimal assignment of rows to columns over the finite entries of ``cost``.

    Returns matched ``(rows, cols)``; every returned pair has a finite cost, each row and
    each column appears at most once. Among assignments with the most finite pairs, the sum of
    costs is minimal (infeasible pairs get a penalty larger than any feasible total).
    """
    empty = np.empty(0, dtype=np.int64)
    finite = np.isfinite(cost)
    rows = np.flatnonzero(finite.any(axis=1))
    cols = np.flatnonzero(finite.any(axis=0))
    if rows.shape[0] == 0:
        return empty, empty
    sub = cost[np.ix_(rows, cols)]
    sub_finite = np.isfinite(sub)
    penalty = (float(sub[sub_finite].max()) + 1.0) * (min(sub.shape) + 1.0)
    r, c = linear_sum_assignment(np.where(sub_finite, sub, penalty))
    ok = sub_finite[r, c]
    return rows[r[ok]].astype(np.int64), cols[c[ok]].astype(np.int64)


def cascade(
    cost: FloatArray, stages: Sequence[BoolArray], available: BoolArray | None = None
) -> tuple[IntArray, BoolArray]:
    """Assign rows stage by stage: ``stages`` are row masks, earlier stages choose first.

    Returns ``match`` (column matched by each row or -1) and the mask of columns still
    unmatched. ``available`` optionally restricts the columns from the start.
    """
    n_rows, n_cols = cost.shape
    match = np.full(n_rows, -1, dtype=np.int64)
    free = np.ones(n_cols, dtype=bool) if available is None else available.copy()
    for stage in stages:
        rows = np.flatnonzero(stage)
        cols = np.flatnonzero(free)
        if rows.shape[0] == 0 or cols.shape[0] == 0:
            continue
        r, c = assign(cost[np.ix_(rows, cols)])
        match[rows[r]] = cols[c]
        free[cols[c]] = False
    return match, free


@dataclass(frozen=True)
class CascadeAssociator:
    """The association role's default: the Hungarian :func:`cascade` over priority groups."""

    def associate(
        self, cost: FloatArray, groups: Sequence[BoolArray]
    ) -> tuple[IntArray, BoolArray]:
        """Each track's matched detection (-1 none) and the detections left free."""
        return cascade(cost, groups)
