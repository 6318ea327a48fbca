"""Scoring a tracker run: which tracks are reported, a run over frames, re-identification on
and off (SR-TRK-5).

The campaign tests score long simulated runs; here one object is tracked through a short
sequence whose every number is known: when its track is confirmed, which statuses the report
keeps, and what switching re-identification off changes when the object is missed for longer
than a lost track is kept.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config import TrackSection, default_config, overridden
from pipeline.track.metrics import (
    REPORTED,
    PositionsFrame,
    compare_reid,
    frame_from_tracks,
    run_tracker,
)
from pipeline.track.tracker import Detections, Tracker
from pipeline.types import TrackStatus

CODE = ["pipeline/track/metrics.py"]


def _det(t: float, xy: list[tuple[float, float]]) -> Detections:
    a = np.array(xy, dtype=float).reshape(-1, 2)
    return Detections(t, a[:, 0], a[:, 1], np.full(len(a), 0.5), np.full(len(a), 1.0))


def _truth(xy: list[tuple[float, float]], ids: list[int] | None = None) -> PositionsFrame:
    a = np.array(xy, dtype=float).reshape(-1, 2)
    return PositionsFrame(np.array(ids if ids is not None else range(len(a))), a)


@pytest.fixture(scope="module")
def track() -> TrackSection:
    return default_config().track


def test_only_confirmed_and_lost_tracks_are_reported_by_default(track: TrackSection) -> None:
    assert REPORTED == (TrackStatus.CONFIRMED, TrackStatus.LOST)
    tracker = Tracker(track)
    tentative = tracker.step(_det(0.0, [(2.0, 1.0)]))
    assert frame_from_tracks(tentative).ids.size == 0
    every = frame_from_tracks(tentative, tuple(TrackStatus))
    assert every.ids.tolist() == tentative.track_id.tolist()
    assert every.xy_m.tolist() == [[2.0, 1.0]]
    for k in range(1, track.confirm_hits):
        tracks = tracker.step(_det(0.1 * k, [(2.0, 1.0)]))
    reported = frame_from_tracks(tracks)
    assert reported.ids.tolist() == tracks.track_id.tolist()
    assert reported.xy_m[0] == pytest.approx([2.0, 1.0], abs=1e-6)


def test_a_run_gives_one_truth_and_one_hypothesis_frame_per_step(track: TrackSection) -> None:
    frames = [(_det(0.1 * k, [(2.0, 1.0)]), _truth([(2.0, 1.0)])) for k in range(6)]
    truths, hyps = run_tracker(frames, track)
    assert [t is f for t, (_, f) in zip(truths, frames, strict=True)] == [True] * 6
    confirmed_from = track.confirm_hits - 1
    assert [h.ids.size for h in hyps] == [0] * confirmed_from + [1] * (6 - confirmed_from)
    everything = run_tracker(frames, track, tuple(TrackStatus))[1]
    assert [h.ids.size for h in everything] == [1] * 6


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_reidentification_is_scored_on_and_off_over_the_same_frames(track: TrackSection) -> None:
    """An object walks 0.4 m/s along x, unseen for longer than a lost track is kept: with
    re-identification its dormant track takes it back (one id); without, a new track is born
    (a second hypothesis id). Everything else is the configuration given."""
    seen = [k for k in range(60) if not 10 <= k < 40]
    frames = []
    for k in range(60):
        xy = [(1.0 + 0.04 * k, 0.5)]
        frames.append((_det(0.1 * k, xy if k in seen else []), _truth(xy, [7])))
    scores = compare_reid(frames, track)
    assert set(scores) == {"reid_on", "reid_off"}
    assert scores["reid_on"].n_frames == scores["reid_off"].n_frames == 60
    assert scores["reid_on"].n_truth_ids == 1
    assert scores["reid_off"].n_hypothesis_ids > scores["reid_on"].n_hypothesis_ids
    default = compare_reid(frames)
    assert default["reid_on"] == scores["reid_on"]
    assert default["reid_off"] == scores["reid_off"]
    strict = compare_reid(frames, track, match_threshold_m=1e-6)
    assert strict["reid_on"].n_matches < scores["reid_on"].n_matches
    off = overridden(default_config(), {"track": {"reid_enabled": False}}).track
    assert compare_reid(frames, off)["reid_on"] == scores["reid_on"]
    # The configuration given is the one scored: tracks confirmed later match fewer frames.
    slow = overridden(default_config(), {"track": {"confirm_hits": track.confirm_hits + 3}})
    later = compare_reid(frames, slow.track)
    assert later["reid_on"].n_matches < scores["reid_on"].n_matches


def test_reidentification_is_scored_with_a_one_metre_match_by_default(track: TrackSection) -> None:
    """The truth stands 1.5 m from what the scanner sees: beyond the default 1 m match no
    frame is matched, within an explicit 2 m every confirmed one is."""
    frames = [(_det(0.1 * k, [(2.0, 1.0)]), _truth([(3.5, 1.0)])) for k in range(8)]
    default = compare_reid(frames, track)
    assert default == compare_reid(frames, track, match_threshold_m=1.0)
    assert default["reid_on"].n_matches == 0
    wide = compare_reid(frames, track, match_threshold_m=2.0)
    assert wide["reid_on"].n_matches == 8 - (track.confirm_hits - 1)
