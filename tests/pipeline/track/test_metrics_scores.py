"""Every tracking score of a four-frame example worked out by hand (SR-TRK-5).

Two objects, four hypothesis tracks; each frame is built to exercise one rule of CLEAR-MOT:

- frame 1: both objects matched (0.5 m and 0.6 m off) and one false positive far away;
- frame 2: object 1 keeps its track (0.3 m); object 2's track is gone and a new one takes it
  (0.8 m): one identity switch;
- frame 3: object 1's track drifts 1.5 m away, beyond the 1 m match threshold: a miss and a
  false positive; object 2 matched (0.1 m);
- frame 4: object 1 alone, matched again by its old track (0.2 m): one fragmentation.

Totals: 7 truth positions, 6 matches, 1 miss, 2 false positives, 1 switch, 1 fragmentation;
MOTA = 1 - (1 + 2 + 1) / 7 = 3/7; MOTP = (0.5 + 0.6 + 0.3 + 0.8 + 0.1 + 0.2) / 6 m; RMSE =
sqrt((0.25 + 0.36 + 0.09 + 0.64 + 0.01 + 0.04) / 6) m; GOSPA (c = 2 m, p = 2) per frame:
sqrt(0.25 + 0.36 + 2^2 / 2), sqrt(0.09 + 0.64), sqrt(1.5^2 + 0.1^2), 0.2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.track.metrics import PositionsFrame, TrackingQuality, evaluate, gospa

CODE = ["pipeline/track/metrics.py"]


def _frame(objects: dict[int, tuple[float, float]]) -> PositionsFrame:
    return PositionsFrame(np.array(list(objects), dtype=np.int64), np.array(list(objects.values())))


TRUTH = [
    _frame({1: (0.0, 0.0), 2: (10.0, 0.0)}),
    _frame({1: (1.0, 0.0), 2: (11.0, 0.0)}),
    _frame({1: (2.0, 0.0), 2: (12.0, 0.0)}),
    _frame({1: (3.0, 0.0)}),
]
HYPOTHESES = [
    _frame({100: (0.3, 0.4), 200: (10.0, 0.6), 300: (50.0, 50.0)}),
    _frame({100: (1.0, 0.3), 201: (11.8, 0.0)}),
    _frame({100: (3.5, 0.0), 201: (12.0, 0.1)}),
    _frame({100: (3.0, 0.2)}),
]


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_every_score_of_the_worked_example() -> None:
    quality = evaluate(TRUTH, HYPOTHESES)
    matched = [0.5, 0.6, 0.3, 0.8, 0.1, 0.2]
    per_frame = [
        math.sqrt(0.25 + 0.36 + 2.0),
        math.sqrt(0.09 + 0.64),
        math.sqrt(2.25 + 0.01),
        0.2,
    ]
    expected = TrackingQuality(
        n_frames=4,
        n_truth=7,
        n_matches=6,
        n_misses=1,
        n_false_positives=2,
        id_switches=1,
        fragmentations=1,
        mota=pytest.approx(3 / 7),  # type: ignore[arg-type]
        motp_m=pytest.approx(sum(matched) / 6),  # type: ignore[arg-type]
        position_rmse_m=pytest.approx(math.sqrt(sum(d * d for d in matched) / 6)),  # type: ignore[arg-type]
        gospa_mean_m=pytest.approx(sum(per_frame) / 4),  # type: ignore[arg-type]
        n_truth_ids=2,
        n_hypothesis_ids=4,
    )
    assert quality == expected
    # The defaults are a 1 m match threshold and GOSPA with c = 2 m, p = 2.
    assert evaluate(TRUTH, HYPOTHESES, 1.0, 2.0, 2.0) == quality
    # A 2 m threshold keeps object 1's drifting track in frame 3: no miss, no false positive.
    loose = evaluate(TRUTH, HYPOTHESES, match_threshold_m=2.0)
    assert (loose.n_matches, loose.n_misses, loose.n_false_positives) == (7, 0, 1)
    assert loose.fragmentations == 0
    # GOSPA's own parameters reach it.
    wide = evaluate(TRUTH, HYPOTHESES, gospa_c_m=3.0, gospa_p=1.0)
    assert wide.gospa_mean_m == pytest.approx((0.5 + 0.6 + 1.5 + 0.3 + 0.8 + 1.5 + 0.1 + 0.2) / 4)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_a_match_at_exactly_the_threshold_counts_and_the_switch_is_counted_once_per_change() -> (
    None
):
    truth = [_frame({1: (0.0, 0.0)}), _frame({1: (0.0, 0.0)}), _frame({1: (0.0, 0.0)})]
    hyps = [_frame({7: (1.0, 0.0)}), _frame({8: (0.0, 1.0)}), _frame({9: (0.0, -1.0)})]
    quality = evaluate(truth, hyps)
    assert (quality.n_matches, quality.id_switches, quality.fragmentations) == (3, 2, 0)
    assert quality.motp_m == 1.0
    assert quality.position_rmse_m == 1.0
    # An empty run has no truth to score: NaN, not a number that reads as a score.
    empty = evaluate([], [])
    assert (empty.n_frames, empty.n_truth) == (0, 0)
    assert all(math.isnan(v) for v in (empty.mota, empty.motp_m, empty.position_rmse_m))
    assert math.isnan(empty.gospa_mean_m)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_gospa_counts_pairs_strictly_closer_than_c_and_half_c_squared_per_missing_point() -> None:
    one = np.array([[0.0, 0.0]])
    assert gospa(one, np.array([[2.0, 0.0]])) == (2.0, 0)  # exactly c: capped, not close
    assert gospa(one, np.array([[1.0, 0.0]])) == (1.0, 1)
    alone, none = gospa(one, np.empty((0, 2)))
    assert (alone, none) == (math.sqrt(2.0), 0)
    assert gospa(np.empty((0, 2)), np.empty((0, 2))) == (0.0, 0)
    two = np.array([[0.0, 0.0], [10.0, 0.0]])
    value, close = gospa(two, np.array([[10.0, 0.5], [0.0, 0.5]]), c_m=1.0, p=1.0)
    assert value == pytest.approx(1.0)
    assert close == 2


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_a_track_keeps_its_object_within_the_threshold_even_when_another_is_closer() -> None:
    """CLEAR-MOT keeps last frame's correspondence while it is within the threshold (here at
    exactly 1 m), though a new hypothesis is nearer: no switch."""
    truth = [_frame({1: (0.0, 0.0)}), _frame({1: (0.0, 0.0)})]
    hyps = [_frame({7: (1.0, 0.0)}), _frame({7: (1.0, 0.0), 8: (0.1, 0.0)})]
    quality = evaluate(truth, hyps)
    assert (quality.n_matches, quality.id_switches, quality.n_false_positives) == (2, 0, 1)
    assert quality.motp_m == 1.0


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_an_infeasible_pair_never_wins_the_assignment_over_a_feasible_one() -> None:
    """One object, two hypotheses: the first 5 m away (infeasible), the second 0.5 m away.
    The assignment must price the infeasible pair above every feasible one."""
    quality = evaluate([_frame({1: (0.0, 0.0)})], [_frame({9: (5.0, 0.0), 8: (0.5, 0.0)})])
    assert (quality.n_matches, quality.n_false_positives, quality.motp_m) == (1, 1, 0.5)
    # With a 2 m threshold a feasible pair may cost more than 1 m: still preferred.
    far = evaluate(
        [_frame({1: (0.0, 0.0)})], [_frame({9: (5.0, 0.0), 8: (1.5, 0.0)})], match_threshold_m=2.0
    )
    assert (far.n_matches, far.motp_m) == (1, 1.5)
