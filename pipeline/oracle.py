"""Ground-truth perception: the simulator's true world as the tracks and predictions the safety
side consumes, for the availability oracle (SR-AVL-1).

:class:`GroundTruthPerception` is a :class:`~pipeline.perception.PerceptionChain`: given a frame
of a simulation it returns the same :class:`~pipeline.perception.Perceived` the perception chain
returns, built from the simulator's world at the scan's stamp instead of from the scan. Every
object is a confirmed track with its true class (``SIM_TO_MODEL_CLASS``, confidence 1), its
reference point the centre of its true oriented box at the stamp, its velocity that centre's
(a finite difference over :data:`VELOCITY_DT_S`, backward, forward at the run's start; exact
for the piecewise motions), zero covariance, a centroid history of the last
``track.history_frames`` frames, and a "cluster" whose hull is the object's true convex outline
(what a still object's zone is built from). Every part of the static structure within
:data:`STRUCTURE_REACH_M` of the lookahead is a confirmed ``static`` track with its exact
outline. No scan point is left over, so the safety side sees no loose points; the scan is still
filtered, so the monitors read its real drop counts.

Predictions come from the one predictor (:func:`pipeline.predict.predict`) with the configured
horizon, cone and margins: the oracle is perfect perception under the same proofs, not a
different model of the world. Objects hidden from the scanner are known too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pipeline.classify.model import MODEL_CLASSES, NEAR_REVERSAL_CLASS
from pipeline.config import SafecaseConfig
from pipeline.features import FEATURE_NAMES, feature_index
from pipeline.frames import IDENTITY, Pose, checked_pose, to_child
from pipeline.perception import (
    Partial,
    Perceived,
    PerceptionError,
    StageError,
    Stopwatch,
    Tracked,
)
from pipeline.points import RangeFilter
from pipeline.predict import predict
from pipeline.shape.box import convex_hulls
from pipeline.sources.sim.simulation import Simulation
from pipeline.sources.sim.truth import CLASS_NAMES, LabelRules, object_labels
from pipeline.sources.sim.world import World
from pipeline.training.data import SIM_TO_MODEL_CLASS
from pipeline.types import (
    Classification,
    ClusterCounts,
    Clusters,
    CycleCounts,
    FloatArray,
    Frame,
    FusedTracks,
    FusionCounts,
    IntArray,
    ScanPoints,
    TrackFeatures,
    Tracks,
    TrackStatus,
)

__all__ = ["STRUCTURE_REACH_M", "VELOCITY_DT_S", "GroundTruthPerception"]

VELOCITY_DT_S = 0.01
"""Time step of the finite difference that gives each object's reference-point velocity [s]."""
STRUCTURE_REACH_M = 3.0
"""Static parts farther than the path lookahead plus this from the robot are left out [m]."""

_STATIC = MODEL_CLASSES.index("static")
_MODEL_CODE = np.array(
    [MODEL_CLASSES.index(SIM_TO_MODEL_CLASS[name]) for name in CLASS_NAMES], dtype=np.int64
)
_NEAR_REVERSAL = feature_index("is_near_reversal")


@dataclass(frozen=True)
class _Outlines:
    """Convex outlines in the world frame with their oriented boxes (one row per outline)."""

    centre_xy_m: FloatArray  # (n, 2)
    width_m: FloatArray
    length_m: FloatArray
    heading_rad: FloatArray
    hull_x_m: FloatArray
    hull_y_m: FloatArray
    hull_offsets: IntArray


