"""Examples for JPDA association and its wiring in the tracker (SR-TRK-8)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.errors import ConfigError
from pipeline.track.associate import CascadeAssociator
from pipeline.track.jpda import JpdaAssociator, joint_betas, pda_update
from pipeline.track.tracker import Detections, Tracker

JPDA = overridden(default_config(), {"track": {"association": "jpda"}}).track


def test_two_tracks_sharing_one_detection_by_hand() -> None:
    # Weights: miss m for both; detection 0 has weight a for track 0 and b for track 1.
    m, a, b = 0.2, 3.0, 1.0
    log_w = np.log(np.array([[m, a], [m, b]]))
    beta, best, n_events = joint_betas(log_w)
    # Events: (miss, miss) m*m; (det, miss) a*m; (miss, det) m*b; (det, det) invalid.
    total = m * m + a * m + m * b
    assert n_events == 3
    assert beta[0, 1] == pytest.approx(a * m / total, rel=1e-12)
    assert beta[1, 1] == pytest.approx(m * b / total, rel=1e-12)
    assert beta[0, 0] == pytest.approx((m * m + m * b) / total, rel=1e-12)
    assert best.tolist() == [0, -1]


def test_gated_out_pairs_take_no_weight() -> None:
    log_w = np.array([[math.log(0.1), 0.0, -np.inf], [math.log(0.1), -np.inf, 0.0]])
    beta, best, n_events = joint_betas(log_w)
    assert n_events == 4
    assert beta[0, 2] == 0.0
    assert beta[1, 1] == 0.0
    assert best.tolist() == [0, 1]


def test_lone_tracks_use_the_cascade_and_shared_gates_jpda() -> None:
    inf = np.inf
    cost = np.array([[1.0, inf, inf], [inf, 2.0, 0.5], [inf, 0.3, inf]])
    groups = [np.ones(3, dtype=bool), np.zeros(3, dtype=bool)]
    assoc = JpdaAssociator(JPDA)
    soft = assoc.associate_soft(cost, groups, np.zeros(3))
    assert soft.pda.tolist() == [False, True, True]
    assert soft.match[0] == 0
    assert assoc.last is not None
    assert (assoc.last.n_clusters, assoc.last.n_jpda, assoc.last.n_fallback) == (1, 1, 0)
    assert np.allclose(soft.beta[1:].sum(axis=1), 1.0)


def test_the_clutter_density_is_learned_from_detections_outside_every_gate() -> None:
    assoc = JpdaAssociator(JPDA)
    cost = np.full((1, 40), np.inf)
    assoc.clutter_density(cost)  # 40 outside
    after = assoc.clutter_density(np.zeros((1, 40)))  # none outside: the average decays
    expected = (1 - JPDA.jpda_clutter_smoothing) * 40 / JPDA.jpda_surveillance_area_m2
    assert after == pytest.approx(max(expected, JPDA.jpda_clutter_density_min_per_m2))
    assoc.reset()
    assert assoc.clutter_density(np.zeros((1, 3))) == JPDA.jpda_clutter_density_min_per_m2


def test_a_certain_detection_gives_the_kalman_update() -> None:
    x = np.array([[0.0, 0.0, 1.0, 0.0]])
    p = np.eye(4)[None] * 0.5
    z = np.array([[0.2, -0.1]])
    x_new, p_new, capped = pda_update(x, p, z, np.array([[0.0, 1.0]]), 0.05)
    from pipeline.track.kalman import update

    x_ref, p_ref = update(x, p, z, 0.05)
    assert np.allclose(x_new, x_ref, atol=1e-12)
    assert np.allclose(p_new, p_ref, atol=1e-12)
    assert not capped.any()


def test_the_tracker_takes_the_configured_associator_and_resets_it() -> None:
    assert isinstance(Tracker(default_config().track).associator, CascadeAssociator)
    tracker = Tracker(JPDA)
    assert isinstance(tracker.associator, JpdaAssociator)
    for k in range(6):
        t = 0.1 * k
        x = np.array([0.0, 0.4, 5.0]) + 0.5 * t
        tracker.step(Detections(t, x, np.zeros(3), np.full(3, 0.3), np.full(3, 0.5)))
    assert tracker.associator.last is not None
    tracker.reset()
    assert tracker.associator.last is None


def test_two_walkers_side_by_side_keep_their_tracks() -> None:
    tracker = Tracker(JPDA)
    ids = None
    for k in range(30):
        t = 0.1 * k
        xs = np.array([1.0 * t, 1.0 * t])
        ys = np.array([0.0, 0.45])
        tracks = tracker.step(Detections(t, xs, ys, np.full(2, 0.2), np.full(2, 0.3)))
        used = tracks.detection_index[tracks.detection_index >= 0]
        assert np.unique(used).shape[0] == used.shape[0]
        if k == 29:
            ids = tracks.track_id.tolist()
    assert ids == [0, 1]


def test_bad_association_settings_are_refused_naming_the_key() -> None:
    with pytest.raises(ConfigError) as caught:
        overridden(default_config(), {"track": {"association": "gnn"}})
    (line,) = caught.value.lines
    assert "track.association" in line
    assert "'hungarian', 'jpda'" in line
    with pytest.raises(ConfigError, match=r"track\.jpda_detection_prob"):
        overridden(default_config(), {"track": {"jpda_detection_prob": 1.5}})
    with pytest.raises(ConfigError, match=r"track\.jpda_max_hypotheses"):
        overridden(default_config(), {"track": {"jpda_max_hypotheses": 0}})
