"""Direction-aware closing speed row by row: which rows, which cone, which path direction
(SR-AVL-5, SR-CLS-8).

The mutation campaign (SR-EVD-5; docs/findings/mutation.md) showed these unwatched: the
properties check only that the directed speed never exceeds the undirected one, so a runtime
that never lowered anything, read the path's direction at the wrong sample, or made a person
row direction-aware passed them. Here: the row mask field by field, the cone read off a region
at its limits (a vertex along the x axis, one at the apex, exactly 90 degrees), and the speed a
forklift is given when it drives away from the robot, towards it, and across a turning path.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipeline.classify.model import MODEL_CLASSES, PERSON_CLASS
from pipeline.config import default_config
from pipeline.predict import predict
from pipeline.types import Envelopes, PredictionMode, Predictions, Tracks
from properties.prediction_cases import classification, features_for, tracks_of
from safety.closing import ANGLE_GUARD_RAD, cone_half_angles_rad, directed_closing, directed_rows
from safety.geometry.envelopes import EnvelopeBuilder
from safety.geometry.path import PathAhead
from safety.model.stopping import StoppingParams

CLOSING = ["safety/closing.py"]
CONFIG = default_config()
PARAMS = StoppingParams.from_config(CONFIG)


def _forklift(heading_rad: float) -> tuple[Tracks, Predictions, Envelopes]:
    """A forklift-sized track 4 m ahead driving at 1.2 m/s along ``heading_rad``, predicted in a
    cone, and its envelopes."""
    u = np.array([math.cos(heading_rad), math.sin(heading_rad)])
    xy = np.array([4.0, 0.5])
    hist = xy[None, :] - u[None, :] * np.linspace(1.5, 0.0, 15)[:, None]
    tracks = tracks_of(xy, 1.2 * u, 0.02, 0.05, 1.2, 2.6, hist)
    klass = classification(tracks, "forklift_moving", 0.95)
    pred = predict(
        tracks,
        features_for(tracks, False),
        klass,
        CONFIG.predict,
        CONFIG.classify.medium_confidence_min,
    )
    env = EnvelopeBuilder(CONFIG.predict, PARAMS).build(pred, klass.class_names)
    return tracks, pred, env


def _turning_path(first_rad: float) -> PathAhead:
    """Three samples 1 m apart whose direction turns by 90 degrees at each."""
    theta = first_rad + np.array([0.0, 0.5 * math.pi, math.pi])
    return PathAhead(
        arc_m=np.array([0.0, 1.0, 2.0]),
        x_m=np.array([0.0, 1.0, 1.0]),
        y_m=np.array([0.0, 0.0, 1.0]),
        theta_rad=theta,
    )


@pytest.mark.requirement("SR-CLS-8", kind="example", code=CLOSING)
def test_only_cone_rows_that_cannot_be_a_person_are_direction_aware() -> None:
    """Row by row: a cone row of a forklift qualifies; the same row in another mode, classified
    person, compatible with a person or without a heading does not; with a class list that has
    no person, a row of any class index qualifies (no index is taken for the person)."""
    _, pred, _ = _forklift(0.0)
    assert pred.n == 1
    assert pred.mode[0] == int(PredictionMode.CONE)
    person = MODEL_CLASSES.index(PERSON_CLASS)
    forklift = int(pred.class_index[0])
    n = 6
    rows = replace(
        pred,
        track_id=np.arange(n),
        mode=np.array(
            [
                int(PredictionMode.CONE),
                int(PredictionMode.FOOTPRINT),
                int(PredictionMode.CONE),
                int(PredictionMode.CONE),
                int(PredictionMode.CONE),
                int(PredictionMode.UNKNOWN),
            ]
        ),
        class_index=np.array([forklift, forklift, person, forklift, forklift, forklift]),
        confidence=np.repeat(pred.confidence, n),
        near_reversal=np.zeros(n, dtype=bool),
        person_compatible=np.array([False, False, False, True, False, False]),
        speed_mps=np.repeat(pred.speed_mps, n),
        heading_rad=np.array([0.0, 0.0, 0.0, 0.0, math.nan, 0.0]),
        body_radius_m=np.repeat(pred.body_radius_m, n),
        reach_xy_m=np.repeat(pred.reach_xy_m, n, axis=0),
    )
    assert directed_rows(rows, MODEL_CLASSES).tolist() == [True, False, False, False, False, False]
    no_person = tuple(c for c in MODEL_CLASSES if c != PERSON_CLASS)
    for index in (-1, 0, 2, len(no_person) - 1):
        one = replace(rows, class_index=np.full(n, index))
        assert directed_rows(one, no_person).tolist() == [True, False, True, False, False, False]


@pytest.mark.requirement("SR-AVL-5", kind="example", code=CLOSING)
def test_the_cone_reads_every_vertex_away_from_the_apex() -> None:
    """A vertex straight along +x from the apex counts (its y offset is 0: the distance must
    use both coordinates); a vertex within ``_APEX_M`` of the apex carries no direction; a
    region 90 degrees off the heading, once guarded, is the disc (pi), not a 90 degree cone."""
    apex = np.zeros((1, 2))
    ahead = np.array([[[0.0, 1.0], [0.0, 2.0], [1.0, 0.0]]])
    assert cone_half_angles_rad(ahead, apex, np.array([0.5 * math.pi]))[0] == math.pi
    at_apex = np.array([[[0.0, 1.0], [0.0, 2.0], [1e-9, 0.0]]])
    read = cone_half_angles_rad(at_apex, apex, np.array([0.5 * math.pi]))[0]
    assert read == ANGLE_GUARD_RAD
    # Heading 1e-9 rad off +x: the +y vertex is 90 deg less 1e-9 off, plus the guard: 90 deg.
    square = np.array([[[0.0, 1.0], [0.0, 2.0], [0.0, 0.5]]])
    assert cone_half_angles_rad(square, apex, np.array([1e-9]))[0] == math.pi
    assert cone_half_angles_rad(square, apex, np.array([1e-3]))[0] < 0.5 * math.pi


@pytest.mark.requirement("SR-AVL-5", kind="example", code=CLOSING)
def test_a_forklift_driving_away_along_the_path_closes_at_the_static_speed() -> None:
    """The runtime lowers the speed: driving away along the path, the forklift closes in at the
    static speed only; coming straight down it, at its whole speed bound."""
    tracks, pred, env = _forklift(0.3)
    assert directed_rows(pred, MODEL_CLASSES).tolist() == [True]
    assert env.closing_speed_mps[0] > 1.0
    free = np.array([1.0])
    away = PathAhead.straight((0.0, 0.0, 0.3), 6.0, 0.1)
    closing = directed_closing(env, pred, tracks, MODEL_CLASSES, away, free, PARAMS)
    assert closing.tolist() == [PARAMS.static_speed_mps]
    towards = PathAhead.straight((0.0, 0.0, 0.3 + math.pi), 6.0, 0.1)
    closing = directed_closing(env, pred, tracks, MODEL_CLASSES, towards, free, PARAMS)
    assert closing[0] == pytest.approx(pred.speed_mps[0], abs=1e-12)


@pytest.mark.requirement("SR-AVL-5", kind="example", code=CLOSING)
@pytest.mark.parametrize(("free_m", "index"), [(0.0, 0), (0.5, 1), (1.0, 1), (2.0, 2), (9.0, 2)])
def test_the_path_direction_is_read_where_the_zone_meets_the_path(
    free_m: float, index: int
) -> None:
    """On a path turning 90 degrees at every sample, the direction is the first sample at or
    beyond the free distance, the last one for a zone off the path's end: the forklift drives
    along that sample's direction (away), so only that reading gives the static speed."""
    path = _turning_path(-0.4)
    for sample in range(3):
        heading = float(path.theta_rad[sample])
        tracks, pred, env = _forklift(heading)
        closing = directed_closing(
            env, pred, tracks, MODEL_CLASSES, path, np.array([free_m]), PARAMS
        )
        if sample == index:
            assert closing.tolist() == [PARAMS.static_speed_mps], (free_m, sample)
        else:
            assert closing[0] > PARAMS.static_speed_mps + 0.2, (free_m, sample, closing)
