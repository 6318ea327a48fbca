"""The roles of the perception chain, each a small protocol (SR-TRK-*, -CLS-*, -FUS-*, -PRED-*).

:class:`pipeline.perception.Perception` is composed of one component per role, declared in its
constructor; each role's default implementation lives in the role's own module
(:class:`~pipeline.points.RangeFilter`, :class:`~pipeline.cluster.dbscan.DbscanClusterer`,
:class:`~pipeline.shape.box.BoxShapes`, :class:`~pipeline.track.tracker.Tracker` with
:class:`~pipeline.track.associate.CascadeAssociator`,
:class:`~pipeline.features.TrackFeatureExtractor`, :class:`~pipeline.classify.model.Classifier`,
:class:`~pipeline.fusion.GatedFusion`, :class:`~pipeline.predict.KinematicPredictor`). A second
implementation of a role (:class:`~pipeline.shape.lshape.LShapeShapes` beside the box,
:class:`~pipeline.track.jpda.JpdaAssociator` beside the Hungarian cascade, each chosen by the
configuration) plugs in beside the default without touching the chain.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

from pipeline.types import (
    BoolArray,
    Classification,
    Clusters,
    CycleCounts,
    Detections,
    FloatArray,
    FusedTracks,
    IntArray,
    Predictions,
    RadarDetections,
    Scan,
    ScanPoints,
    ThermalDetections,
    TrackFeatures,
    Tracks,
)
from pipeline.types.tracking import Partition, SoftAssociation

__all__ = [
    "Associator",
    "Clusterer",
    "FeatureExtractor",
    "FreshnessGuard",
    "Fusion",
    "HeadingRows",
    "Predictor",
    "ScanFilter",
    "ShapeEstimator",
    "SoftAssociator",
    "TrackClassifier",
    "TrackerRole",
]


class ScanFilter(Protocol):
    """Beams to Cartesian points in the scan's frame, invalid ranges dropped and counted."""

    def points(self, scan: Scan) -> ScanPoints: ...


class Clusterer(Protocol):
    """Points to a partition: a cluster label per point (-1 for none), clusters kept by size."""

    def partition(self, points: ScanPoints) -> Partition: ...


class ShapeEstimator(Protocol):
    """A partition to clusters with their geometry: centroid, hull, oriented box, ends."""

    def clusters(self, points: ScanPoints, partition: Partition) -> Clusters: ...


class Associator(Protocol):
    """Gated track-detection costs to one-to-one matches, by priority group.

    ``cost`` is (tracks, detections) with ``inf`` where a pair is outside the gates; each mask
    of ``groups`` selects the tracks matched in that round. Returns the detection matched to
    each track (-1 none) and which detections are left free.
    """

    def associate(
        self, cost: FloatArray, groups: Sequence[BoolArray]
    ) -> tuple[IntArray, BoolArray]: ...


@runtime_checkable
class SoftAssociator(Associator, Protocol):
    """An associator that may update a track with several detections at once (JPDA).

    ``log_norm`` (tracks,) is ``-log(2 pi sqrt(det S))`` of each track's innovation
    covariance; the result says which tracks take a weighted update and with which weights.
    """

    def associate_soft(
        self, cost: FloatArray, groups: Sequence[BoolArray], log_norm: FloatArray
    ) -> SoftAssociation: ...


class TrackerRole(Protocol):
    """Detections of one scan in, the tracks after that scan out (stamped, in order).

    ``last_counts`` is the account of the last step; :meth:`correct` replaces the filtered
    state of live tracks by one another sensor refined at the last step's stamp and returns how
    many it wrote; :meth:`reset` forgets every track.
    """

    @property
    def last_counts(self) -> CycleCounts | None: ...

    def step(self, detections: Detections) -> Tracks: ...

    def correct(self, track_id: IntArray, state: FloatArray, covariance: FloatArray) -> int: ...

    def reset(self) -> None: ...


class FeatureExtractor(Protocol):
    """The classifier's feature row of every track."""

    def features(
        self, tracks: Tracks, clusters: Clusters | None, robot_xy_m: tuple[float, float]
    ) -> TrackFeatures: ...


class TrackClassifier(Protocol):
    """Feature rows to classes with probabilities and a confidence per track."""

    @property
    def class_names(self) -> tuple[str, ...]: ...

    def classify(self, features: TrackFeatures) -> Classification: ...


class FreshnessGuard(Protocol):
    """True where a reading stamped ``stamp_s`` may still be used at ``now_s`` (a safety
    formula: :func:`safety.model.freshness.is_fresh` is the one the runtime gives)."""

    def __call__(
        self, now_s: Any, stamp_s: Any, max_age_s: Any, skew_s: Any, guard_s: Any = ...
    ) -> Any: ...


class Fusion(Protocol):
    """Thermal and radar detections fused into the tracks at decision time ``now_s``."""

    def fuse(
        self,
        now_s: float,
        tracks: Tracks,
        confidence: FloatArray,
        thermal: ThermalDetections | None,
        radar: RadarDetections | None,
    ) -> FusedTracks: ...


class HeadingRows(Protocol):
    """Each track's heading [rad] in the tracking frame, NaN when unknown, one row per track
    (:class:`pipeline.track.heading.TrackHeadings`; named by shape here because the tracker
    imports the roles)."""

    @property
    def track_id(self) -> IntArray: ...

    @property
    def heading_rad(self) -> FloatArray: ...


class Predictor(Protocol):
    """Where each track may be within the horizon: prediction rows, one or two per track
    (``headings``, when the tracker keeps them, have the tracks' rows)."""

    def predict(
        self,
        tracks: Tracks,
        features: TrackFeatures,
        classification: Classification,
        headings: HeadingRows | None = None,
    ) -> Predictions: ...
