"""Builders and strategies for fusion and monitor properties (SR-FUS-*).

:func:`make_tracks` builds a :class:`pipeline.types.Tracks` snapshot directly (positions,
velocities, statuses); the strategies draw detection ages that concentrate on the freshness
threshold (a few ulps either side), on the skew bound, and on non-finite values, because that
is where a guard goes wrong.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from hypothesis import strategies as st

from pipeline.types import FloatArray, Tracks, TrackStatus

__all__ = ["ages", "epoch", "make_tracks", "spd_matrix"]


def make_tracks(
    stamp_s: float,
    xy_m: npt.ArrayLike,
    vxy_mps: npt.ArrayLike | None = None,
    status: npt.ArrayLike | None = None,
    cov_scale: float = 0.1,
) -> Tracks:
    """A tracker snapshot with the given states (other features neutral)."""
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    n = xy.shape[0]
    v = np.zeros((n, 2)) if vxy_mps is None else np.asarray(vxy_mps, dtype=np.float64)
    s = (
        np.full(n, int(TrackStatus.CONFIRMED))
        if status is None
        else np.asarray(status, dtype=np.int64)
    )
    return Tracks(
        stamp_s=stamp_s,
        track_id=np.arange(n),
        status=s,
        state=np.concatenate([xy, v.reshape(n, 2)], axis=1),
        covariance=np.tile(np.eye(4) * cov_scale, (n, 1, 1)),
        detection_index=np.full(n, -1),
        age_frames=np.full(n, 5),
        hits=np.full(n, 5),
        misses=np.zeros(n, dtype=np.int64),
        last_update_s=np.full(n, stamp_s),
        width_m=np.full(n, 0.5),
        length_m=np.full(n, 0.8),
        size_variance_m2=np.zeros(n),
        decel_mps2=np.zeros(n),
        history_xy_m=np.full((n, 15, 2), np.nan),
        history_speed_mps=np.full((n, 15), np.nan),
        history_t_s=np.full((n, 15), np.nan),
        history_len=np.zeros(n, dtype=np.int64),
        max_width_m=np.full(n, 0.5),
        max_length_m=np.full(n, 0.8),
        reid_count=np.zeros(n, dtype=np.int64),
        history_end_xy_m=np.full((n, 15, 4), np.nan),
        history_end_occluded=np.full((n, 15, 2), np.nan),
    )


def epoch() -> st.SearchStrategy[float]:
    """Decision times: near zero (simulator), around a day, or Unix-epoch seconds."""
    return st.one_of(
        st.floats(0.0, 100.0),
        st.floats(86_000.0, 87_000.0),
        st.floats(1.6e9, 1.8e9),
    )


def _nudge(value: float, ulps: int) -> float:
    for _ in range(abs(ulps)):
        value = math.nextafter(value, math.inf if ulps > 0 else -math.inf)
    return value


@st.composite
def ages(draw: st.DrawFn, max_age_s: float, skew_s: float) -> float:
    """A detection age [s]: anywhere, at the threshold +-3 ulps, at -skew, or non-finite."""
    threshold = max_age_s - skew_s
    kind = draw(st.integers(0, 5))
    if kind == 0:
        return draw(st.floats(-2.0 * max_age_s - 0.1, 3.0 * max_age_s))
    if kind == 1:
        return _nudge(threshold, draw(st.integers(-3, 3)))
    if kind == 2:
        return _nudge(threshold - 1e-9, draw(st.integers(-3, 3)))
    if kind == 3:
        return _nudge(-skew_s, draw(st.integers(-3, 3)))
    if kind == 4:
        return draw(st.floats(0.0, threshold))
    return draw(st.sampled_from([math.nan, math.inf, -math.inf]))


def spd_matrix(rng: np.random.Generator, scale: float = 1.0) -> FloatArray:
    """A random symmetric positive definite 4x4 covariance."""
    a = rng.normal(0.0, scale, (4, 4))
    m: FloatArray = a @ a.T + np.eye(4) * 1e-3
    return m
