"""Examples for the Kalman filter, association, lifecycle and metrics (SR-TRK-3..5)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config import TrackSection, default_config, overridden
from pipeline.track import kalman
from pipeline.track.associate import assign, cascade, gated_costs
from pipeline.track.metrics import PositionsFrame, evaluate, gospa
from pipeline.track.tracker import Detections, Tracker, TrackerError
from pipeline.types import TrackStatus


def _reid_on() -> TrackSection:
    return overridden(default_config(), {"track": {"reid_enabled": True}}).track


def _det(t: float, xy: list[tuple[float, float]], size: float = 0.5) -> Detections:
    a = np.array(xy, dtype=float).reshape(-1, 2)
    return Detections(t, a[:, 0], a[:, 1], np.full(len(a), size), np.full(len(a), 2 * size))


def test_assignment_never_returns_an_infeasible_pair_and_prefers_more_matches() -> None:
    inf = np.inf
    cost = np.array([[1.0, 2.0], [inf, 10.0]])
    rows, cols = assign(cost)
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 0), (1, 1)]
    match, free = cascade(np.array([[inf, inf], [0.5, inf]]), [np.array([True, True])])
    assert match.tolist() == [-1, 0]
    assert free.tolist() == [False, True]


def test_gates_reject_far_and_improbable_pairs() -> None:
    s_inv = np.linalg.inv(np.eye(2)[None] * 0.01).astype(np.float64)
    cost = gated_costs(
        np.zeros((1, 2)), s_inv, np.array([[0.1, 0.0], [0.5, 0.0], [5.0, 0]]), 2.0, 9.21
    )
    assert np.isfinite(cost[0, 0])
    assert np.isinf(cost[0, 1])  # within 2 m but d^2 = 25 > 9.21
    assert np.isinf(cost[0, 2])  # beyond the Euclidean pre-gate


def test_constant_velocity_is_learned() -> None:
    x, p = kalman.initiate(np.zeros((1, 2)), 0.05, 2.0)
    for k in range(1, 30):
        x, p = kalman.predict(x, p, np.array([0.1]), 1.0)
        x, p = kalman.update(x, p, np.array([[0.1 * k, -0.05 * k]]), 0.05)
    assert x[0, 2:] == pytest.approx([1.0, -0.5], abs=1e-3)


@pytest.mark.requirement(
    "SR-TRK-4", code=["pipeline/track/lifecycle.py", "pipeline/track/tracker.py"]
)
def test_lifecycle_through_dormancy_and_reidentification() -> None:
    tr = Tracker(_reid_on())
    t = 0.0
    for _ in range(4):
        tracks = tr.step(_det(t, [(2.0 + t, 1.0)]))
        t += 0.1
    assert tracks.status.tolist() == [TrackStatus.CONFIRMED]
    tid = int(tracks.track_id[0])
    statuses = []
    for _ in range(8):  # hidden: CONFIRMED -> LOST -> DORMANT
        statuses.append(int(tr.step(_det(t, [])).status[0]))
        t += 0.1
    assert TrackStatus.LOST in statuses
    assert statuses[-1] == TrackStatus.DORMANT
    tracks = tr.step(_det(t, [(2.0 + t, 1.0)]))
    assert tracks.track_id.tolist() == [tid]
    assert tracks.status.tolist() == [TrackStatus.CONFIRMED]
    assert tracks.reid_count.tolist() == [1]
    assert tracks.history_len[0] == 5
    assert tr.last_counts is not None
    assert tr.last_counts.n_reidentified == 1


def test_without_reidentification_the_object_gets_a_new_id() -> None:
    tr = Tracker(overridden(default_config(), {"track": {"reid_enabled": False}}).track)
    t = 0.0
    for _ in range(4):
        first = tr.step(_det(t, [(2.0, 1.0)]))
        t += 0.1
    for _ in range(8):
        tr.step(_det(t, []))
        t += 0.1
    again = tr.step(_det(t, [(2.0, 1.0)]))
    assert again.track_id.tolist() == [int(first.track_id[0]) + 1]


def test_a_different_size_is_not_reidentified() -> None:
    tr = Tracker(_reid_on())
    t = 0.0
    for _ in range(4):
        tr.step(_det(t, [(2.0, 1.0)], size=0.3))
        t += 0.1
    for _ in range(8):
        tr.step(_det(t, []))
        t += 0.1
    tracks = tr.step(_det(t, [(2.0, 1.0)], size=1.0))
    assert tracks.reid_count.max() == 0


def test_clock_running_backwards_is_refused() -> None:
    tr = Tracker(default_config().track)
    tr.step(_det(1.0, [(1.0, 1.0)]))
    with pytest.raises(TrackerError, match="before the previous cycle"):
        tr.step(_det(0.5, [(1.0, 1.0)]))


def test_deceleration_and_size_variance_features() -> None:
    tr = Tracker(default_config().track)
    x, v = 0.0, 2.0
    for k in range(15):
        tracks = tr.step(_det(0.1 * k, [(x, 0.0)]))
        x += v * 0.1
        v = max(v - 0.1, 0.0)  # 1 m/s^2 braking
    assert tracks.decel_mps2[0] == pytest.approx(1.0, abs=0.35)
    assert tracks.size_variance_m2[0] == pytest.approx(0.0, abs=1e-12)


def _det_with_ends(t: float, xs: list[float], occluded: list[bool]) -> Detections:
    """Detections at (x, 0) with ends at (x, -0.5) and (x, 0.5), the first end as given."""
    x = np.array(xs)
    ends = np.stack([x, np.full_like(x, -0.5), x, np.full_like(x, 0.5)], axis=1)
    occ = np.stack([np.array(occluded), np.zeros(len(xs), dtype=bool)], axis=1)
    return Detections(t, x, np.zeros_like(x), np.full_like(x, 0.3), np.ones_like(x), ends, occ)


def test_each_track_keeps_the_ends_of_the_detections_that_updated_it() -> None:
    tr = Tracker(overridden(default_config(), {"track": {"max_detections": 2}}).track)
    for k in range(3):
        # Three detections, the farthest (x = 9) beyond the cap of two: its ends go with it.
        tracks = tr.step(_det_with_ends(0.1 * k, [9.0, 2.0, 4.0], [True, k == 2, False]))
    assert tracks.n == 2
    order = np.argsort(tracks.state[:, 0])
    near, far = order[0], order[1]
    assert tracks.history_end_xy_m[near, -3:, 0] == pytest.approx([2.0] * 3)
    assert tracks.history_end_xy_m[far, -3:, 3] == pytest.approx([0.5] * 3)
    assert tracks.history_end_occluded[near, -3:, 0].tolist() == [0.0, 0.0, 1.0]
    assert tracks.history_end_occluded[far, -3:].tolist() == [[0.0, 0.0]] * 3
    assert np.isnan(tracks.history_end_xy_m[:, :-3]).all()  # padding before the first update
    # Detections without ends (an older caller) leave NaN in those entries.
    tracks = tr.step(_det(0.3, [(2.0, 0.0), (4.0, 0.0)]))
    assert np.isnan(tracks.history_end_xy_m[:, -1]).all()
    assert np.isnan(tracks.history_end_occluded[:, -1]).all()


def test_a_reused_slot_starts_without_the_old_tracks_ends() -> None:
    tr = Tracker(default_config().track)
    tr.step(_det_with_ends(0.0, [3.0], [True]))
    for k in (1, 2):  # a tentative track that misses is dropped and frees its slot
        tr.step(_det(0.1 * k, []))
    tracks = tr.step(_det_with_ends(0.3, [6.0], [False]))
    assert tracks.n == 1
    assert tracks.history_end_xy_m[0, -1, 0] == 6.0
    assert np.isnan(tracks.history_end_xy_m[0, :-1]).all()
    assert np.isnan(tracks.history_end_occluded[0, :-1]).all()


def test_detections_refuse_half_or_misshapen_ends() -> None:
    x = np.zeros(2)
    with pytest.raises(TrackerError, match="come together"):
        Detections(0.0, x, x, x, x, np.zeros((2, 4)))
    with pytest.raises(TrackerError, match=r"end_xy_m must have shape \(2, 4\)"):
        Detections(0.0, x, x, x, x, np.zeros((2, 2)), np.zeros((2, 2), dtype=bool))


def test_metrics_count_an_id_switch_and_a_fragmentation() -> None:
    truth = [PositionsFrame(np.array([0]), np.array([[0.0, 0.0]])) for _ in range(4)]
    hyps = [
        PositionsFrame(np.array([7]), np.array([[0.1, 0.0]])),
        PositionsFrame(np.array([], dtype=np.int64), np.zeros((0, 2))),
        PositionsFrame(np.array([9]), np.array([[0.0, 0.1]])),
        PositionsFrame(np.array([9]), np.array([[0.0, 0.0]])),
    ]
    q = evaluate(truth, hyps)
    assert (q.id_switches, q.fragmentations, q.n_misses, q.n_false_positives) == (1, 1, 1, 0)
    assert q.mota == pytest.approx(0.5)
    assert gospa(np.zeros((1, 2)), np.zeros((0, 2)), 2.0, 2.0)[0] == pytest.approx(2.0**0.5)


@pytest.mark.requirement("SR-FUS-9", kind="example", code=["pipeline/track/tracker.py"])
def test_correct_writes_live_tracks_only_and_the_next_prediction_starts_from_it() -> None:
    """Another sensor's refinement replaces a live track's filtered state; dormant and unknown
    IDs are left alone; the next step predicts from the refined state."""
    tr = Tracker(default_config().track)
    t = 0.0
    for k in range(6):  # two objects; the second stops being seen after three scans
        t = 0.1 * k
        xy = [(2.0 + t, 1.0)] + ([(6.0, -2.0)] if k < 3 else [])
        tracks = tr.step(_det(t, xy))
    status = dict(zip(tracks.track_id.tolist(), tracks.status.tolist(), strict=True))
    seen, unseen = (int(i) for i in tracks.track_id)
    assert status[seen] == TrackStatus.CONFIRMED
    before = tr.snapshot()
    refined = before.state.copy()
    refined[:, 2:] = [[5.0, 0.0], [0.0, 5.0]]
    cov = before.covariance * 0.5
    unknown = max(seen, unseen) + 100
    ids = np.array([seen, unseen, unknown])
    state3 = np.vstack([refined, refined[:1]])
    cov3 = np.concatenate([cov, cov[:1]])
    live_unseen = status[unseen] != TrackStatus.DORMANT
    written = tr.correct(ids, state3, cov3)
    assert written == 1 + int(live_unseen)
    after = tr.snapshot()
    row = {int(i): r for r, i in enumerate(after.track_id)}
    np.testing.assert_array_equal(after.state[row[seen]], refined[0])
    np.testing.assert_array_equal(after.covariance[row[seen]], cov[0])
    # The next step predicts from the refined velocity (5 m/s along x over 0.1 s).
    nxt = tr.step(_det(t + 0.1, []))
    r = {int(i): k for k, i in enumerate(nxt.track_id)}[seen]
    assert nxt.state[r, 0] == pytest.approx(refined[0, 0] + 0.5, abs=1e-9)


@pytest.mark.requirement("SR-FUS-9", kind="example", code=["pipeline/track/tracker.py"])
def test_correct_leaves_a_dormant_track_alone() -> None:
    tr = Tracker(_reid_on())  # without re-identification a lost track is deleted, not dormant
    for k in range(4):
        tr.step(_det(0.1 * k, [(2.0, 1.0)]))
    k = 4
    while True:  # unseen until dormant
        tracks = tr.step(_det(0.1 * k, []))
        k += 1
        if tracks.n and tracks.status[0] == TrackStatus.DORMANT:
            break
        assert k < 50
    before = tr.snapshot()
    assert tr.correct(before.track_id, before.state + 1.0, before.covariance) == 0
    np.testing.assert_array_equal(tr.snapshot().state, before.state)
