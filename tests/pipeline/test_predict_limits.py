"""Prediction where the mutation campaign found it unwatched (SR-PRED-1, SR-PRED-4).

The gaps (SR-EVD-6, docs/findings/mutation.md): the confirmed heading was only ever read from
one track with a straight, full history, so which entry is the oldest, which the newest, the
closed travel threshold, the velocity's axes and a heading left unknown were never told apart;
no track stood still (0 m/s, with and without velocity uncertainty) or crawled at a subnormal
speed, where the spread's division must stay silent; no batch mixed a body-axis row with a
plain cone row; a cone exactly 90 deg wide, a confidence exactly at the medium threshold, the
reverse mode's speed floor and the horizon in the output were never read; and the prediction
role (:class:`KinematicPredictor`) was never called.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.predict import KinematicPredictor, confirmed_heading_rad, predict
from pipeline.track.heading import TrackHeadings
from pipeline.track.kalman import largest_std
from pipeline.types import Classification, PredictionMode, Tracks
from properties.prediction_cases import classification, features_for, tracks_of

PREDICT = ["pipeline/predict.py"]
NAN = math.nan


def _stack(*parts: Tracks) -> Tracks:
    """One snapshot of the given one-track snapshots, with IDs 0, 1, ..."""
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(Tracks):
        first = getattr(parts[0], f.name)
        fields[f.name] = (
            np.concatenate([getattr(p, f.name) for p in parts])
            if isinstance(first, np.ndarray)
            else first
        )
    fields["track_id"] = np.arange(len(parts), dtype=np.int64)
    return Tracks(**fields)


def _classified(tracks: Tracks, names: list[str], confidence: float) -> Classification:
    rows = [classification(_track(), name, confidence) for name in names]
    return replace(
        rows[0],
        track_id=tracks.track_id,
        class_index=np.concatenate([r.class_index for r in rows]),
        probability=np.concatenate([r.probability for r in rows]),
        confidence=np.concatenate([r.confidence for r in rows]),
    )


def _track(
    v: tuple[float, float] = (0.0, 0.0),
    history: list[tuple[float, float]] | None = None,
    sigma_v: float = 0.01,
    box_m: tuple[float, float] = (0.8, 2.0),
) -> Tracks:
    hist = np.zeros((0, 2)) if history is None else np.array(history, dtype=np.float64)
    return tracks_of(np.zeros(2), np.array(v), 0.01, sigma_v, box_m[0], box_m[1], hist)


@pytest.mark.requirement("SR-PRED-1", kind="example", code=PREDICT)
def test_each_tracks_confirmed_heading_comes_from_its_own_history_or_velocity() -> None:
    """A: five entries, a bend at the last (oldest (0, 0), newest (3, 4)); B: a full history
    whose oldest entry is off the line of the rest (heading 0, not the later entries' 90 deg);
    C: exactly ``heading_min_travel_m`` of travel (the threshold is closed) and a velocity
    pointing elsewhere; D: no history, moving along +y; E: no history, speed exactly k sigma_v
    (not certain: unknown, NaN)."""
    section = default_config().predict
    m = section.heading_min_travel_m
    a = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (3.0, 4.0)]
    b = [(-2.0, 0.0)] + [(0.0, -1.0 + i / 13.0) for i in range(14)]
    b[-1] = (0.0, 0.0)
    tracks = _stack(
        _track(history=a),
        _track(history=b),
        _track(v=(0.0, -1.0), history=[(0.0, 0.0), (m, 0.0)]),
        _track(v=(0.0, 1.0)),
        _track(v=(0.2, 0.0)),
    )
    speed = np.hypot(tracks.state[:, 2], tracks.state[:, 3])
    sigma_v = np.array([0.01, 0.01, 0.01, 0.01, 0.1])
    heading = confirmed_heading_rad(tracks, speed, sigma_v, section)
    assert heading.dtype == np.float64
    assert heading[:4].tolist() == [math.atan2(4.0, 3.0), 0.0, 0.0, 0.5 * math.pi]
    assert math.isnan(heading[4])


@pytest.mark.requirement("SR-PRED-1", kind="example", code=PREDICT)
def test_mismatched_inputs_are_refused_with_the_whole_message() -> None:
    config = default_config()
    tracks = _track()
    other = replace(tracks, track_id=np.array([7]))
    message = "predict: tracks, features, classification and headings must list the same tracks"
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        predict(
            tracks,
            features_for(other, False),
            classification(tracks, "person", 0.9),
            config.predict,
            config.classify.medium_confidence_min,
        )


@pytest.mark.requirement("SR-PRED-1", kind="example", code=PREDICT)
def test_standing_and_crawling_tracks_raise_no_floating_point_warning() -> None:
    """0 m/s with and without velocity uncertainty (x / 0 and 0 / 0 in the spread) and a
    subnormal speed (k sigma_v / speed overflows): discs, and no warning of any kind."""
    config = default_config()
    tracks = _stack(
        _track(v=(0.0, 0.0), sigma_v=0.1),
        _track(v=(0.0, 0.0), sigma_v=0.0),
        _track(v=(1e-310, 0.0), sigma_v=0.1),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = predict(
            tracks,
            features_for(tracks, False),
            classification(tracks, "person", 0.9),
            config.predict,
            config.classify.medium_confidence_min,
        )
    assert [PredictionMode(int(m)) for m in result.mode] == [PredictionMode.CONE] * 3
    assert np.isfinite(result.reach_xy_m).all()


@pytest.mark.requirement("SR-PRED-1", kind="example", code=PREDICT)
def test_the_horizon_the_reverse_floor_and_the_medium_threshold() -> None:
    """A near-reversal truck crawling at 0.1 m/s: its STOP row reaches at its own speed bound,
    its REVERSE row at least at the reversal speed; the rows say the horizon; a confidence
    exactly at ``classify.medium_confidence_min`` is trusted."""
    config = default_config()
    pc, medium = config.predict, config.classify.medium_confidence_min
    tracks = _track(v=(0.1, 0.0), history=[(-1.0, 0.0), (0.0, 0.0)])
    result = predict(
        tracks,
        features_for(tracks, True),
        classification(tracks, "forklift_moving", medium),
        pc,
        medium,
    )
    assert result.horizon_s == pc.horizon_s
    assert [PredictionMode(int(m)) for m in result.mode] == [
        PredictionMode.STOP,
        PredictionMode.REVERSE,
    ]
    bound = 0.1 + pc.velocity_sigmas * 0.01
    assert result.speed_mps.tolist() == pytest.approx([bound, pc.reversal_speed_mps])


def _axis_config(**predict: object) -> object:
    return overridden(default_config(), {"predict": {"heading_source": "track", **predict}})


@pytest.mark.requirement("SR-PRED-4", kind="example", code=PREDICT)
def test_a_body_axis_row_beside_a_plain_cone_row_keeps_each_its_region() -> None:
    """A standing truck (no direction from motion, a body axis at 0.3 rad) and a person
    walking along +x, in one batch and each alone: the same regions, row for row."""
    config = _axis_config()
    assert isinstance(config, type(default_config()))
    pc, medium = config.predict, config.classify.medium_confidence_min
    truck = _track(box_m=(1.2, 2.5))
    walker = _track(v=(1.2, 0.0), history=[(-1.0, 0.0), (0.0, 0.0)], box_m=(0.4, 0.5))

    def run(tracks: Tracks, names: list[str], axes: list[float]) -> np.ndarray:
        headings = TrackHeadings(tracks.track_id, np.array(axes), np.zeros(tracks.n, dtype=bool))
        cls = _classified(tracks, names, 0.9)
        out = predict(tracks, features_for(tracks, False), cls, pc, medium, headings)
        return out.reach_xy_m

    both = run(_stack(truck, walker), ["vehicle", "person"], [0.3, NAN])
    alone = [run(_stack(truck), ["vehicle"], [0.3]), run(_stack(walker), ["person"], [NAN])]
    for row, single in zip(both, alone, strict=True):
        width = single.shape[1]
        assert row[:width].tolist() == single[0].tolist()
        assert (row[width:] == single[0, :1]).all()  # padding repeats the first vertex


@pytest.mark.requirement("SR-PRED-4", kind="example", code=PREDICT)
def test_a_cone_exactly_ninety_degrees_wide_takes_the_body_axis() -> None:
    """cone_half + asin(k sigma_v / |v|) == pi / 2 exactly (|v| = 1 m/s, k sigma_v = cos 15
    deg, whose asin adds to 15 deg to exactly the float pi / 2): the sector would be a disc from
    90 deg on (``sector_points``), so the row is taken along the body axis, as any wider one."""
    config = _axis_config()
    assert isinstance(config, type(default_config()))
    pc, medium = config.predict, config.classify.medium_confidence_min
    spread_target = math.cos(math.radians(pc.cone_half_angle_deg))
    sigma_v = spread_target / pc.velocity_sigmas
    tracks = _track(v=(1.0, 0.0), sigma_v=sigma_v, box_m=(1.2, 2.5))
    assert pc.velocity_sigmas * largest_std(tracks.covariance[:, 2:, 2:])[0] == spread_target
    assert math.radians(pc.cone_half_angle_deg) + math.asin(spread_target) == 0.5 * math.pi
    headings = TrackHeadings(tracks.track_id, np.array([0.3]), np.zeros(1, dtype=bool))
    cls = classification(tracks, "vehicle", 0.9)
    result = predict(tracks, features_for(tracks, False), cls, pc, medium, headings)
    assert result.heading_rad.tolist() == [0.3]


@pytest.mark.requirement("SR-PRED-1", kind="example", code=PREDICT)
def test_the_prediction_role_is_the_function_with_its_section() -> None:
    """Every input reaches the function: a standing truck with a body axis (headings used),
    a walker, a crawling forklift flagged near reversal, one of them below the medium
    confidence."""
    config = _axis_config()
    assert isinstance(config, type(default_config()))
    pc, medium = config.predict, config.classify.medium_confidence_min
    tracks = _stack(_track(box_m=(1.2, 2.5)), _track(v=(1.0, 0.0)), _track(v=(0.1, 0.0)))
    feats = features_for(tracks, True)
    cls = _classified(tracks, ["vehicle", "person", "forklift_moving"], 0.9)
    cls = replace(cls, confidence=np.array([0.9, 0.9, medium - 0.01]))
    headings = TrackHeadings(tracks.track_id, np.array([0.3, NAN, NAN]), np.zeros(3, dtype=bool))
    role = KinematicPredictor(pc, medium).predict(tracks, feats, cls, headings)
    direct = predict(tracks, feats, cls, pc, medium, headings)
    assert direct.heading_rad[0] == 0.3  # the headings are used
    assert PredictionMode.UNKNOWN in direct.mode.tolist()
    for f in dataclasses.fields(direct):
        got, want = getattr(role, f.name), getattr(direct, f.name)
        assert (
            np.array_equal(got, want, equal_nan=True)
            if isinstance(want, np.ndarray)
            else got == want
        )