@dataclass
class GroundTruthPerception:
    """The simulation ``world``'s truth as a perception chain (module docstring).

    ``rules`` are the forklift state labels' thresholds (the simulation's own).
    """

    config: SafecaseConfig
    world: World
    rules: LabelRules
    scan_filter: RangeFilter = field(init=False)

    def __post_init__(self) -> None:
        self.scan_filter = RangeFilter(self.config.scan)
        st = self.world.structure.outline
        first = st.part_starts[:-1]
        self._part_lo = np.minimum.reduceat(st.vertices_m, first, axis=0) if st.n_parts else None
        self._part_hi = np.maximum.reduceat(st.vertices_m, first, axis=0) if st.n_parts else None

    @classmethod
    def for_simulation(cls, config: SafecaseConfig, sim: Simulation) -> GroundTruthPerception:
        """The truth of ``sim``'s world, labelled with ``sim``'s rules."""
        return cls(config, sim.world, sim.rules)

    def reset(self) -> None:
        """Nothing to forget: every frame is read from the world afresh."""

    def perceive(
        self,
        frame: Frame,
        *,
        now_s: Callable[[], float] | None = None,
        watch: Stopwatch | None = None,
    ) -> Perceived:
        """The truth at the frame's scan stamp (module docstring). Raises :class:`StageError`."""
        del now_s  # nothing here is judged against the decision clock
        watch = watch if watch is not None else Stopwatch()
        points = None
        try:
            with watch.stage("points"):
                if frame.scan is None:
                    raise PerceptionError("no scan this cycle")
                pose = IDENTITY if frame.pose is None else checked_pose(frame.pose)
                scanned = self.scan_filter.points(frame.scan)
                points = _no_points(scanned)
            with watch.stage("track"):
                stamp = float(frame.scan.stamp_s)
                tracks, labels, outlines = self._tracks(stamp, pose)
                clusters = _clusters(stamp, outlines, pose)
                features = _features(tracks, labels)
                classification = _classification(tracks, labels)
                fused = _fused(tracks)
            with watch.stage("predict"):
                pc = self.config.predict
                predictions = predict(
                    tracks, features, classification, pc, self.config.classify.medium_confidence_min
                )
        except Exception as exc:
            raise StageError(watch.current, exc, Partial(points)) from exc
        counts = CycleCounts(
            n_detections=tracks.n,
            n_detections_dropped=0,
            n_matched_confirmed=tracks.n,
            n_matched_tentative=0,
            n_reidentified=0,
            n_born=0,
            n_births_refused=0,
            n_tentative_dropped=0,
            n_dormant_deleted=0,
            n_lost_deleted=0,
            n_live=tracks.n,
            n_dormant=0,
        )
        tracked = Tracked(frame, pose, points, clusters, tracks, counts, features)
        return Perceived(tracked, classification, fused, predictions)

    def _tracks(self, stamp_s: float, pose: Pose) -> tuple[Tracks, IntArray, _Outlines]:
        """Confirmed tracks of every object and of the nearby static parts, their model class
        codes, and their outlines (world frame = tracking frame in simulation)."""
        n_hist = self.config.track.history_frames
        period = self.config.track.frame_period_s
        # History times oldest first, then the stamp minus the velocity step (plus it before
        # the run has lasted one step: the world is not defined before 0), then the stamp.
        hist_t = stamp_s - period * np.arange(n_hist - 1, -1, -1, dtype=np.float64)
        step_s = -VELOCITY_DT_S if stamp_s >= VELOCITY_DT_S else VELOCITY_DT_S
        times = np.concatenate([hist_t, [stamp_s + step_s, stamp_s]])
        objects = _object_outlines(self.world, np.maximum(times, 0.0))
        obj_now = objects[-1]
        n_obj = len(self.world.objects)
        centres = np.stack([o.centre_xy_m for o in objects])  # (T, n_obj, 2)
        velocity = (centres[-2] - centres[-1]) / step_s
        labels = _MODEL_CODE[object_labels(self.world, stamp_s, self.rules)]
        parts = self._parts_near(pose)
        n = n_obj + parts.width_m.shape[0]
        h = n_hist
        history = np.full((n, h, 2), np.nan)
        history[:n_obj] = np.transpose(centres[:h], (1, 0, 2))
        history[:n_obj][:, hist_t < 0.0] = np.nan  # before the run: not seen yet
        history[n_obj:] = parts.centre_xy_m[:, None, :]
        hist_times = np.broadcast_to(hist_t, (n, h)).copy()
        hist_speed = np.zeros((n, h))
        hist_speed[:n_obj] = np.hypot(velocity[:, 0], velocity[:, 1])[:, None]
        state = np.zeros((n, 4))
        state[:n_obj, :2] = obj_now.centre_xy_m
        state[:n_obj, 2:] = velocity
        state[n_obj:, :2] = parts.centre_xy_m
        width = np.concatenate([obj_now.width_m, parts.width_m])
        length = np.concatenate([obj_now.length_m, parts.length_m])
        ones = np.full(n, h, dtype=np.int64)
        tracks = Tracks(
            stamp_s=stamp_s,
            track_id=np.arange(1, n + 1, dtype=np.int64),
            status=np.full(n, int(TrackStatus.CONFIRMED), dtype=np.int64),
            state=state,
            covariance=np.zeros((n, 4, 4)),
            detection_index=np.arange(n, dtype=np.int64),
            age_frames=ones,
            hits=ones,
            misses=np.zeros(n, dtype=np.int64),
            last_update_s=np.full(n, stamp_s),
            width_m=width,
            length_m=length,
            size_variance_m2=np.zeros(n),
            decel_mps2=np.zeros(n),
            history_xy_m=history,
            history_speed_mps=hist_speed,
            history_t_s=hist_times,
            history_len=ones,
            max_width_m=width,
            max_length_m=length,
            reid_count=np.zeros(n, dtype=np.int64),
            history_end_xy_m=np.full((n, h, 4), np.nan),
            history_end_occluded=np.full((n, h, 2), np.nan),
        )
        classes = np.concatenate([labels, np.full(n - n_obj, _STATIC, dtype=np.int64)])
        outlines = _Outlines(
            np.concatenate([obj_now.centre_xy_m, parts.centre_xy_m]),
            width,
            length,
            np.concatenate([obj_now.heading_rad, parts.heading_rad]),
            np.concatenate([obj_now.hull_x_m, parts.hull_x_m]),
            np.concatenate([obj_now.hull_y_m, parts.hull_y_m]),
            np.concatenate(
                [obj_now.hull_offsets, obj_now.hull_offsets[-1] + parts.hull_offsets[1:]]
            ),
        )
        return tracks, classes, outlines

    def _parts_near(self, pose: Pose) -> _Outlines:
        """The static parts whose bounding box comes within the lookahead plus
        :data:`STRUCTURE_REACH_M` of the robot."""
        st = self.world.structure.outline
        if self._part_lo is None or self._part_hi is None:
            return _outlines(np.zeros((0, 2)), np.zeros(0, dtype=np.int64), 0, np.zeros(0))
        reach = self.config.runtime.path_lookahead_m + STRUCTURE_REACH_M
        robot = np.array(pose[:2])
        gap = np.maximum(np.maximum(self._part_lo - robot, robot - self._part_hi), 0.0)
        near = np.flatnonzero(np.hypot(gap[:, 0], gap[:, 1]) <= reach)
        rank = np.full(st.n_parts, -1, dtype=np.int64)
        rank[near] = np.arange(near.size)
        labels = np.repeat(rank, np.diff(st.part_starts))
        keep = labels >= 0
        return _outlines(st.vertices_m[keep], labels[keep], int(near.size), np.zeros(near.size))


