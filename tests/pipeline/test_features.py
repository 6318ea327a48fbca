"""Examples for the per-track features (SR-CLS-2)."""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest

from pipeline.cluster.dbscan import cluster_scan
from pipeline.config import default_config
from pipeline.features import (
    END_FEATURE_NAMES,
    END_MIN_ENTRIES,
    END_WINDOW,
    FEATURE_NAMES,
    GROUP_FEATURE_NAMES,
    GROUP_RADIUS_M,
    GROUP_SPEED_MPS,
    MEMORY_FEATURE_NAMES,
    SOURCE_FEATURE_NAMES,
    feature_index,
    track_features,
)
from pipeline.track.tracker import Tracker, detections_in_frame
from pipeline.types import Scan, Tracks
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
    assert FEATURE_NAMES[10:15] == MEMORY_FEATURE_NAMES
    assert FEATURE_NAMES[15:17] == GROUP_FEATURE_NAMES
    assert FEATURE_NAMES[17:] == END_FEATURE_NAMES
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
    assert moved.end_xy_m is not None
    assert moved.end_occluded is not None
    assert moved.end_xy_m[0].tolist() == pytest.approx(
        [
            1.0 - clusters.end_y_m[0, 0],
            2.0 + clusters.end_x_m[0, 0],
            1.0 - clusters.end_y_m[0, 1],
            2.0 + clusters.end_x_m[0, 1],
        ]
    )
    assert moved.end_occluded.tolist() == clusters.end_occluded.tolist()
    with pytest.raises(ValueError, match="expected three finite numbers"):
        detections_in_frame(clusters, (math.nan, 0.0, 0.0))


def _stacked(parts: list[Tracks]) -> Tracks:
    """One snapshot holding the tracks of ``parts`` (each a one-track snapshot), ids 0, 1, ..."""
    joined = {
        f.name: np.concatenate([getattr(p, f.name) for p in parts])
        for f in fields(Tracks)
        if f.name != "stamp_s"
    }
    joined["track_id"] = np.arange(len(parts))
    return Tracks(stamp_s=parts[0].stamp_s, **joined)


def _part(x: float, vx: float, max_length_m: float) -> Tracks:
    one = tracks_of(np.array([x, 0.0]), np.array([vx, 0.0]), 0.1, 0.1, 0.1, 0.3, np.zeros((1, 2)))
    return replace(one, max_length_m=np.array([max_length_m]))


def test_group_features_join_parts_that_move_together() -> None:
    config = default_config()
    # A tine tip at x = 0 and its truck's body 2 m ahead moving with it; a wall 2.4 m behind
    # standing still; a cart 2.6 m ahead moving with the tine (too far to be a partner).
    tracks = _stacked(
        [_part(0.0, 1.0, 0.3), _part(2.0, 1.2, 2.3), _part(-2.4, 0.0, 6.0), _part(2.6, 1.0, 0.9)]
    )
    values = track_features(tracks, None, config.predict).values
    length, gap = feature_index("group_length_m"), feature_index("group_gap_m")
    assert values[0, length] == pytest.approx(2.3)
    assert values[0, gap] == pytest.approx(2.0)
    # The body's partners: the tine (2 m) and the cart (0.6 m), not the wall (4.4 m, too slow).
    assert values[1, length] == pytest.approx(0.9)
    assert values[1, gap] == pytest.approx(0.6)
    # The wall has no partner at all: length 0, gap missing (NaN), not a made-up distance.
    assert values[2, length] == 0.0
    assert math.isnan(values[2, gap])


def test_group_bounds_are_inclusive() -> None:
    config = default_config()
    edge = _stacked([_part(0.0, 0.0, 1.0), _part(GROUP_RADIUS_M, GROUP_SPEED_MPS, 1.5)])
    values = track_features(edge, None, config.predict).values
    assert values[0, feature_index("group_length_m")] == pytest.approx(1.5)
    apart = _stacked([_part(0.0, 0.0, 1.0), _part(GROUP_RADIUS_M + 0.01, 0.0, 1.5)])
    assert (
        track_features(apart, None, config.predict).values[0, feature_index("group_length_m")]
        == 0.0
    )
    fast = _stacked([_part(0.0, 0.0, 1.0), _part(1.0, GROUP_SPEED_MPS + 0.01, 1.5)])
    assert (
        track_features(fast, None, config.predict).values[0, feature_index("group_length_m")] == 0.0
    )


def test_no_tracks_no_rows() -> None:
    config = default_config()
    empty = replace(
        _part(0.0, 0.0, 1.0),
        **{
            f.name: getattr(_part(0.0, 0.0, 1.0), f.name)[:0]
            for f in fields(Tracks)
            if f.name != "stamp_s"
        },
    )
    assert track_features(empty, None, config.predict).values.shape == (0, len(FEATURE_NAMES))


