"""The tracker's inputs at their limits (SR-TRK-4): stamps and detections it must refuse, and a
reset that forgets everything."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config import default_config
from pipeline.track.tracker import Detections, Tracker, TrackerError
from pipeline.types import TrackStatus

CODE = ["pipeline/track/tracker.py"]


def _det(t: float, x: float = 2.0, width: float = 0.5) -> Detections:
    return Detections(t, np.array([x]), np.array([1.0]), np.array([width]), np.array([1.0]))


@pytest.mark.requirement("SR-TRK-4", kind="example", code=CODE)
@pytest.mark.parametrize("stamp", [float("nan"), float("inf"), float("-inf")])
def test_a_stamp_that_is_not_finite_is_refused_naming_it(stamp: float) -> None:
    tracker = Tracker(default_config().track)
    with pytest.raises(
        TrackerError, match=rf"^Tracker\.step: stamp_s must be finite, got {stamp!r}$"
    ):
        tracker.step(_det(stamp))
    # Refused before anything changed: the next good cycle is the first.
    assert tracker.last_stamp_s is None
    assert tracker.step(_det(0.0)).n == 1


@pytest.mark.requirement("SR-TRK-4", kind="example", code=CODE)
@pytest.mark.parametrize(("x", "width"), [(float("nan"), 0.5), (2.0, float("inf"))])
def test_a_detection_that_is_not_finite_is_refused(x: float, width: float) -> None:
    tracker = Tracker(default_config().track)
    tracker.step(_det(0.0))
    with pytest.raises(
        TrackerError, match=r"^Tracker\.step: detections must be finite \(x, y, width, length\)$"
    ):
        tracker.step(_det(0.1, x, width))
    assert tracker.last_stamp_s == 0.0


@pytest.mark.requirement("SR-TRK-4", kind="example", code=CODE)
def test_a_reset_forgets_every_track_and_the_clock() -> None:
    tracker = Tracker(default_config().track)
    for k in range(6):
        tracks = tracker.step(_det(0.1 * k))
    assert tracks.with_status(TrackStatus.CONFIRMED).any()
    tracker.reset()
    assert tracker.last_stamp_s is None
    assert tracker.last_counts is None
    # An earlier stamp is accepted after the reset, and the object is a new, tentative track.
    tracks = tracker.step(_det(0.0))
    assert tracks.n == 1
    assert not tracks.with_status(TrackStatus.CONFIRMED).any()
