"""Direction-aware closing speeds for the governor's rows (SR-AVL-5).

The stopping model's obstacle speed ``V`` is how fast the obstacle closes in along the robot's
path (:mod:`safety.model.stopping`). For a moving object predicted in a cone (prediction mode
CONE) that is not a person, the envelope's closing speed (its speed bound ``s``, whatever its
direction) is replaced by :func:`safety.model.stopping.directed_closing_mps`: the largest
component of any velocity the prediction allows along the path towards the robot, i.e. along
minus the path's direction where the object's zone first meets the path (at the path's end for
a zone off the path). A forklift driving away along the path closes at 0; one coming the other
way at its full speed bound.

The cone is read off the prediction's own reach region: its heading (``heading_rad``) and the
largest angle between that heading and any vertex of the region seen from the track's position
(the sector's apex), so the half-angle covers the predictor's cone plus the heading's own
uncertainty exactly as the region was drawn. People, and every track that may be a person
(``Predictions.person_compatible``, SR-CLS-8), keep the ISO 13855 walking speed (they turn on
the spot); near-reversal, unknown and still rows keep their class speeds.

This is an allowance on top of what already holds the object: the zone (reach region grown by
the body) contains the object for the whole horizon (SR-PRED-1), and the horizon covers the
stopping time (SR-STOP-3). z3 proves that no velocity in the cone has a larger component and
that the directed speed never exceeds the undirected one (properties/test_availability_closing.py).
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.classify.model import PERSON_CLASS
from pipeline.types import BoolArray, Envelopes, FloatArray, PredictionMode, Predictions, Tracks
from safety.geometry.path import PathAhead
from safety.model.stopping import StoppingParams, directed_closing_mps

__all__ = ["ANGLE_GUARD_RAD", "cone_half_angles_rad", "directed_closing", "directed_rows"]

ANGLE_GUARD_RAD = 1e-9
"""Added to every cone half-angle read off a polygon: float rounding stays on the safe side."""
# Reach vertices within this distance of the apex carry no direction [m].
_APEX_M = 1e-9


def directed_rows(pred: Predictions, class_names: tuple[str, ...]) -> BoolArray:
    """Rows whose closing speed is direction-aware: CONE mode, neither classified nor
    compatible with a person (SR-CLS-8), a heading."""
    person = class_names.index(PERSON_CLASS) if PERSON_CLASS in class_names else -2
    rows: BoolArray = (
        (pred.mode == int(PredictionMode.CONE))
        & (pred.class_index != person)
        & ~pred.person_compatible
        & np.isfinite(pred.heading_rad)
    )
    return rows


def cone_half_angles_rad(
    reach_xy_m: FloatArray, apex_xy_m: FloatArray, heading_rad: FloatArray
) -> FloatArray:
    """Per row, the largest angle [rad] between ``heading_rad`` and any vertex of the reach
    region ``reach_xy_m`` (m, P, 2) seen from ``apex_xy_m`` (m, 2), plus
    :data:`ANGLE_GUARD_RAD`; pi from 90 deg on (a sector of 90 deg or more is drawn as the disc
    about the apex, :func:`pipeline.constructive.sector_points`)."""
    rel = reach_xy_m - apex_xy_m[:, None, :]
    away = np.hypot(rel[..., 0], rel[..., 1]) > _APEX_M
    angle = np.arctan2(rel[..., 1], rel[..., 0]) - heading_rad[:, None]
    off = np.abs(np.mod(angle + math.pi, 2.0 * math.pi) - math.pi)
    read = np.max(np.where(away, off, 0.0), axis=1) + ANGLE_GUARD_RAD
    # From 90 deg on the predictor draws the disc about the apex: every direction.
    half: FloatArray = np.where(read < 0.5 * math.pi, read, math.pi)
    return half


def directed_closing(
    env: Envelopes,
    pred: Predictions,
    tracks: Tracks,
    class_names: tuple[str, ...],
    path: PathAhead,
    free_m: FloatArray,
    params: StoppingParams,
) -> FloatArray:
    """The envelopes' closing speeds [m/s], direction-aware where it applies (module docstring).

    ``pred`` and ``tracks`` are in the tracking frame with ``path``; ``free_m`` is each row's
    free distance along ``path`` (the lookahead for a zone off the path).
    """
    closing: FloatArray = env.closing_speed_mps.copy()
    rows = directed_rows(pred, class_names)
    if not rows.any():
        return closing
    apex = tracks.state[np.searchsorted(tracks.track_id, pred.track_id[rows]), :2]
    half = cone_half_angles_rad(pred.reach_xy_m[rows], apex, pred.heading_rad[rows])
    at = np.clip(np.searchsorted(path.arc_m, free_m[rows]), 0, path.arc_m.shape[0] - 1)
    towards = path.theta_rad[at] + math.pi  # minus the path's direction there
    offset = towards - pred.heading_rad[rows]
    closing[rows] = directed_closing_mps(
        pred.speed_mps[rows],
        np.cos(offset),
        np.abs(np.sin(offset)),
        np.cos(half),
        np.sin(half),
        float(params.static_speed_mps),
    )
    return closing
