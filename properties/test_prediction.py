"""Prediction and envelopes: true motion stays inside, margins never shrink (SR-PRED-1, -3).

Every case is a synthetic track with a true motion that satisfies the prediction model's
assumptions (:mod:`properties.prediction_cases`), integrated by the simulator. Containment is
judged by GEOS (shapely), not by our own geometry: the true reference point against the hull
of the predicted reach region (up to 1e-9 m), the true body's corners against the body
polygon and the envelope, and the envelope against the body polygon grown by the margin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.classify.model import MODEL_CLASSES
from pipeline.config import SafecaseConfig
from pipeline.predict import predict
from pipeline.types import ConvexPolygons, PredictionMode
from properties.prediction_cases import MODES, Case, classification, features_for, make_case
from safety.geometry.envelopes import EnvelopeBuilder, body_polygons

CODE = ["pipeline/predict.py", "safety/geometry/envelopes.py"]
TOL_M = 1e-9
EXPECTED = {
    "cone": {PredictionMode.CONE},
    "stop": {PredictionMode.STOP},
    "reverse": {PredictionMode.REVERSE},
    "footprint": {PredictionMode.FOOTPRINT},
    "unknown": {PredictionMode.UNKNOWN},
}


def _shape(polygons: ConvexPolygons, i: int) -> shapely.Polygon:
    return shapely.Polygon(polygons.vertex_list(i))


def _corners(case: Case) -> np.ndarray:
    """(T, 4, 2) corners of the true body (its box about the reference point) over time."""
    hl, hw = 0.5 * case.length_m, 0.5 * case.width_m
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    c, s = np.cos(case.true_heading_rad), np.sin(case.true_heading_rad)
    x = case.true_x_m[:, None] + c[:, None] * local[:, 0] - s[:, None] * local[:, 1]
    y = case.true_y_m[:, None] + s[:, None] * local[:, 0] + c[:, None] * local[:, 1]
    return np.stack([x, y], axis=-1)


@pytest.mark.requirement("SR-PRED-1", kind="property", code=CODE)
@settings(max_examples=examples(150), deadline=None)
@given(mode=st.sampled_from(MODES), seed=st.integers(0, 2**32 - 1))
def test_true_motion_stays_inside_the_prediction_and_envelope(
    safecase_config: SafecaseConfig, mode: str, seed: int
) -> None:
    config = safecase_config
    case = make_case(np.random.default_rng(seed), mode, config)
    tracks = case.tracks
    result = predict(
        tracks,
        features_for(tracks, mode in ("stop", "reverse")),
        classification(tracks, case.class_name, case.confidence),
        config.predict,
        config.classify.medium_confidence_min,
    )
    wanted = EXPECTED[mode]
    rows = [i for i in range(result.n) if PredictionMode(int(result.mode[i])) in wanted]
    assert rows, f"{mode}: no prediction row of mode {wanted}; got {result.mode.tolist()}"
    builder = EnvelopeBuilder.from_config(config)
    env = builder.build(result, MODEL_CLASSES)
    bodies = body_polygons(result, config.predict.disc_sides)
    sigma_p = math.sqrt(tracks.covariance[0, 0, 0])
    start_err = np.array([case.true_x_m[0], case.true_y_m[0]]) - tracks.state[0, :2]
    ref_x = case.true_x_m - start_err[0]
    ref_y = case.true_y_m - start_err[1]
    points = shapely.points(ref_x, ref_y)
    corners = _corners(case).reshape(-1, 2)
    corner_points = shapely.points(corners[:, 0], corners[:, 1])
    # The sharp check: displacement (from the estimated start) inside the reach hull.
    best = np.full(points.shape[0], np.inf)
    for i in rows:
        reach = shapely.MultiPoint(result.reach_xy_m[i]).convex_hull
        best = np.minimum(best, shapely.distance(reach, points))
    assert best.max() <= TOL_M, f"{mode}: true position {best.max():.3g} m outside the reach"
    # The whole body inside a body polygon and inside an envelope, every sample.
    inside_body = np.zeros(corner_points.shape[0], dtype=bool)
    inside_env = np.zeros(corner_points.shape[0], dtype=bool)
    for i in rows:
        inside_body |= shapely.distance(_shape(bodies, i), corner_points) <= TOL_M
        inside_env |= shapely.distance(_shape(env.polygons, i), corner_points) <= TOL_M
        grown = _shape(bodies, i).buffer(float(env.margin_m[i]) - 1e-6, quad_segs=16)
        assert _shape(env.polygons, i).buffer(TOL_M).covers(grown), "margin not applied"
    assert inside_body.all(), f"{mode}: body corner outside the body polygon (sigma_p {sigma_p})"
    assert inside_env.all(), f"{mode}: body corner outside the envelope"
    rec = current()
    rec.count("cases by mode", mode)
    rec.count("true positions checked", mode, points.shape[0])


@pytest.mark.requirement("SR-PRED-1", kind="property", code=CODE)
@settings(max_examples=examples(40), deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_both_near_reversal_modes_are_predicted_and_cover_the_union(
    safecase_config: SafecaseConfig, seed: int
) -> None:
    """A near-reversal track gets exactly a STOP and a REVERSE row, and the REVERSE region
    contains the STOP one (stopping is also a way to start a reversal)."""
    config = safecase_config
    case = make_case(np.random.default_rng(seed), "reverse", config)
    result = predict(
        case.tracks,
        features_for(case.tracks, True),
        classification(case.tracks, "forklift_near_reversal", case.confidence),
        config.predict,
        config.classify.medium_confidence_min,
    )
    assert sorted(result.mode.tolist()) == [int(PredictionMode.STOP), int(PredictionMode.REVERSE)]
    assert result.near_reversal.all()
    stop = shapely.MultiPoint(result.reach_xy_m[result.mode == PredictionMode.STOP][0]).convex_hull
    rev = shapely.MultiPoint(
        result.reach_xy_m[result.mode == PredictionMode.REVERSE][0]
    ).convex_hull
    assert rev.buffer(TOL_M).covers(stop)
    env = EnvelopeBuilder.from_config(config).build(result, MODEL_CLASSES)
    top = float(EnvelopeBuilder.from_config(config).params.margins_m[2])
    assert (env.margin_m == top).all(), "near-reversal rows must carry the near-reversal margin"
    current().count("near-reversal tracks", "both modes predicted")


def _envelope_for(case: Case, config: SafecaseConfig, class_name: str | None, conf: float):  # type: ignore[no-untyped-def]
    tracks = case.tracks
    near = class_name == "forklift_near_reversal"
    result = predict(
        tracks,
        features_for(tracks, near),
        classification(tracks, class_name, conf),
        config.predict,
        config.classify.medium_confidence_min,
    )
    return result, EnvelopeBuilder.from_config(config).build(result, MODEL_CLASSES)


def _union(polygons: ConvexPolygons) -> shapely.Geometry:
    return shapely.union_all([_shape(polygons, i) for i in range(polygons.n)])


@pytest.mark.requirement("SR-PRED-3", kind="property", code=CODE)
@settings(max_examples=examples(100), deadline=None)
@given(
    mode=st.sampled_from(("cone", "stop", "footprint")),
    seed=st.integers(0, 2**32 - 1),
    conf=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)).map(sorted),
)
def test_envelope_never_shrinks_as_confidence_drops(
    safecase_config: SafecaseConfig, mode: str, seed: int, conf: list[float]
) -> None:
    """Lower confidence: a margin at least as large and an envelope that covers the other."""
    config = safecase_config
    case = make_case(np.random.default_rng(seed), mode, config)
    low_c, high_c = conf
    _, low = _envelope_for(case, config, case.class_name, low_c)
    _, high = _envelope_for(case, config, case.class_name, high_c)
    assert low.margin_m.min() >= high.margin_m.max()
    assert low.tier.min() >= high.tier.max()
    assert _union(low.polygons).buffer(1e-9).covers(_union(high.polygons))
    rec = current()
    rec.count("confidence pairs", f"tier {int(high.tier.max())} -> {int(low.tier.max())}")


@pytest.mark.requirement("SR-PRED-3", kind="property", code=["safety/geometry/envelopes.py"])
@settings(max_examples=examples(100), deadline=None)
@given(
    conf=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=30),
    flags=st.lists(st.booleans(), min_size=30, max_size=30),
    margins=st.tuples(st.floats(0.0, 3.0), st.floats(0.0, 3.0), st.floats(0.0, 3.0)).map(sorted),
)
def test_envelope_margins_are_the_stopping_models(
    safecase_config: SafecaseConfig, conf: list[float], flags: list[bool], margins: list[float]
) -> None:
    """The envelope's margin is ``StoppingParams.margin_for`` (the proved function), whatever the
    configured tiers: change them and the envelopes follow."""
    from pipeline.config import overridden
    from safety.model.stopping import StoppingParams

    config = overridden(
        safecase_config,
        {
            "stopping": {
                "margin_high_m": margins[0],
                "margin_medium_m": margins[1],
                "margin_near_reversal_m": margins[2],
            }
        },
    )
    builder = EnvelopeBuilder.from_config(config)
    c = np.array(conf)
    f = np.array(flags[: len(conf)])
    margin, tier = builder.margins(c, f)
    expected = np.asarray(StoppingParams.from_config(config).margin_for(c, f), dtype=np.float64)
    assert np.array_equal(margin, np.broadcast_to(expected, c.shape))
    assert np.array_equal(margin, np.asarray(margins)[tier])


@pytest.mark.requirement("SR-PRED-3", kind="property", code=CODE)
@settings(max_examples=examples(60), deadline=None)
@given(mode=st.sampled_from(("cone", "stop", "footprint")), seed=st.integers(0, 2**32 - 1))
def test_unscored_tracks_get_the_most_cautious_envelope(
    safecase_config: SafecaseConfig, mode: str, seed: int
) -> None:
    """The fallback for a track the classifier cannot score: its region contains every mode's
    region for that track, with the largest margin and the worst closing speed."""
    config = safecase_config
    case = make_case(np.random.default_rng(seed), mode, config)
    fallback_pred, fallback = _envelope_for(case, config, None, 0.0)
    assert fallback_pred.mode.tolist() == [int(PredictionMode.UNKNOWN)]
    params = EnvelopeBuilder.from_config(config).params
    assert fallback.closing_speed_mps[0] == float(params.worst_closing_speed_mps)
    assert fallback.margin_m[0] == max(float(m) for m in params.margins_m)
    region = shapely.MultiPoint(fallback_pred.reach_xy_m[0]).convex_hull.buffer(1e-9)
    for name in ("forklift_moving", "forklift_near_reversal", "static", "person"):
        pred, env = _envelope_for(case, config, name, 0.99)
        for i in range(pred.n):
            assert region.covers(shapely.MultiPoint(pred.reach_xy_m[i]).convex_hull), name
        assert _shape(fallback.polygons, 0).buffer(1e-9).covers(_union(env.polygons)), name
    current().count("fallback cases", mode)
