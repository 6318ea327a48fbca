"""The tracking metrics' inputs at their limits: frames that do not hold together and
sequences of different lengths are refused, naming what is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.track.metrics import PositionsFrame, evaluate

CODE = ["pipeline/track/metrics.py"]


def test_a_frame_needs_one_position_per_unique_id() -> None:
    with pytest.raises(ValueError, match=r"^PositionsFrame: 2 ids but 1 positions$"):
        PositionsFrame(np.array([1, 2]), np.array([[0.0, 0.0]]))
    with pytest.raises(ValueError, match=r"^PositionsFrame: ids must be unique, got \[3, 3\]$"):
        PositionsFrame(np.array([3, 3]), np.zeros((2, 2)))
    frame = PositionsFrame(np.array([4, 5]), np.array([1.0, 2.0, 3.0, 4.0]))
    assert frame.xy_m.tolist() == [[1.0, 2.0], [3.0, 4.0]]
    assert frame.ids.dtype == np.int64
    # Ids handed over as floats (as a JSON reader gives them) are kept as integers.
    floats = PositionsFrame(np.array([6.0, 7.0]), np.zeros((2, 2)))
    assert floats.ids.dtype == np.int64
    assert floats.ids.tolist() == [6, 7]


def test_truth_and_hypotheses_must_have_the_same_number_of_frames() -> None:
    one = PositionsFrame(np.array([0]), np.array([[0.0, 0.0]]))
    with pytest.raises(ValueError, match=r"^evaluate: 2 truth frames but 1 hypotheses$"):
        evaluate([one, one], [one])
    quality = evaluate([one, one], [one, one])
    assert (quality.n_frames, quality.n_matches, quality.mota) == (2, 2, 1.0)
