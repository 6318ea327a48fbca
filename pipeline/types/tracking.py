"""Scan points, clusters and tracks (SR-TRK-*)."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from pipeline.errors import SafecaseError
from pipeline.types.core import BoolArray, FloatArray, IntArray, freeze_fields, frozen_array

NOISE_LABEL = -1
"""A point's cluster label when DBSCAN left it in no cluster (too few neighbours)."""
DROPPED_LABEL = -2
"""A point's cluster label when its cluster was dropped by the size filter or the cap."""


@dataclass(frozen=True, slots=True)
class DropCounts:
    """How many beams of one scan sanitation kept and dropped, by reason (SR-TRK-1).

    The categories are disjoint and add up: ``n_beams == n_valid + n_dropped``. ``n_inf``
    counts +inf and -inf; ``n_below_min`` / ``n_above_max`` count finite ranges outside the
    configured ``[scan.min_range_m, scan.max_range_m]`` (negative ranges are below minimum).
    Runtime monitors read these counts (a scan that is mostly dropped is an ODD violation).
    """

    n_beams: int
    n_valid: int
    n_nan: int
    n_inf: int
    n_below_min: int
    n_above_max: int

    def __post_init__(self) -> None:
        parts = (self.n_valid, self.n_nan, self.n_inf, self.n_below_min, self.n_above_max)
        if min(parts) < 0 or sum(parts) != self.n_beams:
            raise ValueError(f"DropCounts: categories {parts} must be >= 0 and sum to n_beams")

    @property
    def n_dropped(self) -> int:
        """Beams that did not become points."""
        return self.n_beams - self.n_valid


@dataclass(frozen=True, slots=True)
class ScanPoints:
    """The valid beams of one scan as Cartesian points in the robot frame (SR-TRK-1).

    Points are ordered by sensor bearing ``angle_rad`` (wrapped to [-pi, pi)), which the
    clustering stage exploits; ``beam_index`` is each point's index in the original scan.
    ``range_m`` is the sensor range (the distance from the sensor, not from the robot origin).
    """

    stamp_s: float
    x_m: FloatArray
    y_m: FloatArray
    angle_rad: FloatArray
    range_m: FloatArray
    beam_index: IntArray
    drops: DropCounts

    def __post_init__(self) -> None:
        freeze_fields(self, ("x_m", "y_m", "angle_rad", "range_m"), np.float64)
        freeze_fields(self, ("beam_index",), np.int64)
        n = self.x_m.shape[0]
        for name in ("y_m", "angle_rad", "range_m", "beam_index"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"ScanPoints: {name} must have shape ({n},)")

    @property
    def n(self) -> int:
        """Number of points."""
        return int(self.x_m.shape[0])


@dataclass(frozen=True, slots=True)
class ClusterCounts:
    """What the clustering stage found and discarded in one scan (SR-TRK-2, SR-TIM-3)."""

    n_found: int
    n_too_small: int
    n_too_large: int
    n_over_cap: int
    n_noise_points: int
    n_border_points: int


@dataclass(frozen=True, slots=True)
class Partition:
    """Which kept cluster each point of one scan belongs to (SR-TRK-2).

    ``point_labels`` holds, for every point of the :class:`ScanPoints` it was made from, its
    kept cluster index in ``0 .. n_clusters - 1``, :data:`NOISE_LABEL` (-1, in no cluster) or
    :data:`DROPPED_LABEL` (-2, its cluster dropped by the size filter or the cap); ``counts``
    says what was found and discarded.
    """

    stamp_s: float
    point_labels: IntArray
    n_clusters: int
    counts: ClusterCounts

    def __post_init__(self) -> None:
        freeze_fields(self, ("point_labels",), np.int64)
        if self.point_labels.ndim != 1 or int(self.point_labels.max(initial=-1)) >= self.n_clusters:
            raise ValueError("Partition: point_labels must be 1-D labels below n_clusters")


