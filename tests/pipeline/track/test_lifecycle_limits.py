"""The track store's lifecycle, cycle by cycle, where the mutation campaign found it unwatched
(SR-TRK-4).

The campaign (SR-EVD-6, docs/findings/mutation.md) found that the tests reached the store only
through whole tracking runs, which judge the tracks that come out: a track confirmed one hit
early, a lost track kept one miss longer, a dormancy that started or expired one cycle late,
ages and dormancy counters counting wrongly, the returned deletion counts and the oldest-first
eviction all went unseen. Here a store with small limits (confirm after 3 hits, lost after 2
misses, dormant after 4, dormant for at most 3 cycles, 2 dormant slots) is driven hit by hit,
and every counter, status and count is compared after every cycle.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from pipeline.config import TrackSection
from pipeline.track.lifecycle import FREE, TrackStore, size_compatible
from pipeline.types import BoolArray, IntArray, TrackStatus

LIFECYCLE = ["pipeline/track/lifecycle.py"]
T, C, L, D = (
    TrackStatus.TENTATIVE,
    TrackStatus.CONFIRMED,
    TrackStatus.LOST,
    TrackStatus.DORMANT,
)


def _store(**changes: object) -> TrackStore:
    limits: dict[str, object] = {
        "confirm_hits": 3,
        "lost_after_misses": 2,
        "dormant_after_misses": 4,
        "dormant_timeout_frames": 3,
        "max_dormant": 2,
        "reid_enabled": True,
        "max_tracks": 4,
        "history_frames": 3,
        "size_variance_frames": 2,
    }
    return TrackStore(TrackSection.model_validate(limits | changes))


def _create(store: TrackStore, n: int, stamp_s: float, first_x_m: float = 0.0) -> IntArray:
    x = np.zeros((n, 4))
    x[:, 0] = first_x_m + np.arange(n)
    x[:, 1], x[:, 2], x[:, 3] = 2.0, 3.0, 4.0
    wl = np.tile([0.5, 1.5], (n, 1))
    ends = (np.zeros((n, 4)), np.zeros((n, 2)))
    return store.create(x, np.tile(np.eye(4), (n, 1, 1)), stamp_s, wl, np.arange(n), ends)


def _mask(store: TrackStore, *slots: int) -> BoolArray:
    m = np.zeros(store.capacity, dtype=bool)
    m[list(slots)] = True
    return m


def _step(
    store: TrackStore, hit: tuple[int, ...] = (), reid: tuple[int, ...] = ()
) -> tuple[int, int, int]:
    return store.advance(_mask(store, *hit, *reid), _mask(store, *reid))


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_an_empty_store_holds_free_slots_and_unknown_histories() -> None:
    store = _store()
    assert store.capacity == 6
    assert store.status.tolist() == [FREE] * 6
    assert store.track_id.tolist() == [-1] * 6
    assert store.detection_index.tolist() == [-1] * 6
    for counter in (
        store.status,
        store.track_id,
        store.hits,
        store.misses,
        store.age_frames,
        store.dormant_frames,
        store.reid_count,
        store.detection_index,
        store.hist_len,
        store.size_len,
    ):
        assert counter.dtype == np.int64
        assert counter.shape == (6,)
    for history in (store.hist_xy, store.hist_t, store.hist_speed, store.hist_end, store.hist_occ):
        assert history.dtype == np.float64
        assert np.isnan(history).all()
    assert np.isnan(store.max_wl).all()
    assert np.isnan(store.size_wl).all()
    assert store.next_id == 0
    assert not store.live.any()
    assert not store.mask(T, C, L, D).any()


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_a_new_track_starts_tentative_with_its_first_record_in_a_reused_slot() -> None:
    """Two tracks; the first, tentative, is dropped on its first miss; its slot is then
    scribbled over (as a long life would leave it) and a new track created there: every
    field starts afresh, and the ID is a new one."""
    store = _store()
    assert _create(store, 2, 1.0).tolist() == [0, 1]
    assert store.track_id[:2].tolist() == [0, 1]
    assert _step(store, (1,)) == (1, 0, 0)
    assert (store.status[0], store.track_id[0]) == (FREE, -1)
    for field in (store.hits, store.misses, store.age_frames, store.dormant_frames):
        field[0] = 7
    store.reid_count[0], store.detection_index[0] = 2, 5
    for history in (store.hist_xy, store.hist_t, store.hist_speed, store.hist_end, store.hist_occ):
        history[0] = 9.0
    store.size_wl[0], store.max_wl[0] = 9.0, 9.0
    store.heading[0], store.heading_resolved[0] = 0.5, True
    assert _create(store, 1, 2.5, first_x_m=7.0).tolist() == [0]
    assert store.track_id[:2].tolist() == [2, 1]
    assert store.status[0] == T
    assert (store.hits[0], store.misses[0], store.age_frames[0]) == (1, 0, 0)
    assert (store.dormant_frames[0], store.reid_count[0], store.detection_index[0]) == (0, 0, 0)
    assert store.last_update_s[0] == 2.5
    assert store.hist_len[0] == 1
    assert store.size_len[0] == 1
    assert np.isnan(store.hist_xy[0, :2]).all()
    assert store.hist_xy[0, -1].tolist() == [7.0, 2.0]
    assert np.isnan(store.hist_t[0, :2]).all()
    assert store.hist_t[0, -1] == 2.5
    assert np.isnan(store.hist_speed[0, :2]).all()
    assert store.hist_speed[0, -1] == 5.0
    assert np.isnan(store.hist_end[0, :2]).all()
    assert np.isnan(store.hist_occ[0, :2]).all()
    assert np.isnan(store.size_wl[0, 0]).all()
    assert store.size_wl[0, -1].tolist() == [0.5, 1.5]
    assert store.max_wl[0].tolist() == [0.5, 1.5]
    assert np.isnan(store.heading[0])
    assert not store.heading_resolved[0]
    assert store.mask(T).tolist() == [True, True, False, False, False, False]
    assert store.mask(C, L).tolist() == [False] * 6


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_the_store_refuses_more_tracks_than_free_slots_naming_both() -> None:
    store = _store(max_tracks=1, max_dormant=1)
    _create(store, 1, 0.0)
    with pytest.raises(
        RuntimeError, match=re.escape("TrackStore.create: 2 tracks requested, 1 free")
    ):
        _create(store, 2, 0.0)


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_a_record_appends_to_every_history_and_the_sizes() -> None:
    """After the first record the mean size is that box (not half of it); the second record
    shifts the histories, the size history keeps two, the largest box is kept per axis."""
    store = _store()
    (slot,) = _create(store, 1, 0.0).tolist()
    s = np.array([slot])
    assert store.mean_size(s).tolist() == [[0.5, 1.5]]
    store.x_post[slot] = [1.0, 1.0, 0.6, 0.8]
    store.record(s, 0.1, np.array([[0.9, 1.1]]), np.ones((1, 4)), np.array([[1.0, 0.0]]))
    assert store.hist_xy[slot, -2:].tolist() == [[0.0, 2.0], [1.0, 1.0]]
    assert store.hist_t[slot, -2:].tolist() == [0.0, 0.1]
    assert store.hist_speed[slot, -1] == pytest.approx(1.0)
    assert store.hist_end[slot, -1].tolist() == [1.0] * 4
    assert store.hist_occ[slot, -1].tolist() == [1.0, 0.0]
    assert store.size_wl[slot].tolist() == [[0.5, 1.5], [0.9, 1.1]]
    assert store.max_wl[slot].tolist() == [0.9, 1.5]
    assert store.mean_size(s)[0].tolist() == pytest.approx([0.7, 1.3])
    assert (store.hist_len[slot], store.size_len[slot]) == (2, 2)


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_one_track_through_every_state_cycle_by_cycle() -> None:
    """Track 0: confirmed on its third hit, lost on its second miss, back on a hit, dormant
    on its fourth miss, re-identified, dormant again and expired on its third dormant cycle.
    Track 1 (tentative) is dropped on its first miss and counted; a free slot never ages."""
    store = _store()
    _create(store, 2, 0.0)
    script: list[
        tuple[
            tuple[int, ...], tuple[int, ...], TrackStatus | int, int, int, int, tuple[int, int, int]
        ]
    ] = [
        # hit, reid, status of 0, hits, misses, dormant frames, returned counts
        ((0, 1), (), T, 2, 0, 0, (0, 0, 0)),
        ((0,), (), C, 3, 0, 0, (1, 0, 0)),
        ((), (), C, 3, 1, 0, (0, 0, 0)),
        ((), (), L, 3, 2, 0, (0, 0, 0)),
        ((), (), L, 3, 3, 0, (0, 0, 0)),
        ((0,), (), C, 4, 0, 0, (0, 0, 0)),
        ((), (), C, 4, 1, 0, (0, 0, 0)),
        ((), (), L, 4, 2, 0, (0, 0, 0)),
        ((), (), L, 4, 3, 0, (0, 0, 0)),
        ((), (), D, 4, 4, 0, (0, 0, 0)),
        ((), (), D, 4, 4, 1, (0, 0, 0)),
        ((), (0,), C, 5, 0, 0, (0, 0, 0)),
        ((), (), C, 5, 1, 0, (0, 0, 0)),
        ((), (), L, 5, 2, 0, (0, 0, 0)),
        ((), (), L, 5, 3, 0, (0, 0, 0)),
        ((), (), D, 5, 4, 0, (0, 0, 0)),
        ((), (), D, 5, 4, 1, (0, 0, 0)),
        ((), (), D, 5, 4, 2, (0, 0, 0)),
        ((), (), FREE, 5, 4, 3, (0, 1, 0)),
    ]
    for cycle, (hit, reid, status, hits, misses, dormant, counts) in enumerate(script, 1):
        got = _step(store, hit, reid)
        where = f"cycle {cycle}"
        assert got == counts, where
        assert all(type(n) is int for n in got), where
        assert store.status[0] == status, where
        assert (store.hits[0], store.misses[0], store.dormant_frames[0]) == (
            hits,
            misses,
            dormant,
        ), where
        if status != FREE:
            assert store.age_frames[0] == cycle, where
            assert store.track_id[0] == 0, where
        assert store.dormant_frames[2:].tolist() == [0] * 4, where
        assert store.age_frames[2:].tolist() == [0] * 4, where
    assert store.track_id[0] == -1
    assert store.status[1] == FREE


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_a_lost_track_missed_again_stays_lost_and_a_confirmed_one_is_not_touched() -> None:
    """A lost track with more hits than confirm_hits, missed, stays LOST; a confirmed track
    hit stays CONFIRMED; neither's dormancy counter moves."""
    store = _store()
    _create(store, 2, 0.0)
    for _ in range(2):
        _step(store, (0, 1))
    _step(store, (1,))
    _step(store, (1,))
    assert store.status[:2].tolist() == [L, C]
    assert store.hits[:2].tolist() == [3, 5]
    _step(store, (1,))
    assert store.status[:2].tolist() == [L, C]
    assert store.dormant_frames[:2].tolist() == [0, 0]


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
@pytest.mark.parametrize(
    ("reid", "max_dormant", "status", "counts"),
    [(False, 2, FREE, (0, 0, 1)), (True, 0, FREE, (0, 0, 1)), (True, 1, D, (0, 0, 0))],
    ids=["re-identification off", "no dormant slot", "one dormant slot"],
)
def test_a_lost_track_is_deleted_and_counted_when_it_cannot_go_dormant(
    reid: bool, max_dormant: int, status: int, counts: tuple[int, int, int]
) -> None:
    store = _store(reid_enabled=reid, max_dormant=max_dormant)
    _create(store, 1, 0.0)
    for _ in range(2):
        _step(store, (0,))
    for _ in range(3):
        assert _step(store) == (0, 0, 0)
    assert _step(store) == counts
    assert store.status[0] == status


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_too_many_dormant_tracks_evict_the_oldest_first() -> None:
    """Three confirmed tracks last updated at 2.0, 1.0 and 1.0 s go dormant together with two
    dormant slots: the oldest (1.0 s), lowest ID first, is evicted and counted; the others
    stay, and so does the confirmed fourth track."""
    store = _store()
    _create(store, 4, 0.0)
    for _ in range(2):
        _step(store, (0, 1, 2, 3))
    store.last_update_s[:4] = [2.0, 1.0, 1.0, 0.5]
    for _ in range(3):
        assert _step(store, (3,)) == (0, 0, 0)
    assert _step(store, (3,)) == (0, 1, 0)
    assert store.status[:4].tolist() == [D, FREE, D, C]
    assert store.track_id[:4].tolist() == [0, -1, 2, 3]


@pytest.mark.requirement("SR-TRK-4", kind="example", code=LIFECYCLE)
def test_sizes_are_compatible_up_to_the_tolerance_inclusive() -> None:
    """(tracks x detections): |a - b| <= tol * max(a, b, floor) for width and length, both
    needed; exactly at the tolerance counts (1 against 2 m at 50 %)."""
    tracks = np.array([[1.0, 1.0], [1.0, 4.0]])
    dets = np.array([[2.0, 1.0], [2.1, 1.0], [1.0, 1.0]])
    ok = size_compatible(tracks, dets, 0.5, 0.1)
    assert ok.shape == (2, 3)
    assert ok.tolist() == [[True, False, True], [False, False, False]]
