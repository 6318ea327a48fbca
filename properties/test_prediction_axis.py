"""Prediction along a vehicle's body axis (``predict.heading_source = "track"``, SR-PRED-4).

A synthetic track whose motion gives no direction (a cone row whose spread reaches 90 deg, or a
near-reversal row without a confirmed heading) and whose track heading is known. Sampled true
motions move along the body axis either way (switching at will), turn within the cone and keep
the speed bound; for REVERSE, a first phase at the speed bound and a second at the reversal
speed, each either way along the axis. GEOS (shapely) judges containment in the reach hull.
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
from pipeline.config import PredictSection, SafecaseConfig, overridden
from pipeline.predict import predict
from pipeline.track.heading import TrackHeadings
from pipeline.types import PredictionMode, Predictions, Tracks
from properties.prediction_cases import classification, features_for, tracks_of

CODE = ["pipeline/predict.py", "pipeline/predict_axis.py"]
TOL_M = 1e-9
N_PATHS = 200
N_STEPS = 30


def _track(
    rng: np.random.Generator, pc: PredictSection, ratio: float, size_m: float
) -> tuple[Tracks, float]:
    """A one-track snapshot whose speed is ``ratio`` times ``k sigma_v`` (at most about 1: no
    direction), a history that never moved, a ``size_m`` box; and its speed bound [m/s]."""
    sigma_v = float(rng.uniform(0.02, 0.5))
    speed = ratio * pc.velocity_sigmas * sigma_v
    course = float(rng.uniform(-math.pi, math.pi))
    xy = rng.uniform(-20.0, 20.0, 2)
    v = speed * np.array([math.cos(course), math.sin(course)])
    history = xy[None, :] + rng.normal(0.0, 0.01, (10, 2))
    tracks = tracks_of(xy, v, float(rng.uniform(0.01, 0.2)), sigma_v, size_m, size_m, history)
    bound = min(speed + pc.velocity_sigmas * sigma_v, pc.max_object_speed_mps)
    return tracks, bound


def _rows(
    tracks: Tracks, pc: PredictSection, medium: float, class_name: str, axis_rad: float
) -> Predictions:
    headings = TrackHeadings(tracks.track_id, np.array([axis_rad]), np.array([False]))
    near = class_name == "forklift_near_reversal"
    return predict(
        tracks,
        features_for(tracks, near),
        classification(tracks, class_name, 0.99),
        pc,
        medium,
        headings,
    )


def _along_axis(
    rng: np.random.Generator, axis_rad: float, cone_rad: float, speed_mps: float, seconds: float
) -> np.ndarray:
    """(N_PATHS, N_STEPS, 2) displacements at the end of each step: each step's velocity along
    ``axis`` or its opposite (chosen per step), turned within the cone, at most ``speed_mps``;
    the first paths take the extremes (full speed, the cone's edge, one way throughout)."""
    dt = seconds / N_STEPS
    way = rng.integers(0, 2, (N_PATHS, N_STEPS)) * math.pi
    turn = rng.uniform(-cone_rad, cone_rad, (N_PATHS, N_STEPS))
    speed = rng.uniform(0.0, speed_mps, (N_PATHS, N_STEPS))
    edge = np.array([-cone_rad, cone_rad, 0.0, -cone_rad, cone_rad, 0.0])
    way[:6] = np.array([0.0, 0.0, 0.0, math.pi, math.pi, math.pi])[:, None]
    turn[:6] = edge[:, None]
    speed[:6] = speed_mps
    angle = axis_rad + way + turn
    step = np.stack([np.cos(angle), np.sin(angle)], axis=-1) * (speed * dt)[..., None]
    out: np.ndarray = np.cumsum(step, axis=1)
    return out


def _hull(pred: Predictions, i: int) -> shapely.Geometry:
    return shapely.MultiPoint(pred.reach_xy_m[i]).convex_hull


@st.composite
def _cases(draw: st.DrawFn) -> tuple[int, str, float, float]:
    seed = draw(st.integers(0, 2**32 - 1))
    class_name = draw(st.sampled_from(("vehicle", "forklift_moving", "forklift_near_reversal")))
    # A cone row's spread reaches 90 deg up to 1 / sin(75 deg); a near-reversal row's velocity
    # gives its confirmed heading from 1 on.
    top = 0.99 if class_name == "forklift_near_reversal" else 1.03
    ratio = draw(st.floats(0.0, top))
    axis = draw(st.floats(-math.pi, math.pi, exclude_max=True))
    return seed, class_name, ratio, axis


@pytest.mark.requirement("SR-PRED-4", kind="property", code=CODE)
@settings(max_examples=examples(80), deadline=None)
@given(case=_cases(), size=st.floats(1.05, 6.0))
def test_motion_along_the_axis_stays_inside_the_reach(
    safecase_config: SafecaseConfig, case: tuple[int, str, float, float], size: float
) -> None:
    """Every sampled position of an object moving along its axis (module docstring) lies in the
    hull of its row's reach; REVERSE also holds a reversal either way at the reversal speed."""
    seed, class_name, ratio, axis = case
    config = overridden(safecase_config, {"predict": {"heading_source": "track"}})
    pc = config.predict
    rng = np.random.default_rng(seed)
    tracks, bound = _track(rng, pc, ratio, size)
    pred = _rows(tracks, pc, config.classify.medium_confidence_min, class_name, axis)
    cone = math.radians(pc.cone_half_angle_deg)
    horizon = pc.horizon_s
    start = tracks.state[0, :2]
    assert np.isfinite(pred.heading_rad).all()
    assert np.allclose(pred.heading_rad, axis)
    for i in range(pred.n):
        mode = PredictionMode(int(pred.mode[i]))
        path = _along_axis(rng, axis, cone, bound, horizon)
        if mode == PredictionMode.REVERSE:
            # Stop anywhere in the first phase, then reverse either way at the reversal speed.
            cut = rng.integers(0, N_STEPS, N_PATHS)
            first = path[np.arange(N_PATHS), cut][:, None, :]
            second = _along_axis(rng, axis, cone, pc.reversal_speed_mps, horizon)
            path = np.concatenate([path, first + second], axis=1)
        xy = start + path.reshape(-1, 2)
        d = shapely.distance(_hull(pred, i), shapely.points(xy))
        assert d.max() <= TOL_M, f"{mode.name}: {d.max():.3g} m outside the axis reach"
        current().count("axis rows checked", mode.name)
        current().count("positions checked", mode.name, xy.shape[0])


@pytest.mark.requirement("SR-PRED-4", kind="property", code=CODE)
@settings(max_examples=examples(80), deadline=None)
@given(case=_cases(), size=st.floats(1.05, 6.0))
def test_the_axis_reach_is_never_larger_than_the_disc(
    safecase_config: SafecaseConfig, case: tuple[int, str, float, float], size: float
) -> None:
    """Row for row, the reach under "track" has a smaller area than the disc under "motion" and
    lies inside it, up to the difference of the two circumscriptions (an arc piece's outer
    vertex at ``R / cos(piece / 2)``, the disc polygon's edge at ``R``)."""
    seed, class_name, ratio, axis = case
    track_config = overridden(safecase_config, {"predict": {"heading_source": "track"}})
    medium = safecase_config.classify.medium_confidence_min
    tracks, _ = _track(np.random.default_rng(seed), safecase_config.predict, ratio, size)
    motion = _rows(tracks, safecase_config.predict, medium, class_name, axis)
    along = _rows(tracks, track_config.predict, medium, class_name, axis)
    assert np.array_equal(motion.mode, along.mode)
    assert np.array_equal(motion.speed_mps, along.speed_mps)
    assert np.array_equal(motion.body_radius_m, along.body_radius_m)
    assert np.isnan(motion.heading_rad[motion.mode != int(PredictionMode.CONE)]).all()
    slack = 1.0 / math.cos(0.5 * math.radians(safecase_config.predict.arc_step_deg)) - 1.0
    for i in range(motion.n):
        disc, axis_hull = _hull(motion, i), _hull(along, i)
        # The disc polygon's vertices lie at R / cos(pi / sides).
        far = float(np.hypot(*(motion.reach_xy_m[i] - tracks.state[0, :2]).T).max())
        radius = far * math.cos(math.pi / safecase_config.predict.disc_sides)
        assert axis_hull.area < disc.area
        assert disc.buffer(slack * radius + TOL_M).covers(axis_hull)
        current().count(
            "area ratio track / motion (percent, floor of 10)", _decile(axis_hull, disc)
        )


def _decile(small: shapely.Geometry, large: shapely.Geometry) -> str:
    return f"{10 * int(10 * small.area / large.area)}"


@pytest.mark.requirement("SR-PRED-4", kind="property", code=CODE)
@settings(max_examples=examples(60), deadline=None)
@given(
    case=_cases(),
    size=st.floats(0.1, 1.0),
    ratio=st.floats(1.1, 20.0),
    known=st.booleans(),
)
def test_rows_without_an_axis_are_predicted_as_under_motion(
    safecase_config: SafecaseConfig,
    case: tuple[int, str, float, float],
    size: float,
    ratio: float,
    known: bool,
) -> None:
    """Exactly today's rows for a track that may be a person (a box at most
    ``person_max_extent_m``), for one whose heading is unknown (NaN), and for one whose velocity
    gives a direction (speed well above ``k sigma_v``, a big box); and "motion" ignores the
    headings altogether."""
    seed, class_name, small_ratio, axis = case
    track_config = overridden(safecase_config, {"predict": {"heading_source": "track"}})
    pc, medium = safecase_config.predict, safecase_config.classify.medium_confidence_min
    rng = np.random.default_rng(seed)
    person, _ = _track(rng, pc, small_ratio, size)
    directed, _ = _track(rng, pc, ratio, 3.0)
    big, _ = _track(rng, pc, small_ratio, 3.0)
    heading = axis if known else math.nan
    both = (safecase_config, track_config)
    cases = [
        (person, heading, "person-compatible", both),
        (directed, heading, "velocity gives a direction", both),
        (big, heading, "source motion" if known else "heading unknown", both[: 2 - known]),
    ]
    for tracks, heading, label, configs in cases:
        today = predict(
            tracks,
            features_for(tracks, class_name == "forklift_near_reversal"),
            classification(tracks, class_name, 0.99),
            pc,
            medium,
        )
        for config in configs:
            again = _rows(tracks, config.predict, medium, class_name, heading)
            assert np.array_equal(again.reach_xy_m, today.reach_xy_m, equal_nan=True), label
            assert np.array_equal(again.heading_rad, today.heading_rad, equal_nan=True), label
        current().count("rows as under motion", label)


@pytest.mark.requirement("SR-PRED-4", kind="example", code=CODE)
def test_headings_of_other_tracks_are_refused(safecase_config: SafecaseConfig) -> None:
    """Headings must list the tracks' rows, like features and the classification."""
    tracks, _ = _track(np.random.default_rng(0), safecase_config.predict, 0.5, 3.0)
    wrong = TrackHeadings(tracks.track_id + 1, np.array([0.0]), np.array([False]))
    with pytest.raises(ValueError, match="same tracks"):
        predict(
            tracks,
            features_for(tracks, False),
            classification(tracks, "vehicle", 0.99),
            safecase_config.predict,
            safecase_config.classify.medium_confidence_min,
            wrong,
        )