@dataclass(frozen=True, slots=True)
class Clusters:
    """Kept clusters of one scan with their geometry, struct of arrays (SR-TRK-2).

    One entry per cluster: centroid (mean of its points), the minimum-area oriented bounding
    box (``width_m <= length_m``, ``heading_rad`` the direction of the long side in
    [-pi/2, pi/2)), ``area_m2`` of that box, ``point_density_per_m2`` (points per box area,
    area floored at ``cluster.density_min_area_m2``), ``n_points``, and the convex hull:
    counter-clockwise vertices of cluster ``k`` are ``hull_x_m[hull_offsets[k]:hull_offsets[k
    + 1]]`` (one vertex for coincident points, two for collinear ones). ``point_labels`` gives,
    for every point of the :class:`ScanPoints` the clusters came from, its kept cluster index,
    -1 (noise) or -2 (a cluster dropped by the size filter or the cap), as in
    :class:`Partition`. ``end_x_m`` and ``end_y_m`` (n, 2) are the cluster's first and last
    point in the counter-clockwise sweep (column 0 where the sweep enters the cluster);
    ``end_occluded`` (n, 2) says whether the
    beam next to that end returned a point nearer than it (:mod:`pipeline.shape.ends`): the
    object may go on behind.
    """

    stamp_s: float
    centroid_x_m: FloatArray
    centroid_y_m: FloatArray
    width_m: FloatArray
    length_m: FloatArray
    heading_rad: FloatArray
    area_m2: FloatArray
    point_density_per_m2: FloatArray
    n_points: IntArray
    hull_x_m: FloatArray
    hull_y_m: FloatArray
    hull_offsets: IntArray
    point_labels: IntArray
    counts: ClusterCounts
    end_x_m: FloatArray
    end_y_m: FloatArray
    end_occluded: BoolArray

    def __post_init__(self) -> None:
        per_cluster = (
            "centroid_x_m",
            "centroid_y_m",
            "width_m",
            "length_m",
            "heading_rad",
            "area_m2",
            "point_density_per_m2",
        )
        freeze_fields(
            self, (*per_cluster, "hull_x_m", "hull_y_m", "end_x_m", "end_y_m"), np.float64
        )
        freeze_fields(self, ("n_points", "hull_offsets", "point_labels"), np.int64)
        freeze_fields(self, ("end_occluded",), np.bool_)
        n = self.centroid_x_m.shape[0]
        for name in (*per_cluster, "n_points"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"Clusters: {name} must have shape ({n},)")
        for name in ("end_x_m", "end_y_m", "end_occluded"):
            if getattr(self, name).shape != (n, 2):
                raise ValueError(f"Clusters: {name} must have shape ({n}, 2)")
        if self.hull_offsets.shape != (n + 1,) or self.hull_x_m.shape != self.hull_y_m.shape:
            raise ValueError("Clusters: hull_offsets must have n + 1 entries")

    @property
    def n(self) -> int:
        """Number of kept clusters."""
        return int(self.centroid_x_m.shape[0])

    def hull(self, k: int) -> FloatArray:
        """Hull vertices of cluster ``k`` as an (h, 2) array, counter-clockwise."""
        lo, hi = int(self.hull_offsets[k]), int(self.hull_offsets[k + 1])
        return np.stack([self.hull_x_m[lo:hi], self.hull_y_m[lo:hi]], axis=1)


class TrackStatus(enum.IntEnum):
    """Lifecycle state of a track (SR-TRK-4). Deleted tracks are not reported."""

    TENTATIVE = 0
    CONFIRMED = 1
    LOST = 2
    DORMANT = 3


