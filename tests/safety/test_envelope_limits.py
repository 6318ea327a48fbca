"""Envelopes field by field: the UNKNOWN fallback, the frame, the stamp, the rounding margin
(SR-PRED-1, SR-STOP-4).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) showed these unwatched:
an UNKNOWN-mode row keeping its classifier confidence (and so a narrower margin than the
near-reversal one), the envelopes' stamp, a transform applied at the identity pose, stopping
parameters given to ``from_config`` being ignored, a class list without a person, and the
rounding margin that keeps the exact grown region inside the polygon.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline.classify.model import MODEL_CLASSES
from pipeline.config import default_config
from pipeline.predict import predict
from pipeline.types import FloatArray, PredictionMode, Predictions
from properties.prediction_cases import classification, features_for, tracks_of
from safety.geometry.envelopes import ROUNDING_M, EnvelopeBuilder, grown_polygons
from safety.model.stopping import StoppingParams

ENVELOPES = ["safety/geometry/envelopes.py"]
CONFIG = default_config()
PARAMS = StoppingParams.from_config(CONFIG)


def _predictions(name: str, confidence: float, stamp_s: float = 12.5) -> Predictions:
    """One moving track 3 m ahead classified as ``name``, predicted at ``stamp_s``."""
    hist = np.stack([np.linspace(4.5, 3.0, 15), np.zeros(15)], axis=1)
    tracks = tracks_of(np.array([3.0, 0.0]), np.array([-0.3, 0.0]), 0.01, 0.02, 0.5, 1.0, hist)
    tracks = replace(tracks, stamp_s=stamp_s)
    return predict(
        tracks,
        features_for(tracks, False),
        classification(tracks, name, confidence),
        CONFIG.predict,
        CONFIG.classify.medium_confidence_min,
    )


def _edge_distances(ring: FloatArray, centre: FloatArray) -> FloatArray:
    """Distance [m] from ``centre`` to each edge's line of the counter-clockwise ``ring``
    (positive inside)."""
    a, b = ring, np.roll(ring, -1, axis=0)
    edge = b - a
    cross = edge[:, 0] * (centre[1] - a[:, 1]) - edge[:, 1] * (centre[0] - a[:, 0])
    distances: FloatArray = cross / np.hypot(edge[:, 0], edge[:, 1])
    return distances


@pytest.mark.requirement("SR-STOP-4", kind="example", code=ENVELOPES)
def test_an_unknown_row_has_confidence_zero_and_the_widest_margin() -> None:
    """A row predicted UNKNOWN keeps no classifier confidence, whatever the classifier said:
    confidence 0, the near-reversal tier and margin, the worst closing speed. The row beside it
    (same confidence, not UNKNOWN) keeps its own."""
    moving = _predictions("forklift_moving", 0.95)
    assert moving.n == 1
    assert moving.mode[0] != int(PredictionMode.UNKNOWN)
    both = replace(
        moving,
        track_id=np.array([1, 2]),
        mode=np.array([moving.mode[0], int(PredictionMode.UNKNOWN)]),
        class_index=np.repeat(moving.class_index, 2),
        confidence=np.array([0.95, 0.95]),
        near_reversal=np.repeat(moving.near_reversal, 2),
        person_compatible=np.repeat(moving.person_compatible, 2),
        speed_mps=np.repeat(moving.speed_mps, 2),
        heading_rad=np.repeat(moving.heading_rad, 2),
        body_radius_m=np.repeat(moving.body_radius_m, 2),
        reach_xy_m=np.repeat(moving.reach_xy_m, 2, axis=0),
    )
    env = EnvelopeBuilder.from_config(CONFIG).build(both, MODEL_CLASSES)
    high, _, near = PARAMS.margins_m
    assert env.confidence.tolist() == [0.95, 0.0]
    assert env.tier.tolist() == [0, 2]
    assert env.margin_m.tolist() == [high, near]
    assert env.closing_speed_mps[1] == PARAMS.worst_closing_speed_mps


@pytest.mark.requirement("SR-PRED-1", kind="example", code=ENVELOPES)
def test_at_the_identity_pose_the_envelopes_are_the_grown_polygons() -> None:
    """No transform at the identity pose: the polygons are the grown regions themselves, with
    no rounding slack added; the envelopes carry the predictions' stamp."""
    pred = _predictions("static", 0.95)
    env = EnvelopeBuilder.from_config(CONFIG).build(pred, MODEL_CLASSES)
    grown = grown_polygons(
        pred.reach_xy_m, pred.body_radius_m + env.margin_m, CONFIG.predict.disc_sides
    )
    assert np.array_equal(env.polygons.vertices_m, grown.vertices_m)
    assert env.polygons.slack_m.tolist() == grown.slack_m.tolist()
    assert env.stamp_s == 12.5
    moved = EnvelopeBuilder.from_config(CONFIG).build(pred, MODEL_CLASSES, (1.0, 0.0, 0.0))
    assert (moved.polygons.slack_m > grown.slack_m).all()  # a real move adds its rounding


