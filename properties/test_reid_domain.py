"""Re-identification within the operating domain (SR-AVL-7): a dormant track takes only a
detection its object can have reached, and a re-identification moves the track, never its
velocity estimate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from pipeline.config import TrackSection, default_config, overridden
from pipeline.track import kalman
from pipeline.track.tracker import Detections, Tracker, reid_reach_m
from pipeline.types import TrackStatus

CODE = ["pipeline/track/tracker.py", "pipeline/track/kalman.py"]
SIZE_M = 0.5


def _config() -> TrackSection:
    return overridden(default_config(), {"track": {"reid_enabled": True}}).track


def _det(t_s: float, xy: list[tuple[float, float]]) -> Detections:
    a = np.array(xy, dtype=float).reshape(-1, 2)
    n = a.shape[0]
    return Detections(t_s, a[:, 0], a[:, 1], np.full(n, SIZE_M), np.full(n, 2 * SIZE_M))


@pytest.mark.requirement("SR-AVL-7", kind="property", code=CODE)
@settings(max_examples=examples(60))
@given(
    vx=st.floats(-1.5, 1.5),
    vy=st.floats(-1.5, 1.5),
    hidden=st.integers(6, 25),
    bearing=st.floats(0.0, 2.0 * math.pi),
    fraction=st.floats(0.0, 2.0),
)
def test_a_dormant_track_takes_only_a_detection_within_the_domains_reach(
    vx: float, vy: float, hidden: int, bearing: float, fraction: float
) -> None:
    """A walker-sized object seen for 6 frames at constant velocity, hidden for ``hidden``
    frames (long enough to go dormant), then a detection at ``fraction`` times the domain's
    reach from the track's constant-velocity prediction, in any direction. Re-identified only
    within the reach; when re-identified, the velocity estimate is the one the track had when
    last seen and its variance grew by at least ``(a h)^2`` on each axis."""
    config = _config()
    tracker = Tracker(config)
    dt = config.frame_period_s
    t = 0.0
    for k in range(6):
        tracks = tracker.step(_det(t, [(1.0 + vx * k * dt, 2.0 + vy * k * dt)]))
        t += dt
    track_id = int(tracks.track_id[0])
    for _ in range(hidden):
        tracks = tracker.step(_det(t, []))
        t += dt
    assert tracks.status.tolist() == [TrackStatus.DORMANT]
    slot = int(np.flatnonzero(tracker.store.track_id == track_id)[0])
    last_s = float(tracker.store.last_update_s[slot])
    x_post = tracker.store.x_post[slot].copy()
    p_post = tracker.store.p_post[slot].copy()
    horizon = min(t - last_s, config.dormant_prediction_cap_s)
    mean_size = tracker.store.mean_size(np.array([slot]))
    reach = float(reid_reach_m(np.array([horizon]), mean_size.max(axis=1), config)[0])
    predicted = x_post[:2] + horizon * x_post[2:]
    offset = fraction * reach * np.array([math.cos(bearing), math.sin(bearing)])
    z = predicted + offset
    tracks = tracker.step(_det(t, [(float(z[0]), float(z[1]))]))
    row = tracks.track_id.tolist().index(track_id)  # dormant tracks are reported too
    reidentified = bool(tracks.reid_count[row] == 1)
    event("re-identified" if reidentified else "new track")
    if fraction > 1.0 + 1e-9:
        assert not reidentified, (fraction, reach)
    if reidentified:
        assert tracks.status[row] == TrackStatus.CONFIRMED
        assert np.array_equal(tracks.state[row, 2:], x_post[2:])
        widen = (config.reid_max_accel_mps2 * horizon) ** 2
        cov = tracks.covariance[row]
        assert cov[2, 2] >= p_post[2, 2] + widen - 1e-9
        assert cov[3, 3] >= p_post[3, 3] + widen - 1e-9
        assert np.allclose(cov[:2, 2:], 0.0)


@pytest.mark.requirement("SR-AVL-7", kind="example", code=CODE)
def test_within_reach_a_dormant_track_is_re_identified() -> None:
    """The property above is not vacuous: a detection at its prediction is re-identified."""
    config = _config()
    tracker = Tracker(config)
    t = 0.0
    for k in range(6):
        tracks = tracker.step(_det(t, [(1.0 + 0.1 * k, 2.0)]))
        t += 0.1
    track_id = int(tracks.track_id[0])
    for _ in range(10):
        tracker.step(_det(t, []))
        t += 0.1
    tracks = tracker.step(_det(t, [(1.0 + 0.1 * 16, 2.0)]))
    assert tracks.track_id.tolist() == [track_id]
    assert tracks.reid_count.tolist() == [1]
    assert tracks.status.tolist() == [TrackStatus.CONFIRMED]


@pytest.mark.requirement("SR-AVL-7", "SR-TRK-3", kind="property", code=["pipeline/track/kalman.py"])
@settings(max_examples=examples(60))
@given(
    x=st.lists(st.floats(-5.0, 5.0), min_size=4, max_size=4),
    pos_var=st.floats(1e-4, 4.0),
    vel_var=st.floats(1e-4, 4.0),
    cross=st.floats(-0.99, 0.99),
    z=st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)),
    std=st.floats(0.01, 2.0),
    widen=st.floats(0.0, 10.0),
)
def test_reacquire_updates_the_position_as_the_filter_does_and_keeps_the_velocity(
    x: list[float],
    pos_var: float,
    vel_var: float,
    cross: float,
    z: tuple[float, float],
    std: float,
    widen: float,
) -> None:
    """Against the filter's own update on the decoupled covariance (filterpy's arithmetic,
    SR-TRK-3): the same position and position covariance; the velocity is untouched and its
    covariance grows by exactly ``widen^2`` per axis."""
    state = np.array([x])
    c = cross * math.sqrt(pos_var * vel_var)
    p = np.array([[[pos_var, 0, c, 0], [0, pos_var, 0, c], [c, 0, vel_var, 0], [0, c, 0, vel_var]]])
    zz = np.array([z])
    got_x, got_p = kalman.reacquire(state, p, zz, np.array([std]), np.array([widen]))
    decoupled = p.copy()
    decoupled[:, :2, 2:] = decoupled[:, 2:, :2] = 0.0
    want_x, want_p = kalman.update(state, decoupled, zz, std)
    assert np.allclose(got_x[:, :2], want_x[:, :2], atol=1e-9)
    assert np.allclose(got_p[:, :2, :2], want_p[:, :2, :2], atol=1e-9)
    assert np.array_equal(got_x[:, 2:], state[:, 2:])
    assert np.allclose(got_p[:, 2:, 2:], p[:, 2:, 2:] + widen * widen * np.eye(2), atol=1e-9)
    assert np.allclose(got_p[:, :2, 2:], 0.0)
