"""Examples for envelopes: margins, closing speeds, frames, and the consumers (SR-PRED-1, -3)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from pipeline.classify.model import MODEL_CLASSES
from pipeline.config import SafecaseConfig, default_config
from pipeline.predict import predict
from pipeline.types import Action, Envelopes, PredictionMode, Predictions, TrackStatus
from properties.prediction_cases import classification, features_for, tracks_of
from safety.geometry.envelopes import EnvelopeBuilder, body_polygons
from safety.geometry.swept import SweptPathChecker
from safety.model.governor import Governor


def _envelopes(
    name: str | None,
    conf: float,
    xy: tuple[float, float] = (3.0, 0.0),
    near: bool = False,
    box_m: tuple[float, float] = (1.2, 2.5),
) -> tuple[SafecaseConfig, Predictions, Envelopes]:
    """One track's envelopes; its box (width, length) is larger than a person unless given."""
    config = default_config()
    hist = np.stack([np.linspace(xy[0] + 1.5, xy[0], 15), np.full(15, xy[1])], axis=1)
    tracks = tracks_of(np.array(xy), np.array([-0.2, 0.0]), 0.01, 0.02, *box_m, hist)
    pred = predict(
        tracks,
        features_for(tracks, near),
        classification(tracks, name, conf),
        config.predict,
        config.classify.medium_confidence_min,
    )
    return config, pred, EnvelopeBuilder.from_config(config).build(pred, MODEL_CLASSES)


@pytest.mark.parametrize(
    ("name", "conf", "margin", "tier", "closing"),
    [
        ("static", 0.95, 0.4, 0, 0.0),
        ("cart", 0.6, 0.7, 1, 0.0),
        ("person", 0.95, 0.4, 0, 1.6),
        ("forklift_near_reversal", 0.95, 1.0, 2, 0.6),
        ("forklift_moving", 0.3, 1.0, 2, 1.6),  # low confidence: the fallback
        (None, 0.0, 1.0, 2, 1.6),  # unscored: the fallback
    ],
)
def test_margin_tier_and_closing_speed(
    name: str | None, conf: float, margin: float, tier: int, closing: float
) -> None:
    _, _, env = _envelopes(name, conf)
    assert env.margin_m.tolist() == [margin] * env.n
    assert env.tier.tolist() == [tier] * env.n
    assert env.closing_speed_mps.tolist() == pytest.approx([closing] * env.n)


@pytest.mark.parametrize(
    ("name", "near"),
    [("static", False), ("cart", False), ("forklift_near_reversal", True), ("vehicle", False)],
)
def test_a_person_sized_track_closes_at_least_at_the_person_speed(name: str, near: bool) -> None:
    """SR-CLS-8: whatever its class, a track whose box a person could fill (here 0.3 x 0.5 m)."""
    _, pred, env = _envelopes(name, 0.95, near=near, box_m=(0.3, 0.5))
    assert pred.person_compatible.all()
    assert env.closing_speed_mps.tolist() == pytest.approx([1.6] * env.n)


def test_moving_class_closes_at_its_speed_bound() -> None:
    _, pred, env = _envelopes("forklift_moving", 0.95)
    assert env.closing_speed_mps[0] == pytest.approx(pred.speed_mps[0])
    assert pred.speed_mps[0] == pytest.approx(0.2 + 2 * 0.02)


def test_envelope_is_the_body_region_grown_by_the_margin() -> None:
    config, pred, env = _envelopes("static", 0.95)
    body = shapely.Polygon(body_polygons(pred, config.predict.disc_sides).vertex_list(0))
    outer = shapely.Polygon(env.polygons.vertex_list(0))
    assert outer.covers(body.buffer(0.4 - 1e-9))
    assert outer.area < body.buffer(0.4).area * 1.05  # a tight fit, not a box


def test_robot_pose_moves_envelopes_into_the_robot_frame() -> None:
    config = default_config()
    _, pred, world = _envelopes("static", 0.95, xy=(5.0, 1.0))
    robot = EnvelopeBuilder.from_config(config).build(
        pred, MODEL_CLASSES, robot_pose=(4.0, 1.0, math.pi / 2)
    )
    # The object 1 m ahead along world +x is 1 m to the robot's right when it faces +y.
    w = shapely.Polygon(world.polygons.vertex_list(0)).centroid
    r = shapely.Polygon(robot.polygons.vertex_list(0)).centroid
    assert (w.x, w.y) == pytest.approx((5.0, 1.0), abs=1e-9)
    assert (r.x, r.y) == pytest.approx((0.0, -1.0), abs=1e-9)


def test_empty_predictions_give_empty_envelopes() -> None:
    config = default_config()
    tracks = tracks_of(np.zeros(2), np.zeros(2), 0.01, 0.01, 0.5, 0.5, np.zeros((1, 2)))
    dormant = replace(tracks, status=np.array([int(TrackStatus.DORMANT)]))
    empty = predict(
        dormant,
        features_for(dormant, False),
        classification(dormant, "static", 0.9),
        config.predict,
        config.classify.medium_confidence_min,
    )
    env = EnvelopeBuilder.from_config(config).build(empty, MODEL_CLASSES)
    assert empty.n == 0
    assert env.n == 0
    assert env.polygons.n == 0


def test_envelopes_feed_the_swept_path_check_and_the_governor() -> None:
    config, _pred, env = _envelopes("forklift_near_reversal", 0.95, xy=(2.5, 0.0), near=True)
    assert set(env.mode.tolist()) == {int(PredictionMode.STOP), int(PredictionMode.REVERSE)}
    checker = SweptPathChecker(config.geometry)
    report = checker.check(checker.footprint(), checker.candidates(1.0), env.polygons)
    assert report.blocked.any()  # straight ahead: some candidate paths hit it
    hit = report.blocked.any(axis=0)
    free = np.where(hit, 0.0, 10.0)  # free distance along the path (contact now where blocked)
    command = Governor.from_config(config).command(
        0.0, free, env.closing_speed_mps, env.confidence, env.near_reversal
    )
    assert command.action is Action.STOP
    far = Governor.from_config(config).command(
        0.0, np.full(env.n, 5.0), env.closing_speed_mps, env.confidence, env.near_reversal
    )
    assert far.action in (Action.PROCEED, Action.SLOW)