@dataclass(frozen=True, slots=True)
class Tracks:
    """Snapshot of the tracker after one cycle, struct of arrays (SR-TRK-3, SR-TRK-4).

    One entry per live or dormant track, ordered by ``track_id``. ``state`` rows are
    ``[x_m, y_m, vx_mps, vy_mps]`` in the robot frame and ``covariance`` their 4x4
    covariances; for a DORMANT track both are as of its last update (``last_update_s``).
    ``detection_index`` is the index of the detection that updated the track this cycle or -1.
    ``history_xy_m`` holds the last ``history_len`` centroids (oldest first, padded with NaN),
    ``decel_mps2`` the least-squares deceleration of the filtered speed over the configured
    window (positive when slowing), ``size_variance_m2`` the variance of width plus that of
    length over the configured frames. ``reid_count`` counts re-identifications of the track.
    ``history_speed_mps`` and ``history_t_s`` are the filtered speeds and stamps of the same
    history entries; ``max_width_m`` and ``max_length_m`` the largest box the track has shown
    since it was born (a part-view of a large object keeps the size once seen).
    ``history_end_xy_m`` (n, h, 4) holds the same entries' cluster ends ``[x0, y0, x1, y1]``
    in the tracking frame and ``history_end_occluded`` (n, h, 2) whether each end was bounded
    by a nearer return (1.0 / 0.0; NaN where the detection carried no ends).
    """

    stamp_s: float
    track_id: IntArray
    status: IntArray
    state: FloatArray
    covariance: FloatArray
    detection_index: IntArray
    age_frames: IntArray
    hits: IntArray
    misses: IntArray
    last_update_s: FloatArray
    width_m: FloatArray
    length_m: FloatArray
    size_variance_m2: FloatArray
    decel_mps2: FloatArray
    history_xy_m: FloatArray
    history_speed_mps: FloatArray
    history_t_s: FloatArray
    history_len: IntArray
    max_width_m: FloatArray
    max_length_m: FloatArray
    reid_count: IntArray
    history_end_xy_m: FloatArray
    history_end_occluded: FloatArray

    def __post_init__(self) -> None:
        freeze_fields(
            self,
            (
                "state",
                "covariance",
                "last_update_s",
                "width_m",
                "length_m",
                "size_variance_m2",
                "decel_mps2",
                "history_xy_m",
                "history_speed_mps",
                "history_t_s",
                "max_width_m",
                "max_length_m",
                "history_end_xy_m",
                "history_end_occluded",
            ),
            np.float64,
        )
        freeze_fields(
            self,
            (
                "track_id",
                "status",
                "detection_index",
                "age_frames",
                "hits",
                "misses",
                "history_len",
                "reid_count",
            ),
            np.int64,
        )
        n = self.track_id.shape[0]
        if self.state.shape != (n, 4) or self.covariance.shape != (n, 4, 4):
            raise ValueError(f"Tracks: state must be ({n}, 4) and covariance ({n}, 4, 4)")
        h = self.history_xy_m.shape[:2]
        if self.history_speed_mps.shape != h or self.history_t_s.shape != h:
            raise ValueError(f"Tracks: history_speed_mps and history_t_s must be {h}")
        if self.history_end_xy_m.shape != (*h, 4) or self.history_end_occluded.shape != (*h, 2):
            raise ValueError(f"Tracks: history_end_xy_m must be {(*h, 4)}, occluded {(*h, 2)}")
        if self.max_width_m.shape != (n,) or self.max_length_m.shape != (n,):
            raise ValueError(f"Tracks: max_width_m and max_length_m must be ({n},)")

    @property
    def n(self) -> int:
        """Number of tracks in the snapshot (dormant included)."""
        return int(self.track_id.shape[0])

    def with_status(self, *statuses: TrackStatus) -> BoolArray:
        """Mask of the tracks whose status is one of ``statuses``."""
        return np.isin(self.status, [int(s) for s in statuses])


class TrackerError(SafecaseError, ValueError):
    """Input the tracker refuses: a clock that ran backwards or non-finite detections."""


