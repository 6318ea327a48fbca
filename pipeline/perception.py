"""THE perception chain: one frame in, what the safety side needs out (SR-TRK-*, SR-CLS-*,
SR-FUS-*, SR-PRED-*, SR-TIM-1).

:class:`Perception` declares its role components in its constructor and is the only place the
chain is wired; the runtime (:class:`safety.runtime.Runtime`), classifier training
(:mod:`pipeline.training.data`), the real-log checks and the campaigns all call it, so they
cannot drift apart. The data path reads top to bottom in :meth:`Perception.perceive`:

    scan filter -> clusterer -> shape estimator -> tracker (with its associator)
    -> feature extractor -> classifier -> fusion -> predictor

Frames: the scan filter gives points in the robot frame (with a second scanner configured, its
fresh points merged in: :mod:`pipeline.scanners`); when the frame carries an odometry
pose the clusters are moved into the tracking frame (:func:`pipeline.track.tracker.
detections_in_frame`) and tracked there, else tracking happens in the robot frame. Thermal
detections move with the same pose. Radar returns go through the radar's front-end
(:class:`pipeline.sensors.radar.RadarFrontEnd`, SR-FUS-7, SR-FUS-9): its filters (no reflector
map), its ego-motion compensation with the frame's pose and twist, and the position weight of the
scan's LiDAR degradation index (its share of isolated returns near the scanner); fusion then
gates them with the tracker's own gates (:class:`pipeline.sensors.radar.RadarGate`), and the
radar-refined states of the matched tracks go back into the tracker's filter
(``radar.write_back``). A moving
robot without a twist cannot compensate the Doppler: the frame is refused (the runtime STOPs
naming the fusion stage).

Each stage is timed by a :class:`Stopwatch`; a stage that raises ends the call with
:class:`StageError`, which names the stage and carries what the earlier stages produced.

:class:`PerceptionChain` is what the runtime needs of a chain; besides :class:`Perception`, the
ground-truth chain of :mod:`pipeline.oracle` (the simulator's true objects as tracks and
predictions, the availability oracle) is one.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Protocol

from pipeline.classify.model import Classifier
from pipeline.cluster.dbscan import DbscanClusterer
from pipeline.config import SafecaseConfig
from pipeline.errors import SafecaseError
from pipeline.features import TrackFeatureExtractor
from pipeline.frames import IDENTITY, Pose, checked_pose, is_identity
from pipeline.fusion import GatedFusion, thermal_in_frame
from pipeline.points import RangeFilter
from pipeline.predict import KinematicPredictor
from pipeline.roles import (
    Clusterer,
    FeatureExtractor,
    FreshnessGuard,
    Fusion,
    Predictor,
    ScanFilter,
    ShapeEstimator,
    TrackClassifier,
    TrackerRole,
)
from pipeline.scanners import SecondScanner, SecondScanReport
from pipeline.sensors.radar import RadarCounts, RadarFrontEnd, RadarGate, degradation_index
from pipeline.sensors.radar_counts import RadarFusionCounts
from pipeline.shape.box import BoxShapes
from pipeline.shape.lshape import LShapeShapes
from pipeline.track.heading import TrackHeadings
from pipeline.track.tracker import Tracker, detections_in_frame
from pipeline.types import (
    NOISE_LABEL,
    Classification,
    Clusters,
    CycleCounts,
    Detections,
    Frame,
    FusedTracks,
    Predictions,
    RadarDetections,
    ScanPoints,
    TrackFeatures,
    Tracks,
)

__all__ = [
    "STAGES",
    "Perceived",
    "Perception",
    "PerceptionChain",
    "PerceptionError",
    "StageError",
    "Stopwatch",
    "Tracked",
]

STAGES = ("points", "cluster", "shape", "track", "features", "classify", "fusion", "predict")


class PerceptionError(SafecaseError, ValueError):
    """A frame the chain cannot process (no scan, radar from a moving robot without its twist,
    no classifier)."""


class StageError(SafecaseError):
    """A stage raised: ``stage`` names it, ``cause`` is the error, ``partial`` holds what the
    stages before it produced (the points' drop counts feed the monitors even then)."""

    def __init__(self, stage: str, cause: Exception, partial: Partial) -> None:
        super().__init__(f"{type(cause).__name__}: {cause}")
        self.stage = stage
        self.cause = cause
        self.partial = partial


class Stopwatch:
    """Wall-clock time per stage of one cycle [s]; ``current`` is the stage last entered.

    ``on_enter(stage)`` runs as each stage starts (the runtime's fault injection in tests).
    """

    def __init__(self, on_enter: Callable[[str], None] | None = None) -> None:
        self.wall_s: dict[str, float] = {}
        self.current = ""
        self._on_enter = on_enter

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block as stage ``name`` (recorded even when it raises)."""
        self.current = name
        start = time.perf_counter_ns()
        try:
            if self._on_enter is not None:
                self._on_enter(name)
            yield
        finally:
            self.wall_s[name] = (time.perf_counter_ns() - start) * 1e-9


@dataclass(frozen=True)
class Partial:
    """What the stages before a failure produced (each None when not reached)."""

    points: ScanPoints | None = None
    clusters: Clusters | None = None
    counts: CycleCounts | None = None
    fused: FusedTracks | None = None


@dataclass(frozen=True)
class Tracked:
    """The tracking half of the chain for one frame (tracking frame placed by ``pose``).

    ``points`` and ``clusters`` are in the robot frame; ``tracks`` and ``features`` in the
    tracking frame; ``counts`` is the tracker's account of the cycle; ``headings`` each track's
    heading (same rows as ``tracks``) when the tracker keeps one (SR-TRK-7).
    """

    frame: Frame
    pose: Pose
    points: ScanPoints
    clusters: Clusters
    tracks: Tracks
    counts: CycleCounts | None
    features: TrackFeatures
    headings: TrackHeadings | None = None
    second: SecondScanReport | None = None


@dataclass(frozen=True)
class Perceived:
    """The whole chain for one frame: :class:`Tracked` plus classes, fusion and predictions.

    ``fused.tracks`` are the tracks after radar updates; ``predictions`` are made from them.
    """

    tracked: Tracked
    classification: Classification
    fused: FusedTracks
    predictions: Predictions

    @property
    def pose(self) -> Pose:
        """The robot's pose in the tracking frame at the scan's stamp."""
        return self.tracked.pose

    @property
    def points(self) -> ScanPoints:
        """The scan's valid points (robot frame)."""
        return self.tracked.points

    @property
    def clusters(self) -> Clusters:
        """The kept clusters (robot frame)."""
        return self.tracked.clusters

    @property
    def features(self) -> TrackFeatures:
        """The feature row of every track."""
        return self.tracked.features


class PerceptionChain(Protocol):
    """What the runtime calls once per frame: :meth:`Perception.perceive` and ``reset``."""

    def perceive(
        self,
        frame: Frame,
        *,
        now_s: Callable[[], float] | None = None,
        watch: Stopwatch | None = None,
    ) -> Perceived: ...

    def reset(self) -> None: ...


@dataclass(frozen=True)
class Perception:
    """The perception chain, one component per role (module docstring).

    ``classifier``, ``fusion`` and ``predictor`` may be left out by a caller that only tracks
    (:meth:`track`: training-data generation, tracking campaigns); :meth:`perceive` needs all.
    """

    scan_filter: ScanFilter
    clusterer: Clusterer
    shapes: ShapeEstimator
    tracker: TrackerRole
    features: FeatureExtractor
    classifier: TrackClassifier | None = None
    fusion: Fusion | None = None
    predictor: Predictor | None = None
    second: SecondScanner | None = None
    radar: RadarFrontEnd | None = None

    @classmethod
    def from_config(
        cls,
        config: SafecaseConfig,
        *,
        classifier: TrackClassifier | None = None,
        guard: FreshnessGuard | None = None,
        tracking_only: bool = False,
    ) -> Perception:
        """The chain ``config`` describes, each stage given its own section; the shape
        estimator is ``cluster.shape_estimator``'s, the tracker's associator
        ``track.association``'s.

        ``classifier`` defaults to the configured model (hash-checked); fusion needs the
        freshness ``guard``, a safety formula (:func:`safety.model.freshness.is_fresh`).
        ``tracking_only`` leaves out classification, fusion and prediction (and needs no guard).
        A second scanner (``scan2.enabled``) is merged only by a chain given the ``guard``.
        A chain with fusion runs a frame's radar through the radar's front-end and gates it with
        the radar gate (the ``radar`` section's noise, the ``track`` section's gates).
        """
        chain = cls(
            scan_filter=RangeFilter(config.scan),
            clusterer=DbscanClusterer(config.cluster),
            shapes=(
                LShapeShapes(config.cluster)
                if config.cluster.shape_estimator == "lshape"
                else BoxShapes(config.cluster)
            ),
            tracker=Tracker(config.track),
            features=TrackFeatureExtractor(config.predict),
        )
        if tracking_only:
            return chain
        if guard is None:
            raise PerceptionError("Perception.from_config: fusion needs a freshness guard")
        return cls(
            chain.scan_filter,
            chain.clusterer,
            chain.shapes,
            chain.tracker,
            chain.features,
            classifier if classifier is not None else Classifier.from_config(config.classify),
            GatedFusion(config.fusion, guard, RadarGate.from_config(config)),
            KinematicPredictor(config.predict, config.classify.medium_confidence_min),
            (
                SecondScanner(config.scan, config.scan2, config.monitors, guard)
                if config.scan2.enabled
                else None
            ),
            RadarFrontEnd(config),
        )

    def reset(self) -> None:
        """Forget every track (a source that restarted, a clock that ran backwards)."""
        self.tracker.reset()

    def track(
        self, frame: Frame, watch: Stopwatch | None = None, now_s: float | None = None
    ) -> Tracked:
        """Scan filter, clustering, shapes, tracking and features for one frame; a second
        scan is judged fresh at ``now_s`` [s] (default: the frame's ``received_s``)."""
        watch = watch if watch is not None else Stopwatch()
        points = clusters = None
        counts = None
        second = None
        try:
            with watch.stage("points"):
                if frame.scan is None:
                    raise PerceptionError("no scan this cycle")
                pose = IDENTITY if frame.pose is None else checked_pose(frame.pose)
                points = self.scan_filter.points(frame.scan)
                if self.second is not None:
                    now = frame.received_s if now_s is None else now_s
                    points, second = self.second.merge(frame, points, now)
            with watch.stage("cluster"):
                partition = self.clusterer.partition(points)
            with watch.stage("shape"):
                clusters = self.shapes.clusters(points, partition)
            with watch.stage("track"):
                if is_identity(pose):
                    detections = Detections.from_clusters(clusters)
                else:
                    detections = detections_in_frame(clusters, pose)
                tracks = self.tracker.step(detections)
                counts = self.tracker.last_counts
            with watch.stage("features"):
                features = self.features.features(tracks, clusters, (pose[0], pose[1]))
        except Exception as exc:  # the caller decides (the runtime: STOP naming the stage)
            raise StageError(watch.current, exc, Partial(points, clusters, counts)) from exc
        headings = getattr(self.tracker, "last_headings", None)
        return Tracked(frame, pose, points, clusters, tracks, counts, features, headings, second)

    def perceive(
        self,
        frame: Frame,
        *,
        now_s: Callable[[], float] | None = None,
        watch: Stopwatch | None = None,
    ) -> Perceived:
        """The whole chain for one frame (module docstring).

        ``now_s()`` is the decision clock when fusion runs [s] (default: the frame's
        ``received_s``): detections are judged fresh against it. Raises :class:`StageError`.
        """
        watch = watch if watch is not None else Stopwatch()
        tracked = self.track(frame, watch, None if now_s is None else now_s())
        fused = None
        try:
            with watch.stage("classify"):
                if self.classifier is None or self.fusion is None or self.predictor is None:
                    raise PerceptionError("this chain only tracks (built with tracking_only)")
                classification = self.classifier.classify(tracked.features)
            with watch.stage("fusion"):
                fused = self._fuse(tracked, classification, now_s)
            with watch.stage("predict"):
                boosted = replace(classification, confidence=fused.confidence)
                predictions = self.predictor.predict(
                    fused.tracks, tracked.features, boosted, tracked.headings
                )
        except Exception as exc:
            partial = Partial(tracked.points, tracked.clusters, tracked.counts, fused)
            raise StageError(watch.current, exc, partial) from exc
        return Perceived(tracked, classification, fused, predictions)

    def _fuse(
        self,
        tracked: Tracked,
        classification: Classification,
        now_s: Callable[[], float] | None,
    ) -> FusedTracks:
        """Thermal (moved into the tracking frame) and radar (through its front-end) fused at
        decision time; with radar, the counts are :class:`RadarFusionCounts`."""
        frame, pose = tracked.frame, tracked.pose
        now = frame.received_s if now_s is None else now_s()
        thermal = None if frame.thermal is None else thermal_in_frame(frame.thermal, pose)
        assert self.fusion is not None  # perceive checked
        if frame.radar is None:
            return self.fusion.fuse(now, tracked.tracks, classification.confidence, thermal, None)
        radar, front, index = self._radar(tracked)
        fused = self.fusion.fuse(now, tracked.tracks, classification.confidence, thermal, radar)
        weight = radar.position_weight
        given = 0.0 if weight is None or weight.shape[0] == 0 else float(weight[0])
        written = 0
        assert self.radar is not None  # _radar checked
        if self.radar.section.write_back:
            # The radar updated these tracks at the scan's stamp: the filter keeps the result.
            matched = fused.radar_index >= 0
            t = fused.tracks
            written = self.tracker.correct(
                t.track_id[matched], t.state[matched], t.covariance[matched]
            )
        counts = RadarFusionCounts.of(fused.counts, front, index, given, written)
        return replace(fused, counts=counts)

    def _radar(self, tracked: Tracked) -> tuple[RadarDetections, RadarCounts, float]:
        """The frame's radar returns through the front-end (module docstring): the kept ones in
        the tracking frame, what the filters did and the LiDAR degradation index. Raises
        :class:`PerceptionError` for a chain without the front-end, or a moving robot without a
        twist."""
        frame, pose = tracked.frame, tracked.pose
        assert frame.radar is not None  # the caller checked
        if self.radar is None:
            raise PerceptionError("radar returns need the radar front-end (Perception.radar)")
        kept, counts = self.radar.filter(frame.radar, pose, None)
        section = self.radar.section
        index = degradation_index(
            tracked.points.range_m,
            tracked.clusters.point_labels == NOISE_LABEL,
            section.degraded_within_m,
            section.degraded_noise_fraction,
        )
        try:
            framed = self.radar.in_tracking_frame(frame.radar, kept, pose, frame.twist, index)
        except ValueError as exc:  # no twist on a moving robot: refused, never guessed
            raise PerceptionError(str(exc)) from exc
        return framed, counts, index