def _object_outlines(world: World, times_s: FloatArray) -> list[_Outlines]:
    """Every object's outline at each of ``times_s`` (one :class:`_Outlines` per time)."""
    verts = world.object_vertices(times_s)  # (T, V, 2)
    n = len(world.objects)
    labels = np.repeat(np.arange(n), [hi - lo for lo, hi in world.vertex_slices])
    headings = np.zeros((times_s.shape[0], n))
    for i, obj in enumerate(world.objects):
        headings[:, i] = obj.trajectory.at(times_s)["heading_rad"]
    return [_outlines(verts[k], labels, n, headings[k]) for k in range(times_s.shape[0])]


def _outlines(xy_m: FloatArray, labels: IntArray, n: int, heading_rad: FloatArray) -> _Outlines:
    """Hulls of the points of each label and the box about each, aligned with ``heading_rad``:
    its centre is the reference point, and half its diagonal reaches every point."""
    if n == 0:
        empty = np.zeros(0)
        return _Outlines(np.zeros((0, 2)), empty, empty, empty, empty, empty, np.zeros(1, int))
    x, y = xy_m[:, 0], xy_m[:, 1]
    hx, hy, offsets = convex_hulls(x, y, labels, n)
    c, s = np.cos(heading_rad)[labels], np.sin(heading_rad)[labels]
    along, across = c * x + s * y, -s * x + c * y
    lo_a = np.full(n, np.inf)
    hi_a = np.full(n, -np.inf)
    lo_c = np.full(n, np.inf)
    hi_c = np.full(n, -np.inf)
    np.minimum.at(lo_a, labels, along)
    np.maximum.at(hi_a, labels, along)
    np.minimum.at(lo_c, labels, across)
    np.maximum.at(hi_c, labels, across)
    mid_a, mid_c = 0.5 * (lo_a + hi_a), 0.5 * (lo_c + hi_c)
    ch, sh = np.cos(heading_rad), np.sin(heading_rad)
    centre = np.stack([ch * mid_a - sh * mid_c, sh * mid_a + ch * mid_c], axis=1)
    return _Outlines(centre, hi_c - lo_c, hi_a - lo_a, heading_rad, hx, hy, offsets)


