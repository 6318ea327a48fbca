"""Examples for the track heading: box axes smoothed, the flip resolved (SR-TRK-7)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.frames import IDENTITY
from pipeline.track.heading import nearest_side, update_headings, wrap_pi
from pipeline.track.tracker import Detections, Tracker, detections_in_frame
from pipeline.types import ClusterCounts, Clusters

CFG = default_config().track


def test_nearest_side_picks_the_quarter_turn_towards_the_reference() -> None:
    axis = np.array([0.1, 0.1, 0.1, 0.1])
    ref = np.array([0.0, math.pi, math.pi / 2, -math.pi / 2])
    got = nearest_side(axis, ref)
    want = wrap_pi(np.array([0.1, 0.1 + math.pi, 0.1 + math.pi / 2, 0.1 - math.pi / 2]))
    assert np.allclose(got, want)


def test_a_certain_velocity_resolves_the_flip_at_once() -> None:
    heading, resolved = update_headings(
        np.array([0.05]),
        np.array([False]),
        np.array([0.0]),
        np.array([[-1.0, 0.0]]),  # driving towards -x
        np.array([0.1]),
        np.array([True]),
        CFG,
    )
    assert resolved[0]
    assert abs(abs(heading[0]) - math.pi) < 1e-12


def test_an_uncertain_or_unsettled_velocity_resolves_nothing() -> None:
    for std, settled in ((0.6, True), (0.1, False)):
        heading, resolved = update_headings(
            np.array([0.0]),
            np.array([False]),
            np.array([0.2]),
            np.array([[-1.0, 0.0]]),
            np.array([std]),
            np.array([settled]),
            CFG,
        )
        assert not resolved[0]
        assert heading[0] == pytest.approx(CFG.heading_smoothing * 0.2)


def test_a_slow_track_keeps_its_direction_from_its_history() -> None:
    # Resolved towards -x; the box says axis 0.1 (mod pi): the side near -x is taken.
    heading, resolved = update_headings(
        np.array([math.pi - 0.05]),
        np.array([True]),
        np.array([0.1]),
        np.array([[0.01, 0.0]]),
        np.array([0.01]),
        np.array([True]),
        CFG,
    )
    assert resolved[0]
    target = wrap_pi(np.array([0.1 + math.pi]))[0]
    step = wrap_pi(np.array([target - (math.pi - 0.05)]))[0]
    assert heading[0] == pytest.approx(
        wrap_pi(np.array([math.pi - 0.05 + CFG.heading_smoothing * step]))[0]
    )


def test_a_certain_slower_velocity_chooses_the_side_but_not_the_flip() -> None:
    # Seen end-on, the box's longer side is the vehicle's back (axis pi/2), and the track's
    # heading so far followed it; the vehicle drives at 0.5 m/s along +x, between
    # track.heading_side_speed_mps and the flip speed.
    assert CFG.heading_side_speed_mps <= 0.5 < CFG.heading_flip_speed_mps
    for history, want in ((math.pi / 2 - 0.3, 0.0), (math.pi / 2 + 0.3, math.pi)):
        heading, resolved = update_headings(
            np.array([history]),
            np.array([False]),
            np.array([math.pi / 2]),
            np.array([[0.5, 0.0]]),
            np.array([0.05]),
            np.array([True]),
            CFG,
        )
        assert not resolved[0]
        # The side along the velocity, in the half-plane the history has (no flip).
        step = wrap_pi(np.array([want - history]))[0]
        assert heading[0] == pytest.approx(
            wrap_pi(np.array([history + CFG.heading_smoothing * step]))[0]
        )


def test_no_axis_leaves_the_heading_alone() -> None:
    heading, resolved = update_headings(
        np.array([1.0]),
        np.array([True]),
        np.array([np.nan]),
        np.zeros((1, 2)),
        np.zeros(1),
        np.array([True]),
        CFG,
    )
    assert heading[0] == 1.0
    assert resolved[0]


def test_the_tracker_reports_a_heading_per_track() -> None:
    cfg = overridden(default_config(), {"track": {"heading_smoothing": 1.0}}).track
    tracker = Tracker(cfg)
    for k in range(20):
        t = 0.1 * k
        det = Detections(
            t,
            np.array([-1.0 * t]),
            np.array([2.0]),
            np.array([1.0]),
            np.array([2.5]),
            heading_rad=np.array([0.02]),
        )
        tracks = tracker.step(det)
    h = tracker.last_headings
    assert h is not None
    assert h.track_id.tolist() == tracks.track_id.tolist()
    assert h.resolved[0]
    assert abs(wrap_pi(h.heading_rad - (math.pi + 0.02))[0]) < 1e-9


def _one_cluster(heading_rad: float) -> Clusters:
    one = np.ones(1)
    return Clusters(
        stamp_s=0.0,
        centroid_x_m=one,
        centroid_y_m=0 * one,
        width_m=0.5 * one,
        length_m=one,
        heading_rad=heading_rad * one,
        area_m2=0.5 * one,
        point_density_per_m2=10 * one,
        n_points=np.array([5]),
        hull_x_m=one,
        hull_y_m=0 * one,
        hull_offsets=np.array([0, 1]),
        point_labels=np.zeros(5, dtype=np.int64),
        counts=ClusterCounts(1, 0, 0, 0, 0, 0),
        end_x_m=np.ones((1, 2)),
        end_y_m=np.zeros((1, 2)),
        end_occluded=np.zeros((1, 2), dtype=bool),
    )


def test_moving_detections_into_the_tracking_frame_turns_their_axes() -> None:
    moved = detections_in_frame(_one_cluster(0.3), (0.0, 0.0, 0.5))
    assert moved.heading_rad is not None
    assert moved.heading_rad[0] == pytest.approx(0.8)
    same = detections_in_frame(_one_cluster(0.3), IDENTITY)
    assert same.heading_rad is not None
    assert same.heading_rad[0] == pytest.approx(0.3)
