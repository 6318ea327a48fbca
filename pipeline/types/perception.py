"""Features, classes, predictions and envelopes (SR-CLS-*, SR-PRED-*)."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from pipeline.types.core import BoolArray, FloatArray, IntArray, freeze_fields
from pipeline.types.geometry import ConvexPolygons


@dataclass(frozen=True, slots=True)
class TrackFeatures:
    """The per-track feature rows of one cycle, struct of arrays (SR-CLS-2).

    ``values`` (N, F) holds one row per track of the :class:`Tracks` snapshot it came from (same
    order), columns in the order of ``pipeline.features.FEATURE_NAMES`` (units in those names);
    NaN marks a feature that could not be measured this cycle (e.g. the point density of a track
    that no cluster updated). ``status`` is the track's :class:`TrackStatus` code.
    """

    stamp_s: float
    track_id: IntArray
    status: IntArray
    values: FloatArray

    def __post_init__(self) -> None:
        freeze_fields(self, ("values",), np.float64)
        freeze_fields(self, ("track_id", "status"), np.int64)
        n = self.track_id.shape[0]
        if self.status.shape != (n,) or self.values.ndim != 2 or self.values.shape[0] != n:
            raise ValueError(
                f"TrackFeatures: status {self.status.shape} and values {self.values.shape} must "
                f"have {n} rows"
            )

    @property
    def n(self) -> int:
        """Number of tracks."""
        return int(self.track_id.shape[0])


@dataclass(frozen=True, slots=True)
class Classification:
    """Class probabilities of the tracks of one cycle (SR-CLS-1, SR-CLS-3).

    ``probability`` (N, C) over ``class_names``; ``class_index`` (N,) is the argmax, or -1 for a
    track the classifier did not score (tentative or dormant: too young or unseen), whose
    probabilities are NaN and ``confidence`` 0. ``confidence`` is the probability of the chosen
    class. ``model_sha256`` names the model file that produced it.
    """

    stamp_s: float
    track_id: IntArray
    class_index: IntArray
    probability: FloatArray
    confidence: FloatArray
    class_names: tuple[str, ...]
    model_sha256: str

    def __post_init__(self) -> None:
        freeze_fields(self, ("probability", "confidence"), np.float64)
        freeze_fields(self, ("track_id", "class_index"), np.int64)
        n, c = self.track_id.shape[0], len(self.class_names)
        if (
            self.class_index.shape != (n,)
            or self.confidence.shape != (n,)
            or self.probability.shape != (n, c)
        ):
            raise ValueError(
                f"Classification: class_index, confidence and probability must have {n} rows "
                f"(probability {c} columns)"
            )

    @property
    def n(self) -> int:
        """Number of tracks."""
        return int(self.track_id.shape[0])

    @property
    def scored(self) -> BoolArray:
        """Tracks the classifier scored."""
        scored: BoolArray = self.class_index >= 0
        return scored


class PredictionMode(enum.IntEnum):
    """How a track's future was predicted (SR-PRED-1)."""

    FOOTPRINT = 0  # stationary or static: where it is now
    CONE = 1  # moving: linear projection inside the heading cone
    STOP = 2  # near-reversal, first mode: carries on forwards at most, stops
    REVERSE = 3  # near-reversal, second mode: stops, then reverses
    UNKNOWN = 4  # unscored or low confidence: any direction


@dataclass(frozen=True, slots=True)
class Predictions:
    """Where each tracked object may be within the horizon: one row per mode (SR-PRED-1).

    ``reach_xy_m`` (M, P, 2): the counter-clockwise vertices of a convex region (repeated
    points allowed; a point or a segment for degenerate rows) that holds every position the
    track's reference point (its cluster centroid, in the tracking frame) may reach at any time
    in ``[0, horizon_s]``. ``body_radius_m`` (M,) is the radius
    of a disc about the reference point that holds the object's body, so the region grown by
    it holds the whole object. ``speed_mps`` is the speed bound the region was built with and
    ``heading_rad`` the direction it was built around (NaN when none: a disc; on a row built
    along a body axis either way, one of the axis's two directions, :mod:`pipeline.predict_axis`).
    ``person_compatible``: nothing seen of the track excludes a person (its box is not larger
    than a person can be; :func:`pipeline.predict.person_compatible`, SR-CLS-8).
    ``safety.geometry.envelopes`` turns rows into polygons.
    """

    stamp_s: float
    horizon_s: float
    track_id: IntArray
    mode: IntArray
    class_index: IntArray
    confidence: FloatArray
    near_reversal: BoolArray
    person_compatible: BoolArray
    speed_mps: FloatArray
    heading_rad: FloatArray
    body_radius_m: FloatArray
    reach_xy_m: FloatArray

    def __post_init__(self) -> None:
        freeze_fields(
            self,
            ("confidence", "speed_mps", "heading_rad", "body_radius_m", "reach_xy_m"),
            np.float64,
        )
        freeze_fields(self, ("track_id", "mode", "class_index"), np.int64)
        freeze_fields(self, ("near_reversal", "person_compatible"), np.bool_)
        m = self.track_id.shape[0]
        for name in (
            "mode",
            "class_index",
            "confidence",
            "near_reversal",
            "person_compatible",
            "speed_mps",
            "heading_rad",
            "body_radius_m",
        ):
            if getattr(self, name).shape != (m,):
                raise ValueError(f"Predictions: {name} must have shape ({m},)")
        if (
            self.reach_xy_m.ndim != 3
            or self.reach_xy_m.shape[0] != m
            or self.reach_xy_m.shape[2] != 2
        ):
            raise ValueError(f"Predictions: reach_xy_m must be ({m}, P, 2)")

    @property
    def n(self) -> int:
        """Number of rows (modes)."""
        return int(self.track_id.shape[0])


@dataclass(frozen=True, slots=True)
class Envelopes:
    """Obstacle envelopes: predicted regions inflated by body and margin (SR-PRED-1, SR-STOP-4).

    One convex polygon per prediction row, in the frame the envelopes were built for (the robot
    frame for the swept-path check). Per polygon: ``track_id``, the prediction ``mode``,
    ``class_index`` (-1 unscored), the margin ``tier`` (0 high, 1 medium, 2 near-reversal:
    :class:`safety.model.stopping.Tier` order) and ``margin_m`` chosen by the stopping model's
    ``margin_for``, the ``closing_speed_mps`` the governor must assume, the classification
    ``confidence`` (0 when unscored) and the ``near_reversal`` flag. The arrays are exactly
    what :meth:`safety.model.governor.Governor.command` takes per obstacle.
    """

    stamp_s: float
    polygons: ConvexPolygons
    track_id: IntArray
    mode: IntArray
    class_index: IntArray
    tier: IntArray
    margin_m: FloatArray
    closing_speed_mps: FloatArray
    confidence: FloatArray
    near_reversal: BoolArray

    def __post_init__(self) -> None:
        freeze_fields(self, ("margin_m", "closing_speed_mps", "confidence"), np.float64)
        freeze_fields(self, ("track_id", "mode", "class_index", "tier"), np.int64)
        freeze_fields(self, ("near_reversal",), np.bool_)
        m = self.polygons.n
        for name in (
            "track_id",
            "mode",
            "class_index",
            "tier",
            "margin_m",
            "closing_speed_mps",
            "confidence",
            "near_reversal",
        ):
            if getattr(self, name).shape != (m,):
                raise ValueError(f"Envelopes: {name} must have shape ({m},) like the polygons")

    @property
    def n(self) -> int:
        """Number of envelopes."""
        return self.polygons.n