def _no_points(scanned: ScanPoints) -> ScanPoints:
    """No points left over for the safety side, with the scan's real drop counts."""
    empty = np.zeros(0)
    return ScanPoints(
        scanned.stamp_s, empty, empty, empty, empty, np.zeros(0, np.int64), scanned.drops
    )


def _clusters(stamp_s: float, o: _Outlines, pose: Pose) -> Clusters:
    """One cluster per outline, in the robot frame (its hull is what a still zone is)."""
    n = o.width_m.shape[0]
    cx, cy = to_child(pose, o.centre_xy_m[:, 0], o.centre_xy_m[:, 1])
    hx, hy = to_child(pose, o.hull_x_m, o.hull_y_m)
    area = o.width_m * o.length_m
    return Clusters(
        stamp_s=stamp_s,
        centroid_x_m=cx,
        centroid_y_m=cy,
        width_m=np.minimum(o.width_m, o.length_m),
        length_m=np.maximum(o.width_m, o.length_m),
        heading_rad=np.mod(o.heading_rad - pose[2] + 0.5 * np.pi, np.pi) - 0.5 * np.pi,
        area_m2=area,
        point_density_per_m2=np.zeros(n),
        n_points=np.zeros(n, dtype=np.int64),
        hull_x_m=hx,
        hull_y_m=hy,
        hull_offsets=o.hull_offsets,
        point_labels=np.zeros(0, dtype=np.int64),
        counts=ClusterCounts(n, 0, 0, 0, 0, 0),
        end_x_m=np.zeros((n, 2)),
        end_y_m=np.zeros((n, 2)),
        end_occluded=np.zeros((n, 2), dtype=bool),
    )


def _features(tracks: Tracks, classes: IntArray) -> TrackFeatures:
    """Feature rows: NaN except the near-reversal flag, which the truth gives."""
    values = np.full((tracks.n, len(FEATURE_NAMES)), np.nan)
    near = classes == MODEL_CLASSES.index(NEAR_REVERSAL_CLASS)
    values[:, _NEAR_REVERSAL] = near.astype(np.float64)
    return TrackFeatures(tracks.stamp_s, tracks.track_id, tracks.status, values)


def _classification(tracks: Tracks, classes: IntArray) -> Classification:
    """The true class of every track, with certainty."""
    probability = np.zeros((tracks.n, len(MODEL_CLASSES)))
    probability[np.arange(tracks.n), classes] = 1.0
    return Classification(
        tracks.stamp_s,
        tracks.track_id,
        classes,
        probability,
        np.ones(tracks.n),
        MODEL_CLASSES,
        "ground truth",
    )


def _fused(tracks: Tracks) -> FusedTracks:
    """The tracks as fusion would hand them on: nothing fused, no thermal-only pedestrians."""
    n = tracks.n
    none = np.full(n, -1, dtype=np.int64)
    empty = np.zeros(0)
    return FusedTracks(
        tracks.stamp_s,
        tracks,
        np.ones(n),
        none,
        none.copy(),
        empty,
        empty,
        empty,
        empty,
        np.zeros(0, dtype=np.int64),
        FusionCounts(),
    )
