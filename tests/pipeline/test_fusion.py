"""Fusion by example: freshness fallback, gating, boosts, pedestrians, Doppler, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.errors import ConfigError
from pipeline.fusion import FusionError, doppler_row, doppler_update, fuse
from pipeline.types import RadarDetections, ThermalDetections, TrackStatus
from properties.fusion_cases import make_tracks
from safety.model.freshness import is_fresh

FUSION = ["pipeline/fusion.py"]
CONFIG = default_config()


def _thermal(
    stamps: list[float], xy: list[tuple[float, float]], conf: float = 0.9
) -> ThermalDetections:
    a = np.array(xy, dtype=np.float64).reshape(-1, 2)
    return ThermalDetections(np.array(stamps), a[:, 0], a[:, 1], np.full(len(stamps), conf))


def test_is_fresh_reads_floats_and_arrays_alike() -> None:
    assert is_fresh(10.0, 9.85, 0.2, 0.0)
    assert not is_fresh(10.0, 9.7, 0.2, 0.0)
    assert not is_fresh(10.0, 10.01, 0.2, 0.0)  # from the future: skew assumption broken
    assert is_fresh(10.0, 10.01, 0.2, 0.02)
    assert not is_fresh(10.0, math.nan, 0.2, 0.0)
    ages = np.array([0.0, 0.1, 0.2 - 1e-9, 0.2, 0.3, math.nan, -math.inf])
    got = is_fresh(10.0, 10.0 - ages, 0.2, 0.0)
    assert got.tolist() == [True, True, True, False, False, False, False]


@pytest.mark.requirement("SR-FUS-1", kind="example", code=FUSION)
def test_stale_thermal_falls_back_to_lidar_only() -> None:
    tracks = make_tracks(5.0, [[2.0, 0.0], [0.0, 3.0]])
    thermal = _thermal([4.7, 4.79], [(2.1, 0.0), (0.0, 3.0)])  # 0.3 s and 0.21 s old
    fused = fuse(
        5.0, tracks, CONFIG.fusion, guard=is_fresh, confidence=np.array([0.5, 0.5]), thermal=thermal
    )
    assert fused.counts.n_thermal_stale == 2
    assert fused.counts.lidar_only
    assert fused.n_pedestrians == 0
    assert fused.thermal_index.tolist() == [-1, -1]
    assert fused.confidence.tolist() == [0.5, 0.5]


@pytest.mark.requirement("SR-FUS-3", kind="example", code=FUSION)
def test_matched_thermal_boosts_and_unmatched_becomes_pedestrian() -> None:
    tracks = make_tracks(5.0, [[2.0, 0.0], [0.0, 3.0], [9.0, 9.0]])
    # Near track 0 (0.3 m), near track 1 (1.9 m: inside the 2 m gate), and far from everything.
    thermal = _thermal([4.9, 4.9, 4.95], [(2.3, 0.0), (0.0, 4.9), (-5.0, -5.0)], conf=0.8)
    fused = fuse(
        5.0,
        tracks,
        CONFIG.fusion,
        guard=is_fresh,
        confidence=np.array([0.7, 0.9, 0.4]),
        thermal=thermal,
    )
    assert fused.thermal_index.tolist() == [0, 1, -1]
    assert fused.confidence.tolist() == pytest.approx([0.9, 1.0, 0.4])  # boost 0.2, capped at 1
    assert fused.pedestrian_index.tolist() == [2]
    assert fused.pedestrian_x_m.tolist() == [-5.0]
    assert fused.pedestrian_stamp_s.tolist() == [4.95]
    assert fused.pedestrian_confidence.tolist() == [0.3]  # fusion.thermal_only_confidence
    assert not fused.counts.lidar_only


def test_gate_is_two_metres_and_tracks_are_taken_to_the_detection_time() -> None:
    # The track moves at 2 m/s along x; the detection is 0.15 s old, so the track was 0.3 m
    # behind its current position then.
    tracks = make_tracks(5.0, [[3.0, 0.0]], vxy_mps=[[2.0, 0.0]])
    fused = fuse(
        5.0, tracks, CONFIG.fusion, guard=is_fresh, thermal=_thermal([4.85], [(0.75, 0.0)])
    )
    assert fused.thermal_index.tolist() == [0]  # 2.7 m now, 1.95 m at the detection's time
    fused = fuse(
        5.0, tracks, CONFIG.fusion, guard=is_fresh, thermal=_thermal([4.85], [(0.65, 0.0)])
    )
    assert fused.thermal_index.tolist() == [-1]
    assert fused.n_pedestrians == 1


def test_one_detection_per_track_and_dormant_tracks_never_match() -> None:
    tracks = make_tracks(
        1.0,
        [[1.0, 0.0], [5.0, 0.0]],
        status=[int(TrackStatus.CONFIRMED), int(TrackStatus.DORMANT)],
    )
    thermal = _thermal([1.0, 1.0, 1.0], [(1.1, 0.0), (1.2, 0.0), (5.0, 0.0)])
    fused = fuse(1.0, tracks, CONFIG.fusion, guard=is_fresh, thermal=thermal)
    assert fused.thermal_index.tolist() == [0, -1]
    assert fused.pedestrian_index.tolist() == [1, 2]  # conservative: two people, not one


def test_invalid_and_future_detections_are_counted_not_used() -> None:
    tracks = make_tracks(2.0, [[1.0, 0.0]])
    thermal = _thermal(
        [math.nan, 2.5, 1.9, 1.95], [(1.0, 0.0), (1.0, 0.0), (math.inf, 0.0), (-3, 0)]
    )
    fused = fuse(2.0, tracks, CONFIG.fusion, guard=is_fresh, thermal=thermal)
    c = fused.counts
    assert (c.n_thermal_invalid, c.n_thermal_future, c.n_thermal_stale) == (2, 1, 0)
    assert (c.n_thermal_matched, c.n_thermal_only) == (0, 1)


def test_over_cap_keeps_the_nearest_and_counts_the_rest() -> None:
    config = overridden(CONFIG, {"fusion": {"max_thermal": 2}})
    thermal = _thermal([1.0] * 4, [(9.0, 0.0), (1.0, 0.0), (5.0, 0.0), (2.0, 0.0)])
    fused = fuse(
        1.0, make_tracks(1.0, np.empty((0, 2))), config.fusion, guard=is_fresh, thermal=thermal
    )
    assert fused.counts.n_thermal_over_cap == 2
    assert fused.pedestrian_index.tolist() == [1, 3]


def test_bad_confidence_shape_and_unsafe_config_are_refused() -> None:
    tracks = make_tracks(1.0, [[1.0, 0.0]])
    with pytest.raises(FusionError, match=r"confidence has shape \(2,\)"):
        fuse(1.0, tracks, CONFIG.fusion, guard=is_fresh, confidence=np.array([0.1, 0.2]))
    # The cross-section rule is checked when the configuration loads (SR-CFG-1).
    with pytest.raises(ConfigError, match=r"thermal_only_confidence \(0.6\) must be below"):
        overridden(CONFIG, {"fusion": {"thermal_only_confidence": 0.6}})
    with pytest.raises(ValueError, match="equal length"):
        ThermalDetections(np.zeros(2), np.zeros(1), np.zeros(2), np.zeros(2))


def test_skew_config_must_stay_below_the_maximum_age() -> None:
    with pytest.raises(ConfigError, match=r"fusion.clock_skew_s \(0.3\) must be below"):
        overridden(CONFIG, {"fusion": {"clock_skew_s": 0.3}})


@pytest.mark.requirement("SR-FUS-4", kind="example", code=FUSION)
def test_doppler_measures_the_radial_velocity() -> None:
    rows = doppler_row(np.array([0.0, math.pi / 2]))
    assert np.allclose(rows, [[0, 0, 1, 0], [0, 0, 0, 1]], rtol=0.0, atol=1e-16)
    # A track believed still, very uncertain in velocity; the radar sees it approach at 1 m/s
    # straight ahead: the update pulls vx towards -1 and leaves vy alone.
    x = np.array([[5.0, 0.0, 0.0, 0.0]])
    p = np.diag([0.01, 0.01, 4.0, 4.0])[None]
    new_x, new_p = doppler_update(x, p, np.array([0.0]), np.array([-1.0]), 0.1)
    assert new_x[0, 2] == pytest.approx(-1.0 * 4.0 / (4.0 + 0.01))
    assert new_x[0, 3] == 0.0
    assert new_p[0, 2, 2] < 0.01
    assert new_p[0, 3, 3] == 4.0


def test_radar_updates_the_matched_track_only() -> None:
    tracks = make_tracks(3.0, [[4.0, 0.0], [0.0, -6.0]])
    radar = RadarDetections(
        np.array([2.95, 2.95, 2.5]),
        np.array([4.1, 20.0, 6.0]),
        np.array([0.0, 1.0, -math.pi / 2]),
        np.array([-0.8, 3.0, 0.5]),
    )
    fused = fuse(3.0, tracks, CONFIG.fusion, guard=is_fresh, radar=radar)
    assert fused.radar_index.tolist() == [0, -1]
    assert fused.tracks.state[0, 2] < 0.0
    assert fused.tracks.state[1].tolist() == tracks.state[1].tolist()
    c = fused.counts
    assert (c.n_radar_matched, c.n_radar_unmatched, c.n_radar_stale) == (1, 1, 1)