@pytest.mark.requirement("SR-STOP-4", kind="example", code=ENVELOPES)
def test_given_stopping_parameters_set_the_margins() -> None:
    params = replace(PARAMS, margins_m=(0.25, 0.5, 0.75))
    pred = _predictions("static", 0.95)
    env = EnvelopeBuilder.from_config(CONFIG, params).build(pred, MODEL_CLASSES)
    assert env.margin_m.tolist() == [0.25]
    assert EnvelopeBuilder.from_config(CONFIG).build(pred, MODEL_CLASSES).margin_m.tolist() == [
        PARAMS.margins_m[0]
    ]


@pytest.mark.requirement("SR-PRED-1", kind="example", code=ENVELOPES)
def test_a_class_list_without_a_person_gives_no_person_speed() -> None:
    """With no person class, no row closes at the walking speed (class indices are the
    list's, so index 2 is a moving class here; the row's size rules a person out)."""
    pred = _predictions("forklift_moving", 0.95)
    row = replace(pred, class_index=np.array([2]), person_compatible=np.array([False]))
    builder = EnvelopeBuilder.from_config(CONFIG)
    closing = builder.closing_speeds(row, ("pallet", "cart", "forklift_moving", "rack"))
    assert closing.tolist() == [max(float(pred.speed_mps[0]), PARAMS.static_speed_mps)]
    assert closing[0] != PARAMS.person_speed_mps


@pytest.mark.requirement("SR-PRED-1", kind="example", code=ENVELOPES)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_grown_polygon_keeps_the_rounding_margin(dtype: type[np.floating]) -> None:
    """Every edge of a polygon grown from a point lies at least its radius plus half the
    rounding margin from it, also for single-precision radii (whose own rounding would
    swallow the margin: 0.3 and 0.8 in float32 put edges 2 and 5 nm inside the disc)."""
    centre = np.array([1.25, -0.5])
    reach = np.tile(centre, (3, 3, 1))  # degenerate regions: one point each
    radius = np.array([0.5, 0.3, 0.8], dtype=dtype)
    polygons = grown_polygons(reach, radius, 16)
    for k in range(3):
        inner = _edge_distances(polygons.vertex_list(k), centre).min()
        assert inner >= float(radius[k]) + 0.5 * ROUNDING_M, (k, inner - float(radius[k]))


@pytest.mark.requirement("SR-STOP-4", kind="example", code=ENVELOPES)
def test_a_single_precision_confidence_is_tiered_at_its_float64_value() -> None:
    """A float32 confidence (an exported classifier's output) is compared with the tier
    thresholds at its own value, widened to float64: float32(0.7) is 0.69999998..., below a
    threshold of 0.7, so it takes the medium tier. Compared in float32 the threshold would be
    rounded down to the same value and the row would take the narrower high-tier margin."""
    params = replace(PARAMS, high_confidence_min=0.7, medium_confidence_min=0.5)
    builder = EnvelopeBuilder.from_config(CONFIG, params)
    conf = np.array([0.7, 0.9, 0.4], dtype=np.float32)
    margin, tier = builder.margins(conf, np.zeros(3, dtype=bool))
    high, medium, near = params.margins_m
    assert float(conf[0]) < 0.7
    assert tier.tolist() == [1, 0, 2]
    assert margin.tolist() == [medium, high, near]
    assert margin.dtype == np.float64
    assert tier.dtype == np.int64


@pytest.mark.requirement("SR-STOP-4", kind="example", code=ENVELOPES)
def test_the_margins_are_floats_also_from_the_exact_parameters() -> None:
    """With the proofs' exact parameters (Fractions of the configured decimals) the margins
    are the same float64 array as with the float parameters, and so are the envelopes built
    from them; an array of Fractions would not be a ``FloatArray``."""
    conf = np.array([0.95, 0.6, 0.1, 0.95])
    near = np.array([False, False, False, True])
    float_margin, float_tier = EnvelopeBuilder.from_config(CONFIG).margins(conf, near)
    exact = EnvelopeBuilder.from_config(CONFIG, PARAMS.exact())
    margin, tier = exact.margins(conf, near)
    assert margin.dtype == np.float64
    assert margin.tolist() == float_margin.tolist() == [0.4, 0.7, 1.0, 1.0]
    assert tier.tolist() == float_tier.tolist() == [0, 1, 2, 2]
    env = exact.build(_predictions("static", 0.95), MODEL_CLASSES)
    assert env.margin_m.dtype == np.float64
    assert env.margin_m.tolist() == [PARAMS.margins_m[0]]