def _with_ends(
    t_s: list[float],
    first_xy: list[tuple[float, float]],
    last_xy: list[tuple[float, float]],
    occluded: list[tuple[float, float]],
    detection_index: int = 0,
) -> Tracks:
    """A one-track snapshot whose newest history entries carry these ends (oldest first)."""
    one = tracks_of(np.zeros(2), np.zeros(2), 0.1, 0.1, 0.5, 1.0, np.zeros((1, 2)))
    k = len(t_s)
    t = np.full((1, 15), np.nan)
    ends = np.full((1, 15, 4), np.nan)
    occ = np.full((1, 15, 2), np.nan)
    t[0, 15 - k :] = t_s
    ends[0, 15 - k :] = np.concatenate([np.array(first_xy), np.array(last_xy)], axis=1)
    occ[0, 15 - k :] = occluded
    return replace(
        one,
        history_t_s=t,
        history_end_xy_m=ends,
        history_end_occluded=occ,
        detection_index=np.array([detection_index]),
    )


def _ends_row(tracks: Tracks) -> dict[str, float]:
    row = track_features(tracks, None, default_config().predict).values[0]
    return {name: float(row[feature_index(name)]) for name in END_FEATURE_NAMES}


def test_a_clipped_view_moves_at_its_free_end() -> None:
    # A truck entering a gap: its free end advances 1 m/s along y, the end at the occluder's
    # edge stays; the centroid would move at half the speed.
    t = [0.1 * k for k in range(5)]
    row = _ends_row(
        _with_ends(t, [(20.0, 0.1 * k) for k in range(5)], [(20.0, -1.0)] * 5, [(0.0, 1.0)] * 5)
    )
    assert row["ends_occluded"] == 1.0
    assert row["end_speed_max_mps"] == pytest.approx(1.0)
    assert row["end_speed_min_mps"] == pytest.approx(0.0, abs=1e-12)
    assert row["free_end_speed_mps"] == pytest.approx(1.0)
    assert row["end_occluded_share"] == pytest.approx(0.5)
    assert row["end_mid_speed_mps"] == pytest.approx(0.5)


def test_an_end_occluded_once_in_the_window_is_not_free() -> None:
    t = [0.1 * k for k in range(5)]
    first = [(0.0, 0.1 * k) for k in range(5)]
    last = [(0.0, 1.0 + 0.2 * k) for k in range(5)]
    occluded = [(0.0, 0.0)] * 4 + [(0.0, 1.0)]
    row = _ends_row(_with_ends(t, first, last, occluded))
    assert row["free_end_speed_mps"] == pytest.approx(1.0)  # the last end (2 m/s) is out
    assert row["end_speed_max_mps"] == pytest.approx(2.0)
    assert row["end_occluded_share"] == pytest.approx(0.1)
    both = _ends_row(_with_ends(t, first, last, [(1.0, 0.0), *occluded[1:]]))
    assert math.isnan(both["free_end_speed_mps"])  # neither end stayed free: missing


def test_end_speeds_look_back_over_the_window_only() -> None:
    # Twelve updates; the two oldest (outside the window) put the first end 5 m away.
    n = END_WINDOW + 2
    t = [0.1 * k for k in range(n)]
    first = [(5.0, 5.0)] * 2 + [(0.5 * 0.1 * k, 0.0) for k in range(2, n)]
    row = _ends_row(_with_ends(t, first, first, [(0.0, 0.0)] * n))
    assert row["end_speed_max_mps"] == pytest.approx(0.5)
    assert row["end_speed_min_mps"] == pytest.approx(0.5)


def test_too_few_ends_or_a_coasting_track_give_missing_values() -> None:
    k = END_MIN_ENTRIES - 1
    short = _ends_row(
        _with_ends(
            [0.1 * i for i in range(k)], [(0.0, 0.0)] * k, [(1.0, 0.0)] * k, [(1.0, 0.0)] * k
        )
    )
    assert short["ends_occluded"] == 1.0
    assert all(math.isnan(v) for name, v in short.items() if name != "ends_occluded")
    t = [0.1 * i for i in range(4)]
    coasting = _ends_row(
        _with_ends(t, [(0.0, 0.0)] * 4, [(1.0, 0.0)] * 4, [(1.0, 1.0)] * 4, detection_index=-1)
    )
    assert math.isnan(coasting["ends_occluded"])  # no cluster this cycle
    assert coasting["end_speed_max_mps"] == pytest.approx(0.0, abs=1e-12)
    without = _ends_row(
        _with_ends(t, [(math.nan, math.nan)] * 4, [(math.nan, math.nan)] * 4, [(math.nan,) * 2] * 4)
    )
    assert all(math.isnan(v) for v in without.values())  # detections that carried no ends