@dataclass(frozen=True, slots=True)
class Detections:
    """What the tracker consumes from one scan: centroids and box sizes (struct of arrays).

    Optionally the clusters' ends: ``end_xy_m`` (n, 4) ``[x0, y0, x1, y1]`` and
    ``end_occluded`` (n, 2) (:mod:`pipeline.shape.ends`). The tracker only keeps them in the
    tracks' histories for the classifier's features; without them those entries are NaN.
    Optionally ``heading_rad`` (n,): each box's axis (its longer side, modulo pi), from which
    the tracker keeps a heading per track (:mod:`pipeline.track.heading`, SR-TRK-7).
    """

    stamp_s: float
    x_m: FloatArray
    y_m: FloatArray
    width_m: FloatArray
    length_m: FloatArray
    end_xy_m: FloatArray | None = None
    end_occluded: BoolArray | None = None
    heading_rad: FloatArray | None = None

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "width_m", "length_m"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        n = self.x_m.shape
        if self.y_m.shape != n or self.width_m.shape != n or self.length_m.shape != n:
            raise TrackerError("Detections: x_m, y_m, width_m and length_m must match in shape")
        if (self.end_xy_m is None) != (self.end_occluded is None):
            raise TrackerError("Detections: end_xy_m and end_occluded come together or not at all")
        if self.end_xy_m is not None and self.end_occluded is not None:
            object.__setattr__(self, "end_xy_m", frozen_array(self.end_xy_m))
            object.__setattr__(self, "end_occluded", frozen_array(self.end_occluded, np.bool_))
            if self.end_xy_m.shape != (*n, 4) or self.end_occluded.shape != (*n, 2):
                raise TrackerError(
                    f"Detections: end_xy_m must have shape {(*n, 4)} and end_occluded {(*n, 2)}"
                )
        if self.heading_rad is not None:
            object.__setattr__(self, "heading_rad", frozen_array(self.heading_rad))
            if self.heading_rad.shape != n:
                raise TrackerError(f"Detections: heading_rad must have shape {n}")

    @classmethod
    def from_clusters(cls, clusters: Clusters) -> Detections:
        """Centroids, oriented-box sizes, ends and box axes of the kept clusters (scanner
        frame)."""
        return cls(
            clusters.stamp_s,
            clusters.centroid_x_m,
            clusters.centroid_y_m,
            clusters.width_m,
            clusters.length_m,
            np.stack([clusters.end_x_m, clusters.end_y_m], axis=2).reshape(-1, 4),
            clusters.end_occluded,
            clusters.heading_rad,
        )

    def ends(self) -> tuple[FloatArray, FloatArray]:
        """``(end_xy_m, occluded)``, (n, 4) and (n, 2) floats (1.0 occluded, 0.0 free); NaN
        for detections without ends."""
        if self.end_xy_m is None or self.end_occluded is None:
            return np.full((self.n, 4), np.nan), np.full((self.n, 2), np.nan)
        return self.end_xy_m, self.end_occluded.astype(np.float64)

    @property
    def n(self) -> int:
        """Number of detections."""
        return int(self.x_m.shape[0])


@dataclass(frozen=True, slots=True)
class SoftAssociation:
    """One cycle's association by a probabilistic associator (:mod:`pipeline.track.jpda`,
    SR-TRK-8). ``match`` (tracks,): each track's detection for the bookkeeping (-1 none);
    ``free`` (detections,): left for tentative tracks and births; ``pda`` (tracks,): the tracks
    updated with every gated detection at once (:func:`pipeline.track.jpda.pda_update`) with
    ``beta`` (tracks, detections + 1; column 0 the missed-detection probability, zero rows
    elsewhere)."""

    match: IntArray
    free: BoolArray
    pda: BoolArray
    beta: FloatArray


@dataclass(frozen=True, slots=True)
class CycleCounts:
    """What one tracker cycle did (read by the evidence and the runtime monitors)."""

    n_detections: int
    n_detections_dropped: int
    n_matched_confirmed: int
    n_matched_tentative: int
    n_reidentified: int
    n_born: int
    n_births_refused: int
    n_tentative_dropped: int
    n_dormant_deleted: int
    n_lost_deleted: int
    n_live: int
    n_dormant: int
