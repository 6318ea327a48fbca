"""Examples for prediction: regions by mode, confirmed heading, dormant tracks (SR-PRED-1)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from pipeline.config import default_config
from pipeline.constructive import disc_points, sector_points
from pipeline.features import feature_index
from pipeline.predict import near_reversal_flags, predict
from pipeline.track.kalman import largest_std
from pipeline.types import PredictionMode, TrackStatus
from properties.prediction_cases import classification, features_for, tracks_of


def _hull(points: np.ndarray) -> shapely.Geometry:
    return shapely.MultiPoint(points).convex_hull


def test_sector_points_contain_the_exact_sector() -> None:
    pts = sector_points(
        np.array([1.0]),
        np.array([2.0]),
        np.array([0.3]),
        np.array([0.5]),
        np.array([2.0]),
        math.radians(15),
        12,
    )
    hull = _hull(pts[0]).buffer(1e-12)
    arc = np.linspace(0.3 - 0.5, 0.3 + 0.5, 400)
    exact = np.stack([1.0 + 2.0 * np.cos(arc), 2.0 + 2.0 * np.sin(arc)], axis=1)
    assert shapely.covers(hull, shapely.points(exact)).all()
    assert hull.area < 1.01 * 0.5 * 2.0**2 * 1.0  # close to the sector's own area
    # A half-angle of 90 deg or more, or no heading, is a disc.
    wide = sector_points(
        np.zeros(2),
        np.zeros(2),
        np.array([0.0, np.nan]),
        np.array([2.0, 0.1]),
        np.ones(2),
        math.radians(15),
        12,
    )
    for row in wide:
        assert _hull(row).area == pytest.approx(12 * math.tan(math.pi / 12), rel=1e-9)


def test_disc_points_circumscribe_and_largest_std() -> None:
    ring = disc_points(np.zeros(1), np.zeros(1), np.array([1.0]), 8)[0]
    assert np.hypot(ring[:, 0], ring[:, 1]).min() > 1.0
    cov = np.array([[[4.0, 0.0], [0.0, 1.0]], [[1.0, 1.0], [1.0, 1.0]]])
    assert largest_std(cov) == pytest.approx([2.0, math.sqrt(2.0)])


def _one(speed: float = 1.0, status: TrackStatus = TrackStatus.CONFIRMED, travel: float = 1.5):  # type: ignore[no-untyped-def]
    hist = np.stack([np.linspace(-travel, 0.0, 15), np.zeros(15)], axis=1)
    tracks = tracks_of(np.zeros(2), np.array([speed, 0.0]), 0.01, 0.05, 0.8, 2.0, hist)
    return replace(tracks, status=np.array([int(status)]))


@pytest.mark.parametrize(
    ("name", "conf", "near", "modes"),
    [
        ("forklift_moving", 0.9, False, [PredictionMode.CONE]),
        ("forklift_moving", 0.9, True, [PredictionMode.STOP, PredictionMode.REVERSE]),
        ("person", 0.9, True, [PredictionMode.CONE]),  # the flag counts for forklifts only
        ("forklift_near_reversal", 0.6, False, [PredictionMode.STOP, PredictionMode.REVERSE]),
        ("static", 0.9, False, [PredictionMode.FOOTPRINT]),
        ("cart", 0.4, False, [PredictionMode.UNKNOWN]),  # below the medium confidence
        (None, 0.0, False, [PredictionMode.UNKNOWN]),  # unscored
    ],
)
def test_modes_follow_class_confidence_and_flag(
    name: str | None, conf: float, near: bool, modes: list[PredictionMode]
) -> None:
    config = default_config()
    tracks = _one()
    result = predict(
        tracks,
        features_for(tracks, near),
        classification(tracks, name, conf),
        config.predict,
        config.classify.medium_confidence_min,
    )
    assert [PredictionMode(int(m)) for m in result.mode] == modes
    assert result.near_reversal.tolist() == [
        m in (PredictionMode.STOP, PredictionMode.REVERSE) for m in modes
    ]


@pytest.mark.parametrize(
    ("name", "speed", "since", "modes"),
    [
        # A truck called moving or stationary that stopped 0.5 s ago: near reversal.
        ("forklift_moving", 0.1, 0.5, [PredictionMode.STOP, PredictionMode.REVERSE]),
        ("forklift_stationary", 0.0, 1.0, [PredictionMode.STOP, PredictionMode.REVERSE]),
        ("forklift_stationary", 0.0, 1.01, [PredictionMode.FOOTPRINT]),  # longer ago
        ("forklift_stationary", 0.0, math.nan, [PredictionMode.FOOTPRINT]),  # never moved
        ("forklift_moving", 0.3, 0.0, [PredictionMode.CONE]),  # still at speed
        ("cart", 0.0, 0.2, [PredictionMode.FOOTPRINT]),  # forklift classes only
    ],
)
def test_a_forklift_that_just_stopped_is_near_reversal_whatever_its_state(
    name: str, speed: float, since: float, modes: list[PredictionMode]
) -> None:
    config = default_config()
    tracks = _one(speed)
    feats = features_for(tracks, False)
    values = feats.values.copy()
    values[:, feature_index("time_since_moving_s")] = since
    feats = replace(feats, values=values)
    flags = near_reversal_flags(feats, config.predict)
    assert flags.tolist() == [speed < 0.3 and since <= 1.0]
    result = predict(
        tracks,
        feats,
        classification(tracks, name, 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    assert [PredictionMode(int(m)) for m in result.mode] == modes


def test_cone_reverse_and_footprint_regions() -> None:
    config = default_config()
    h = config.predict.horizon_s
    tracks = _one(speed=1.0)
    cone = predict(
        tracks,
        features_for(tracks, False),
        classification(tracks, "forklift_moving", 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    bound = 1.0 + 2 * 0.05
    region = _hull(cone.reach_xy_m[0])
    assert region.covers(shapely.Point(bound * h, 0.0))
    assert not region.covers(shapely.Point(-0.1, 0.0))  # nothing behind a moving object
    near = predict(
        tracks,
        features_for(tracks, True),
        classification(tracks, "forklift_near_reversal", 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    reverse = _hull(near.reach_xy_m[near.mode == PredictionMode.REVERSE][0])
    # Back up at the reversal speed opposite the confirmed heading (+x from the history).
    assert reverse.covers(shapely.Point(-config.predict.reversal_speed_mps * h, 0.0))
    still = predict(
        tracks,
        features_for(tracks, False),
        classification(tracks, "static", 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    assert np.allclose(still.reach_xy_m[0], 0.0)
    assert still.body_radius_m[0] == pytest.approx(0.5 * math.hypot(0.8, 2.0) + 2 * 0.01)


def test_unknown_confirmed_heading_makes_both_modes_discs() -> None:
    config = default_config()
    tracks = _one(speed=0.01, travel=0.05)  # barely moved, speed below its uncertainty
    result = predict(
        tracks,
        features_for(tracks, True),
        classification(tracks, "forklift_near_reversal", 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    assert np.isnan(result.heading_rad).all()
    reverse = _hull(result.reach_xy_m[result.mode == PredictionMode.REVERSE][0])
    r = config.predict.reversal_speed_mps * config.predict.horizon_s
    for angle in np.linspace(0, 2 * math.pi, 16):
        assert reverse.covers(shapely.Point(r * math.cos(angle), r * math.sin(angle)))


def test_dormant_tracks_get_no_prediction_and_inputs_must_match() -> None:
    config = default_config()
    tracks = _one(status=TrackStatus.DORMANT)
    result = predict(
        tracks,
        features_for(tracks, False),
        classification(tracks, "person", 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    assert result.n == 0
    other = _one()
    with pytest.raises(ValueError, match="same tracks"):
        predict(
            tracks,
            features_for(replace(other, track_id=np.array([7])), False),
            classification(tracks, "person", 0.9),
            config.predict,
            config.classify.medium_confidence_min,
        )
