"""Examples for the per-track features (SR-CLS-2)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipeline.cluster import cluster_scan
from pipeline.config import default_config
from pipeline.features import (
    FEATURE_NAMES,
    MEMORY_FEATURE_NAMES,
    SOURCE_FEATURE_NAMES,
    detections_in_frame,
    feature_index,
    track_features,
)
from pipeline.track.tracker import Tracker
from pipeline.types import Scan
from properties.prediction_cases import tracks_of


def _scan_of_box(stamp: float, cx: float, cy: float, half: float = 0.3) -> Scan:
    """A 1080-beam scan that sees a square box centred at (cx, cy) and nothing else."""
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    lo, hi = np.array([cx, cy]) - half, np.array([cx, cy]) + half
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = lo / d, hi / d
    near = np.nanmax(np.minimum(t1, t2), axis=1)
    far = np.nanmin(np.maximum(t1, t2), axis=1)
    ranges = np.where((far >= near) & (near > 0), near, np.nan)
    return Scan(stamp_s=stamp, angles_rad=angles, ranges_m=ranges)


def test_names_and_index() -> None:
    assert len(SOURCE_FEATURE_NAMES) == 10
    assert FEATURE_NAMES[:10] == SOURCE_FEATURE_NAMES
    assert FEATURE_NAMES[10:] == MEMORY_FEATURE_NAMES
    assert feature_index("is_near_reversal") == 9
    with pytest.raises(KeyError, match="unknown feature 'speed'"):
        feature_index("speed")


def test_box_features_density_and_age_from_the_tracker() -> None:
    config = default_config()
    tracker = Tracker(config.track)
    for k in range(6):
        _, clusters = cluster_scan(_scan_of_box(0.1 * k, 4.0 + 0.05 * k, 0.0), config)
        tracks = tracker.step(detections_in_frame(clusters, (0.0, 0.0, 0.0)))
    feats = track_features(tracks, clusters, config.predict)
    row = feats.values[0]
    assert feats.track_id.tolist() == tracks.track_id.tolist()
    assert row[feature_index("bbox_area_m2")] == pytest.approx(row[0] * row[1])
    det = int(tracks.detection_index[0])
    assert row[feature_index("point_density_per_m2")] == clusters.point_density_per_m2[det]
    assert row[feature_index("track_age_frames")] == tracks.age_frames[0]
    assert row[feature_index("velocity_magnitude_mps")] == pytest.approx(0.5, abs=0.2)
    # Moving away from the robot at the origin: direction pi.
    assert row[feature_index("velocity_direction_rad")] == pytest.approx(math.pi, abs=0.3)
    # Without this cycle's clusters the density is missing, never guessed.
    assert np.isnan(track_features(tracks, None, config.predict).values[0, 3])


def test_direction_is_relative_to_the_line_of_sight() -> None:
    config = default_config()
    hist = np.zeros((1, 2))
    towards = tracks_of(np.array([5.0, 0.0]), np.array([-1.0, 0.0]), 0.01, 0.01, 0.5, 1.0, hist)
    across = tracks_of(np.array([5.0, 0.0]), np.array([0.0, 1.0]), 0.01, 0.01, 0.5, 1.0, hist)
    col = feature_index("velocity_direction_rad")
    assert track_features(towards, None, config.predict).values[0, col] == pytest.approx(0.0)
    assert track_features(across, None, config.predict).values[0, col] == pytest.approx(math.pi / 2)
    # The robot elsewhere in the frame: the same track now heads away from it.
    away = track_features(towards, None, config.predict, robot_xy_m=(10.0, 0.0))
    assert away.values[0, col] == pytest.approx(math.pi)


@pytest.mark.parametrize(
    ("speed", "decel", "flag"),
    [(0.2, 0.5, 1.0), (0.3, 0.5, 0.0), (0.2, 0.4, 0.0), (0.0, 1.0, 1.0), (1.0, 2.0, 0.0)],
)
def test_near_reversal_flag_thresholds(speed: float, decel: float, flag: float) -> None:
    config = default_config()
    tracks = tracks_of(np.zeros(2), np.array([speed, 0.0]), 0.01, 0.01, 0.5, 1.0, np.zeros((1, 2)))
    tracks = replace(tracks, decel_mps2=np.array([decel]))
    assert track_features(tracks, None, config.predict).values[0, 9] == flag


def test_a_part_view_keeps_the_largest_box_the_track_showed() -> None:
    config = default_config()
    tracker = Tracker(config.track)
    for k in range(12):
        # The box is seen whole for six scans, then only a 0.2 m part of it.
        half = 0.4 if k < 6 else 0.1
        _, clusters = cluster_scan(_scan_of_box(0.1 * k, 4.0, 0.0, half), config)
        tracks = tracker.step(detections_in_frame(clusters, (0.0, 0.0, 0.0)))
    row = track_features(tracks, clusters, config.predict).values[0]
    assert row[feature_index("bbox_length_m")] < 0.3
    assert row[feature_index("max_length_m")] == pytest.approx(0.8, abs=0.05)
    assert row[feature_index("max_width_m")] >= row[feature_index("bbox_width_m")]
    assert row[feature_index("range_m")] == pytest.approx(4.0, abs=0.1)


@pytest.mark.parametrize(
    ("speeds", "peak", "since"),
    [
        ([1.0, 0.5, 0.2, 0.1], 1.0, 0.2),  # last fast at t = 0.2, newest at 0.4
        ([0.2, 0.3, 0.29, 0.0], 0.3, 0.2),  # the threshold itself counts as moving
        ([0.1, 0.2, 0.1, 0.4], 0.4, 0.0),  # moving now
        ([0.1, 0.2, 0.29, 0.0], 0.29, math.nan),  # never as fast: missing, not guessed
    ],
)
def test_speed_memory_from_the_history(speeds: list[float], peak: float, since: float) -> None:
    config = default_config()
    tracks = tracks_of(np.zeros(2), np.zeros(2), 0.01, 0.01, 0.5, 1.0, np.zeros((1, 2)))
    history = np.full((1, 15), np.nan)
    history[0, -4:] = speeds
    stamps = np.full((1, 15), np.nan)
    stamps[0, -4:] = [0.1, 0.2, 0.3, 0.4]
    tracks = replace(tracks, history_speed_mps=history, history_t_s=stamps)
    row = track_features(tracks, None, config.predict).values[0]
    assert row[feature_index("peak_speed_mps")] == pytest.approx(peak)
    got = row[feature_index("time_since_moving_s")]
    assert got == pytest.approx(since, nan_ok=True)


def test_detections_move_into_the_frame() -> None:
    config = default_config()
    _, clusters = cluster_scan(_scan_of_box(0.0, 3.0, 0.0), config)
    moved = detections_in_frame(clusters, (1.0, 2.0, math.pi / 2))
    assert moved.x_m[0] == pytest.approx(1.0 - clusters.centroid_y_m[0])
    assert moved.y_m[0] == pytest.approx(2.0 + clusters.centroid_x_m[0])
    assert moved.width_m[0] == clusters.width_m[0]
    with pytest.raises(ValueError, match="must be finite"):
        detections_in_frame(clusters, (math.nan, 0.0, 0.0))
