"""Where may each tracked object be within the horizon? (SR-PRED-1)

Per track, from its filtered state (position ``p``, velocity ``v`` and the velocity's
covariance), its class and confidence (:class:`~pipeline.types.Classification`) and its
features, over the horizon ``H`` (``predict.horizon_s``, 1.5 s):

* speed bound ``s = |v| + k sigma_v`` (``k`` = ``predict.velocity_sigmas``, ``sigma_v`` the
  largest standard deviation of the velocity estimate);
* **moving** classes (forklift moving, pallet jack, person, vehicle): the reference
  point stays in the sector of radius ``s H`` about the velocity's direction with half-angle
  ``cone + asin(k sigma_v / |v|)`` (the source's +/-15 deg heading change plus the heading's
  own uncertainty); past 90 deg the sector becomes the disc of radius ``s H``. If the object
  keeps its speed at most ``s`` and its direction of travel inside that cone, its displacement
  (an integral of velocities in a convex cone, each at most ``s``) lies in the sector;
* **near reversal** (the class, or a forklift class whose kinematics say so: the
  ``is_near_reversal`` feature, or slower than ``predict.near_reversal_speed_mps`` having moved
  within ``predict.near_reversal_memory_s``, :func:`near_reversal_flags`):
  two modes about the *last confirmed heading* ``h`` (the direction of the track's centroid
  history when it spans at least ``predict.heading_min_travel_m``, else the velocity's
  direction when the speed is certain, else unknown): STOP, the sector of radius ``s H`` about
  ``h``; REVERSE, that sector plus (Minkowski sum) the sector of radius ``r H`` about ``-h``
  (``r`` = ``predict.reversal_speed_mps``, 0.6 m/s): carry on forwards, stop, back up at most
  at ``r``. With ``h`` unknown both become discs;
* **along the body axis** (``predict.heading_source = "track"``, :mod:`pipeline.predict_axis`):
  a vehicle whose motion gives no direction (a cone row whose half-angle reaches 90 deg, a
  near-reversal row whose confirmed heading is unknown) that has a track heading ``a``
  (:class:`~pipeline.track.heading.TrackHeadings`) and cannot be a person is predicted along
  its body axis either way instead of in a disc: a cone row and STOP, the hull of the sectors of
  radius ``s H`` and half-angle ``cone`` about ``a`` and ``a + pi``; REVERSE, that hull plus
  (Minkowski sum) the hull of the sectors of radius ``r H`` about both (a reversal either way).
  ``heading_rad`` is then ``a``, one of the axis's two directions;
* **stationary and static** classes (stationary forklift, cart, static structure): the
  footprint, i.e. the reference point itself;
* **unscored or low confidence** (confidence below ``classify.medium_confidence_min``): any
  direction, the disc of radius ``(s + r) H``, which holds every region above.

Whatever the mode, every row says whether the track may be a person (:func:`person_compatible`):
the envelopes then give it at least the person's closing speed (SR-CLS-8).

Every track's body is a disc about its reference point: half the diagonal of its box, at
least ``predict.min_body_radius_m``, plus ``k`` standard deviations of its position estimate.
Arcs are drawn as circumscribed polygons (:func:`sector_points`), so hulls of the points
returned contain the exact regions. Dormant tracks (not observed for several cycles) get no
prediction. Margins are added by :mod:`safety.geometry.envelopes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.classify.model import FORKLIFT_CLASSES, NEAR_REVERSAL_CLASS, STILL_CLASSES
from pipeline.config import PredictSection
from pipeline.constructive import minkowski, sector_points
from pipeline.features import feature_index
from pipeline.predict_axis import axis_points, body_axes
from pipeline.roles import HeadingRows
from pipeline.track.kalman import largest_std
from pipeline.types import (
    BoolArray,
    Classification,
    FloatArray,
    PredictionMode,
    Predictions,
    TrackFeatures,
    Tracks,
    TrackStatus,
)

__all__ = [
    "KinematicPredictor",
    "confirmed_heading_rad",
    "near_reversal_flags",
    "person_compatible",
    "predict",
    "track_modes",
]

_NEAR_REVERSAL_FEATURE = feature_index("is_near_reversal")
_SPEED_FEATURE = feature_index("velocity_magnitude_mps")
_SINCE_MOVING_FEATURE = feature_index("time_since_moving_s")
_WIDTH_FEATURE = feature_index("bbox_width_m")
_LENGTH_FEATURE = feature_index("bbox_length_m")


def near_reversal_flags(features: TrackFeatures, predict: PredictSection) -> BoolArray:
    """Per track: do its kinematics say near reversal, whatever state the classifier gave?

    True with the ``is_near_reversal`` feature, or when the track is slower than
    ``near_reversal_speed_mps`` and its history was moving within ``near_reversal_memory_s``
    (the simulator's label rule seen from behind: a truck that has just stopped). Applied to
    forklift classes only (:func:`track_modes`); on the held-out rows the second clause gives
    67 more near-reversal rows the 1.0 m tier (docs/findings/classification.md). SR-PRED-3.
    """
    v = features.values
    # NaN (never moving in the history) compares False: no flag.
    recent = (v[:, _SPEED_FEATURE] < predict.near_reversal_speed_mps) & (
        v[:, _SINCE_MOVING_FEATURE] <= predict.near_reversal_memory_s
    )
    flags: BoolArray = (v[:, _NEAR_REVERSAL_FEATURE] > 0.5) | recent
    return flags


def person_compatible(features: TrackFeatures, predict: PredictSection) -> BoolArray:
    """Per track: may it be a person, whatever class the classifier gave it? (SR-CLS-8)

    True unless the box of the track's cluster is longer or wider than
    ``predict.person_max_extent_m``: a larger cluster is not a person alone (the clusters at
    the labelled legs of the leg_tracker bags are at most 0.43 m long in 99 % of scans, the
    simulator's people at most 0.83 m; docs/findings/classification.md). A track without a box
    (NaN) is compatible. Nothing else measured on a track excludes a person: a standing person
    is slow, small and still until it walks, so neither a slow speed nor a long still history
    lowers the closing speed of a person-sized track.
    """
    v = features.values
    bound = predict.person_max_extent_m
    # NaN compares False: a track without a box stays compatible.
    larger = (v[:, _WIDTH_FEATURE] > bound) | (v[:, _LENGTH_FEATURE] > bound)
    compatible: BoolArray = ~larger
    return compatible


def confirmed_heading_rad(
    tracks: Tracks, speed: FloatArray, sigma_v: FloatArray, section: PredictSection
) -> FloatArray:
    """Last confirmed heading per track [rad]; NaN when not known (module docstring)."""
    hist = tracks.history_xy_m
    valid = ~np.isnan(hist[:, :, 0])
    n = tracks.n
    first = np.argmax(valid, axis=1)
    rows = np.arange(n)
    newest = hist[:, -1, :]  # the history is newest-last, padded at the front
    oldest = hist[rows, first, :]
    dx, dy = newest[:, 0] - oldest[:, 0], newest[:, 1] - oldest[:, 1]
    travel = np.hypot(dx, dy)
    k = section.velocity_sigmas
    from_history = valid.any(axis=1) & (travel >= section.heading_min_travel_m)
    from_velocity = ~from_history & (speed > k * sigma_v) & (speed > 0.0)
    vx, vy = tracks.state[:, 2], tracks.state[:, 3]
    heading = np.full(n, np.nan)
    heading[from_history] = np.arctan2(dy[from_history], dx[from_history])
    heading[from_velocity] = np.arctan2(vy[from_velocity], vx[from_velocity])
    return heading


def track_modes(
    classification: Classification, near_reversal_feature: BoolArray, medium_confidence_min: float
) -> tuple[BoolArray, BoolArray, BoolArray, BoolArray]:
    """Per track: (near_reversal, footprint, cone, unknown) masks, exactly one of them true.

    Unknown: unscored or confidence below ``medium_confidence_min``. Near reversal: the
    near-reversal class, or any forklift class flagged by :func:`near_reversal_flags`.
    Footprint: a stationary or static class. Cone: every other (moving) class.
    """
    names = classification.class_names
    index = classification.class_index

    def member(group: frozenset[str]) -> BoolArray:
        codes = [i for i, name in enumerate(names) if name in group]
        found: BoolArray = np.isin(index, codes) & (index >= 0)
        return found

    trusted = (index >= 0) & (classification.confidence >= medium_confidence_min)
    near = trusted & (
        member(frozenset({NEAR_REVERSAL_CLASS}))
        | (member(FORKLIFT_CLASSES) & near_reversal_feature)
    )
    still = trusted & ~near & member(STILL_CLASSES)
    cone = trusted & ~near & ~still
    return near, still, cone, ~trusted


def predict(
    tracks: Tracks,
    features: TrackFeatures,
    classification: Classification,
    section: PredictSection,
    medium_confidence_min: float,
    headings: HeadingRows | None = None,
) -> Predictions:
    """Prediction rows for every non-dormant track (module docstring; SR-PRED-1, SR-PRED-4).

    ``features``, ``classification`` and ``headings`` (when given) must come from ``tracks``
    (same rows, same order); ``medium_confidence_min`` (``classify.medium_confidence_min``) is
    the confidence below which a track's class is not trusted and it is predicted as unknown.
    ``headings`` orient vehicles along their body axis under ``heading_source = "track"``.
    """
    if not (
        np.array_equal(features.track_id, tracks.track_id)
        and np.array_equal(classification.track_id, tracks.track_id)
        and (headings is None or np.array_equal(headings.track_id, tracks.track_id))
    ):
        raise ValueError(
            "predict: tracks, features, classification and headings must list the same tracks"
        )
    pc = section
    horizon, k = pc.horizon_s, pc.velocity_sigmas
    live = tracks.status != int(TrackStatus.DORMANT)
    px, py = tracks.state[:, 0], tracks.state[:, 1]
    vx, vy = tracks.state[:, 2], tracks.state[:, 3]
    speed = np.hypot(vx, vy)
    sigma_v = largest_std(tracks.covariance[:, 2:, 2:])
    sigma_p = largest_std(tracks.covariance[:, :2, :2])
    bound = speed + k * sigma_v
    half_diag = 0.5 * np.hypot(np.nan_to_num(tracks.width_m), np.nan_to_num(tracks.length_m))
    body = np.maximum(half_diag, pc.min_body_radius_m) + k * sigma_p

    confidence = classification.confidence
    flagged = near_reversal_flags(features, pc)
    near, footprint, cone, unknown = track_modes(classification, flagged, medium_confidence_min)

    heading_v = np.arctan2(vy, vx)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        spread = np.where(
            speed > k * sigma_v, np.arcsin(np.minimum(k * sigma_v / speed, 1.0)), np.pi
        )
    cone_half = math.radians(pc.cone_half_angle_deg)
    confirmed = confirmed_heading_rad(tracks, speed, sigma_v, pc)
    compatible = person_compatible(features, pc)
    axes = body_axes(headings, compatible, pc)

    # One entry per (track, mode); near-reversal tracks get two.
    parts: list[tuple[BoolArray, PredictionMode]] = [
        (live & footprint, PredictionMode.FOOTPRINT),
        (live & cone, PredictionMode.CONE),
        (live & near, PredictionMode.STOP),
        (live & near, PredictionMode.REVERSE),
        (live & unknown, PredictionMode.UNKNOWN),
    ]
    order = np.concatenate([np.flatnonzero(mask) for mask, _ in parts])
    modes = np.concatenate(
        [np.full(int(mask.sum()), int(mode), dtype=np.int64) for mask, mode in parts]
    )
    # Sort by track, then mode, so rows of one track are adjacent.
    perm = np.lexsort((modes, order))
    rows, modes = order[perm], modes[perm]

    arc = math.radians(pc.arc_step_deg)
    sides = pc.disc_sides
    x, y = px[rows], py[rows]
    is_mode = {m: modes == int(m) for m in PredictionMode}
    heading = np.full(rows.shape[0], np.nan)
    heading[is_mode[PredictionMode.CONE]] = heading_v[rows][is_mode[PredictionMode.CONE]]
    two_mode = is_mode[PredictionMode.STOP] | is_mode[PredictionMode.REVERSE]
    heading[two_mode] = confirmed[rows][two_mode]
    half = np.where(
        is_mode[PredictionMode.CONE], cone_half + spread[rows], np.where(two_mode, cone_half, np.pi)
    )
    # Rows whose motion gives no direction and whose body axis is used instead.
    axis = np.isfinite(axes[rows]) & (
        (is_mode[PredictionMode.CONE] & (half >= 0.5 * math.pi)) | (two_mode & np.isnan(heading))
    )
    heading[axis] = axes[rows][axis]
    # The operating domain's speed limit bounds every object, however unsure its filter is
    # (a new track's velocity variance alone would reach several metres per second); an
    # unknown track may also be starting a reversal, so it keeps that on top.
    reach_speed = np.minimum(bound[rows], pc.max_object_speed_mps)
    reach_speed[is_mode[PredictionMode.FOOTPRINT]] = 0.0
    reach_speed[is_mode[PredictionMode.UNKNOWN]] += pc.reversal_speed_mps
    main = sector_points(x, y, heading, half, reach_speed * horizon, arc, sides)
    reverse = is_mode[PredictionMode.REVERSE]
    back_m = pc.reversal_speed_mps * horizon
    regions: list[tuple[BoolArray, FloatArray]] = []
    plain = reverse & ~axis
    if plain.any():
        r = int(plain.sum())
        back = sector_points(
            np.zeros(r),
            np.zeros(r),
            heading[plain] + math.pi,
            np.full(r, cone_half),
            np.full(r, back_m),
            arc,
            sides,
        )
        regions.append((plain, minkowski(main[plain], back)))
    if axis.any():
        along = axis_points(
            x[axis], y[axis], heading[axis], cone_half, reach_speed[axis] * horizon, arc, sides
        )
        both = reverse[axis]
        regions.append((axis & ~reverse, along[~both]))
        if both.any():
            r = int(both.sum())
            zero = np.zeros(r)
            either = axis_points(
                zero, zero, heading[axis][both], cone_half, np.full(r, back_m), arc, sides
            )
            regions.append((axis & reverse, minkowski(along[both], either)))
    reach = _overlay(main, regions)
    return Predictions(
        stamp_s=tracks.stamp_s,
        horizon_s=horizon,
        track_id=tracks.track_id[rows],
        mode=modes,
        class_index=classification.class_index[rows],
        confidence=confidence[rows],
        near_reversal=two_mode,
        person_compatible=compatible[rows],
        speed_mps=np.where(reverse, np.maximum(reach_speed, pc.reversal_speed_mps), reach_speed),
        heading_rad=heading,
        body_radius_m=body[rows],
        reach_xy_m=reach,
    )


def _overlay(base: FloatArray, regions: list[tuple[BoolArray, FloatArray]]) -> FloatArray:
    """``base`` (M, P, 2) with the rows of each mask replaced by its polygons, every row padded
    to the widest by repeating its first vertex (a repeated vertex leaves a polygon as it is)."""
    if not regions:
        return base
    width = max([base.shape[1]] + [poly.shape[1] for _, poly in regions])
    out = np.repeat(base[:, :1], width, axis=1)
    out[:, : base.shape[1]] = base
    for mask, poly in regions:
        out[mask] = np.concatenate(
            [poly, np.repeat(poly[:, :1], width - poly.shape[1], axis=1)], axis=1
        )
    return out


@dataclass(frozen=True)
class KinematicPredictor:
    """The prediction role's default: :func:`predict` with the ``predict`` section and the
    classifier's medium-confidence threshold."""

    config: PredictSection
    medium_confidence_min: float

    def predict(
        self,
        tracks: Tracks,
        features: TrackFeatures,
        classification: Classification,
        headings: HeadingRows | None = None,
    ) -> Predictions:
        """Prediction rows for every non-dormant track."""
        return predict(
            tracks,
            features,
            classification,
            self.config,
            self.medium_confidence_min,
            headings,
        )
