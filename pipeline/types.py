"""Frozen data passed between the stages of the data path (struct of arrays, units in names).

Each hop of ``serial/sim -> Scan -> clusters -> tracks -> classes -> envelopes -> Command`` has
one type here. Arrays are made read-only on construction so a stage cannot modify what an
earlier stage (or the audit log) still holds.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from pipeline.errors import DegeneratePolygonError, GeometryError, NonFiniteGeometryError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

__all__ = [
    "Action",
    "BoolArray",
    "Classification",
    "ClusterCounts",
    "Clusters",
    "Command",
    "ConvexPolygons",
    "DriverHealth",
    "DriverState",
    "DropCounts",
    "Envelopes",
    "FloatArray",
    "FusedTracks",
    "FusionCounts",
    "IntArray",
    "PredictionMode",
    "Predictions",
    "RadarDetections",
    "Scan",
    "ScanPoints",
    "SweptPathReport",
    "ThermalDetections",
    "TrackFeatures",
    "TrackStatus",
    "Tracks",
    "frozen_array",
]


def frozen_array(
    values: npt.ArrayLike, dtype: type[np.generic] = np.float64
) -> npt.NDArray[np.generic]:
    """A read-only, C-contiguous copy of ``values`` with the given dtype."""
    array = np.array(values, dtype=dtype, copy=True, order="C")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, slots=True)
class Scan:
    """One revolution of a 2D range scanner, whatever produced it (SR-DRV-*, SR-SIM-*).

    ``angles_rad`` and ``ranges_m`` have one entry per beam, in the scanner frame
    (counter-clockwise, 0 rad straight ahead). A beam with no return has range NaN; the
    sanitation stage drops and counts such beams, it never guesses. ``stamp_s`` is the time of
    the first beam; beam ``i`` was taken at ``stamp_s + i * beam_period_s``. ``complete`` is
    False when the driver had to drop rejected frames from this revolution (the beams that
    came from them are absent, never patched).
    """

    stamp_s: float
    angles_rad: FloatArray
    ranges_m: FloatArray
    intensities: FloatArray | None = None
    beam_period_s: float = 0.0
    seq: int = 0
    source: str = ""
    complete: bool = True

    def __post_init__(self) -> None:
        angles = frozen_array(self.angles_rad)
        ranges = frozen_array(self.ranges_m)
        if angles.ndim != 1 or ranges.shape != angles.shape:
            raise ValueError(
                f"Scan: angles_rad shape {angles.shape} and ranges_m shape {ranges.shape} "
                "must be equal and one-dimensional"
            )
        if not np.all(np.isfinite(angles)):
            raise ValueError("Scan: angles_rad must be finite")
        object.__setattr__(self, "angles_rad", angles)
        object.__setattr__(self, "ranges_m", ranges)
        if self.intensities is not None:
            intensities = frozen_array(self.intensities)
            if intensities.shape != angles.shape:
                raise ValueError(
                    f"Scan: intensities shape {intensities.shape} must equal "
                    f"angles_rad shape {angles.shape}"
                )
            object.__setattr__(self, "intensities", intensities)
        if not np.isfinite(self.stamp_s):
            raise ValueError(f"Scan: stamp_s must be finite, got {self.stamp_s!r}")
        if not (np.isfinite(self.beam_period_s) and self.beam_period_s >= 0.0):
            raise ValueError(f"Scan: beam_period_s must be >= 0, got {self.beam_period_s!r}")

    @property
    def n_beams(self) -> int:
        """Number of beams in this revolution."""
        return int(self.angles_rad.shape[0])


class Action(enum.Enum):
    """The governor's decision (SR-STOP-*)."""

    PROCEED = "PROCEED"
    SLOW = "SLOW"
    STOP = "STOP"


@dataclass(frozen=True, slots=True)
class Command:
    """What the safety layer tells the drive, with every reason that shaped it.

    ``speed_mps`` is the commanded speed limit (0 for STOP). ``reasons`` is never empty for
    SLOW or STOP: fail-safe stops record why (stale input, missed deadline, bad config, ...).
    """

    action: Action
    speed_mps: float
    stamp_s: float
    reasons: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.speed_mps) and self.speed_mps >= 0.0):
            raise ValueError(f"Command: speed_mps must be finite and >= 0, got {self.speed_mps}")
        if self.action is Action.STOP and self.speed_mps != 0.0:
            raise ValueError(f"Command: STOP must have speed_mps 0, got {self.speed_mps}")
        if self.action is not Action.PROCEED and not self.reasons:
            raise ValueError(f"Command: {self.action.value} needs at least one reason")


class DriverState(enum.Enum):
    """Health of a serial scanner link, as the runtime monitors read it (SR-DRV-3).

    ``OK``: valid frames arrive. ``DEGRADED``: valid frames arrive but some were rejected within
    the last silent timeout. ``STALE``: no valid frame for longer than the silent timeout.
    ``DISCONNECTED``: the port failed or is closed and a reconnect is pending. ``CONNECTING``:
    opening the port and handshaking. ``FAILED``: the reconnect budget is spent; the driver
    gives up. Only ``OK`` and ``DEGRADED`` mean the scans are fresh.
    """

    CONNECTING = "CONNECTING"
    OK = "OK"
    DEGRADED = "DEGRADED"
    STALE = "STALE"
    DISCONNECTED = "DISCONNECTED"
    FAILED = "FAILED"


@dataclass(frozen=True, slots=True)
class DriverHealth:
    """A snapshot of a driver's link health and counters at ``stamp_s`` (SR-DRV-2, SR-DRV-3).

    ``age_s`` is the time since the last valid frame (infinite before the first). Counters are
    totals since the driver was created: ``frames_rejected`` failed a checksum or check bit,
    ``bytes_discarded`` were skipped while re-synchronising, ``scans_incomplete`` were emitted
    with ``Scan.complete == False``, ``scans_dropped`` were withheld.
    """

    state: DriverState
    stamp_s: float
    age_s: float
    frames_ok: int = 0
    frames_rejected: int = 0
    bytes_discarded: int = 0
    scans_emitted: int = 0
    scans_incomplete: int = 0
    scans_dropped: int = 0
    reconnects: int = 0
    last_error: str = ""

    @property
    def fresh(self) -> bool:
        """True when the scans from this link may be used (state OK or DEGRADED)."""
        return self.state in (DriverState.OK, DriverState.DEGRADED)


@dataclass(frozen=True, slots=True)
class ConvexPolygons:
    """N convex polygons in metres, counter-clockwise, vertex-major (SR-SAT-*).

    ``vertices_m`` has shape (2, K, N): ``[0]`` holds x, ``[1]`` holds y; column ``n`` holds
    polygon ``n``'s ``counts[n]`` vertices followed by copies of its first vertex up to K. The
    padding repeats a vertex (which changes no projection) and adds zero-length edges (which
    never separate), so the SAT kernels need no masks. The vertex index leads because numpy
    reduces over a leading axis as whole-row operations, 10-30x faster than over a short
    trailing axis; x and y are stacked so one gather moves both. ``slack_m`` (N,) bounds how
    far, in metres, a point given to the normalisation that built the polygon may lie outside
    it (rounding in the hull); the collision check adds it to its clearance threshold.

    Build these with :func:`safety.geometry.convex_polygons` (which normalises: hull,
    counter-clockwise order, duplicates and collinear points removed); this constructor only
    checks shapes, finiteness and padding.
    """

    vertices_m: FloatArray
    counts: IntArray
    slack_m: FloatArray

    def __post_init__(self) -> None:
        vertices: FloatArray = np.array(self.vertices_m, dtype=np.float64, order="C", copy=True)
        counts: IntArray = np.array(self.counts, dtype=np.int64, copy=True)
        slack: FloatArray = np.array(self.slack_m, dtype=np.float64, copy=True)
        for array in (vertices, counts, slack):
            array.flags.writeable = False
        if vertices.ndim != 3 or vertices.shape[0] != 2 or vertices.shape[1] < 3:
            raise GeometryError(
                f"ConvexPolygons: vertices_m must have shape (2, K >= 3, N), got {vertices.shape}"
            )
        k, n = vertices.shape[1], vertices.shape[2]
        if counts.shape != (n,) or slack.shape != (n,):
            raise GeometryError(
                f"ConvexPolygons: counts {counts.shape} and slack_m {slack.shape} must have "
                f"shape ({n},)"
            )
        # One reduction: a sum is finite exactly when every (bounded) term is.
        if not np.isfinite(vertices.sum()) and not np.all(np.isfinite(vertices)):
            bad = np.argwhere(~np.isfinite(vertices))[0]
            raise NonFiniteGeometryError(
                f"ConvexPolygons: vertex {bad[1]} of polygon {bad[2]} is not finite "
                f"({float(vertices[tuple(bad)])!r}); expected finite coordinates in metres"
            )
        if n == 0:
            pass
        elif counts.min() < 3 or counts.max() > k:
            raise DegeneratePolygonError(
                f"ConvexPolygons: counts must lie in [3, {k}], got {int(counts.min())}"
            )
        elif not (slack.min() >= 0.0 and np.isfinite(slack.sum())):
            raise GeometryError("ConvexPolygons: slack_m must be finite and >= 0")
        # Padding content cannot make a "clear" verdict unsound (a separating axis proves the
        # hull of all K points apart); checking the last row catches misuse such as zeros.
        elif ((vertices[:, -1, :] != vertices[:, 0, :]).any(axis=0) & (counts < k)).any():
            raise GeometryError("ConvexPolygons: padding must repeat each polygon's first vertex")
        object.__setattr__(self, "vertices_m", vertices)
        object.__setattr__(self, "counts", counts)
        object.__setattr__(self, "slack_m", slack)

    @property
    def n(self) -> int:
        """Number of polygons."""
        return int(self.vertices_m.shape[2])

    @property
    def k(self) -> int:
        """Padded vertex count K."""
        return int(self.vertices_m.shape[1])

    def vertex_list(self, i: int) -> FloatArray:
        """Polygon ``i``'s vertices as a (counts[i], 2) array, counter-clockwise."""
        count = int(self.counts[i])
        return np.ascontiguousarray(self.vertices_m[:, :count, i].T)

    def take(self, indices: npt.ArrayLike) -> ConvexPolygons:
        """The polygons at ``indices`` (in that order), with the same padding K."""
        idx = np.asarray(indices, dtype=np.int64)
        return ConvexPolygons(
            vertices_m=self.vertices_m[:, :, idx],
            counts=self.counts[idx],
            slack_m=self.slack_m[idx],
        )


@dataclass(frozen=True, slots=True)
class SweptPathReport:
    """Which candidate trajectories are blocked, by what and when (SR-SAT-3).

    For T trajectories and O obstacle envelopes: ``blocked`` (T, O) is True where the swept
    hull of trajectory t overlaps envelope o. ``contact_step`` (T, O) is the first sample
    index k whose segment hull (the hull of the footprints at k and k+1) touches the envelope,
    -1 where the pair is clear, and 0 where only the whole-path hull touches it (a concave
    pocket of a curved path: reported as contact now, the conservative answer; ``hull_only``
    marks these). ``earliest_contact_s`` (T,) is ``step_s`` times the smallest contact step
    of the trajectory (``inf`` when clear) and ``first_obstacle`` (T,) the envelope that
    gives it (-1 when clear). ``gated`` (O,) marks envelopes skipped by the distance
    pre-gate because no swept hull can reach them.
    """

    blocked: BoolArray
    contact_step: IntArray
    hull_only: BoolArray
    earliest_contact_s: FloatArray
    first_obstacle: IntArray
    gated: BoolArray
    step_s: float

    def __post_init__(self) -> None:
        blocked = frozen_array(self.blocked, dtype=np.bool_)
        if blocked.ndim != 2:
            raise ValueError(f"SweptPathReport: blocked must be (T, O), got {blocked.shape}")
        t, o = blocked.shape
        shapes = {
            "contact_step": (self.contact_step, (t, o), np.int64),
            "hull_only": (self.hull_only, (t, o), np.bool_),
            "earliest_contact_s": (self.earliest_contact_s, (t,), np.float64),
            "first_obstacle": (self.first_obstacle, (t,), np.int64),
            "gated": (self.gated, (o,), np.bool_),
        }
        object.__setattr__(self, "blocked", blocked)
        for name, (value, shape, dtype) in shapes.items():
            array = frozen_array(value, dtype=dtype)
            if array.shape != shape:
                raise ValueError(f"SweptPathReport: {name} must have shape {shape}")
            object.__setattr__(self, name, array)

    @property
    def blocked_trajectories(self) -> IntArray:
        """Indices of the trajectories blocked by at least one envelope."""
        return np.flatnonzero(self.blocked.any(axis=1)).astype(np.int64)


# ---------------------------------------------------------------- clustering and tracking (TRK)


def _freeze_fields(obj: object, names: tuple[str, ...], dtype: type[np.generic]) -> None:
    """Replace each named field of a frozen dataclass by a read-only array of ``dtype``."""
    for name in names:
        object.__setattr__(obj, name, frozen_array(getattr(obj, name), dtype))


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
        _freeze_fields(self, ("x_m", "y_m", "angle_rad", "range_m"), np.float64)
        _freeze_fields(self, ("beam_index",), np.int64)
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
class Clusters:
    """Kept clusters of one scan with their geometry, struct of arrays (SR-TRK-2).

    One entry per cluster: centroid (mean of its points), the minimum-area oriented bounding
    box (``width_m <= length_m``, ``heading_rad`` the direction of the long side in
    [-pi/2, pi/2)), ``area_m2`` of that box, ``point_density_per_m2`` (points per box area,
    area floored at ``cluster.density_min_area_m2``), ``n_points``, and the convex hull:
    counter-clockwise vertices of cluster ``k`` are ``hull_x_m[hull_offsets[k]:hull_offsets[k
    + 1]]`` (one vertex for coincident points, two for collinear ones). ``point_labels`` gives,
    for every point of the :class:`ScanPoints` the clusters came from, its kept cluster index
    or -1 (noise, or a cluster dropped by the size filter or the cap).
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
        _freeze_fields(self, (*per_cluster, "hull_x_m", "hull_y_m"), np.float64)
        _freeze_fields(self, ("n_points", "hull_offsets", "point_labels"), np.int64)
        n = self.centroid_x_m.shape[0]
        for name in (*per_cluster, "n_points"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"Clusters: {name} must have shape ({n},)")
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
    history_len: IntArray
    reid_count: IntArray

    def __post_init__(self) -> None:
        _freeze_fields(
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
            ),
            np.float64,
        )
        _freeze_fields(
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

    @property
    def n(self) -> int:
        """Number of tracks in the snapshot (dormant included)."""
        return int(self.track_id.shape[0])

    def with_status(self, *statuses: TrackStatus) -> BoolArray:
        """Mask of the tracks whose status is one of ``statuses``."""
        return np.isin(self.status, [int(s) for s in statuses])


# ---------------------------------------------------------------- fusion (FUS)


@dataclass(frozen=True, slots=True)
class ThermalDetections:
    """Warm-body detections of a thermal camera, robot frame, one entry each (SR-FUS-1, -3).

    ``stamp_s`` is each detection's capture time on the sensor's clock (which may differ from
    the decision clock by at most ``fusion.clock_skew_s``); ``confidence`` the detector's score
    in [0, 1]. Non-finite values are allowed here: fusion drops and counts them.
    """

    stamp_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    confidence: FloatArray

    def __post_init__(self) -> None:
        _freeze_fields(self, ("stamp_s", "x_m", "y_m", "confidence"), np.float64)
        n = self.stamp_s.shape
        if len(n) != 1 or any(getattr(self, k).shape != n for k in ("x_m", "y_m", "confidence")):
            raise ValueError(
                "ThermalDetections: stamp_s, x_m, y_m and confidence must be one-dimensional "
                f"and of equal length, got {[getattr(self, k).shape for k in self.__slots__]}"
            )

    @property
    def n(self) -> int:
        """Number of detections."""
        return int(self.stamp_s.shape[0])


@dataclass(frozen=True, slots=True)
class RadarDetections:
    """Radar returns with Doppler, robot frame, one entry each (SR-FUS-1).

    The radar sits at ``(mount_x_m, mount_y_m)``; ``bearing_rad`` is the direction of the return
    from there in the robot frame and ``radial_velocity_mps`` the measured range rate (positive:
    moving away). Non-finite values are allowed here: fusion drops and counts them.
    """

    stamp_s: FloatArray
    range_m: FloatArray
    bearing_rad: FloatArray
    radial_velocity_mps: FloatArray
    mount_x_m: float = 0.0
    mount_y_m: float = 0.0

    def __post_init__(self) -> None:
        names = ("stamp_s", "range_m", "bearing_rad", "radial_velocity_mps")
        _freeze_fields(self, names, np.float64)
        n = self.stamp_s.shape
        if len(n) != 1 or any(getattr(self, k).shape != n for k in names):
            shapes = [getattr(self, k).shape for k in names]
            raise ValueError(
                "RadarDetections: stamp_s, range_m, bearing_rad and radial_velocity_mps must be "
                f"one-dimensional and of equal length, got {shapes}"
            )
        if not (np.isfinite(self.mount_x_m) and np.isfinite(self.mount_y_m)):
            raise ValueError("RadarDetections: the mount position must be finite")

    @property
    def n(self) -> int:
        """Number of returns."""
        return int(self.stamp_s.shape[0])

    @property
    def x_m(self) -> FloatArray:
        """Robot-frame x of each return [m]."""
        return self.mount_x_m + self.range_m * np.cos(self.bearing_rad)

    @property
    def y_m(self) -> FloatArray:
        """Robot-frame y of each return [m]."""
        return self.mount_y_m + self.range_m * np.sin(self.bearing_rad)


@dataclass(frozen=True, slots=True)
class FusionCounts:
    """What one fusion cycle did with each detection (SR-FUS-1); every input lands in one bin.

    Per sensor: ``invalid`` (non-finite stamp or position), ``stale`` (older than the maximum
    age), ``future`` (stamped later than the clock skew allows), ``over_cap`` (fresh but beyond
    the per-cycle cap), ``matched`` (fused into a track); thermal also ``only`` (became a
    thermal-only pedestrian), radar ``unmatched`` (no track in the gate: not used).
    """

    n_thermal: int = 0
    n_thermal_invalid: int = 0
    n_thermal_stale: int = 0
    n_thermal_future: int = 0
    n_thermal_over_cap: int = 0
    n_thermal_matched: int = 0
    n_thermal_only: int = 0
    n_radar: int = 0
    n_radar_invalid: int = 0
    n_radar_stale: int = 0
    n_radar_future: int = 0
    n_radar_over_cap: int = 0
    n_radar_matched: int = 0
    n_radar_unmatched: int = 0

    def __post_init__(self) -> None:
        thermal = (
            self.n_thermal_invalid,
            self.n_thermal_stale,
            self.n_thermal_future,
            self.n_thermal_over_cap,
            self.n_thermal_matched,
            self.n_thermal_only,
        )
        radar = (
            self.n_radar_invalid,
            self.n_radar_stale,
            self.n_radar_future,
            self.n_radar_over_cap,
            self.n_radar_matched,
            self.n_radar_unmatched,
        )
        if min(*thermal, *radar) < 0 or sum(thermal) != self.n_thermal:
            raise ValueError(f"FusionCounts: thermal bins {thermal} must sum to {self.n_thermal}")
        if sum(radar) != self.n_radar:
            raise ValueError(f"FusionCounts: radar bins {radar} must sum to {self.n_radar}")

    @property
    def lidar_only(self) -> bool:
        """True when nothing from thermal or radar was fused this cycle (LiDAR-only fallback)."""
        return self.n_thermal_matched + self.n_thermal_only + self.n_radar_matched == 0


@dataclass(frozen=True, slots=True)
class FusedTracks:
    """LiDAR tracks after fusion, plus thermal-only pedestrians (SR-FUS-1, SR-FUS-3).

    ``tracks`` are the tracker's snapshot with the velocity of radar-matched tracks refined by
    the Doppler update; ``confidence`` (one per track) the classifier's confidence raised for
    thermal-matched tracks; ``thermal_index`` / ``radar_index`` the input detection fused into
    each track or -1. Pedestrians (one per unmatched fresh thermal detection): position as
    detected at ``pedestrian_stamp_s`` [robot frame, m], ``pedestrian_confidence`` below
    ``classify.medium_confidence_min`` (most cautious tier), ``pedestrian_index`` the input
    detection.
    """

    stamp_s: float
    tracks: Tracks
    confidence: FloatArray
    thermal_index: IntArray
    radar_index: IntArray
    pedestrian_x_m: FloatArray
    pedestrian_y_m: FloatArray
    pedestrian_stamp_s: FloatArray
    pedestrian_confidence: FloatArray
    pedestrian_index: IntArray
    counts: FusionCounts

    def __post_init__(self) -> None:
        _freeze_fields(self, ("confidence",), np.float64)
        _freeze_fields(self, ("thermal_index", "radar_index", "pedestrian_index"), np.int64)
        names = ("pedestrian_x_m", "pedestrian_y_m", "pedestrian_stamp_s", "pedestrian_confidence")
        _freeze_fields(self, names, np.float64)
        n = self.tracks.n
        for name in ("confidence", "thermal_index", "radar_index"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"FusedTracks: {name} must have shape ({n},)")
        m = self.pedestrian_index.shape
        if len(m) != 1 or any(getattr(self, k).shape != m for k in names):
            raise ValueError("FusedTracks: pedestrian arrays must have equal length")

    @property
    def n_pedestrians(self) -> int:
        """Number of thermal-only pedestrians."""
        return int(self.pedestrian_index.shape[0])


# ---------------------------------------------------------- classification, prediction (CLS, PRED)


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
        _freeze_fields(self, ("values",), np.float64)
        _freeze_fields(self, ("track_id", "status"), np.int64)
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
        _freeze_fields(self, ("probability", "confidence"), np.float64)
        _freeze_fields(self, ("track_id", "class_index"), np.int64)
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
    ``heading_rad`` the direction it was built around (NaN when none: a disc).
    ``safety.envelope`` turns rows into polygons.
    """

    stamp_s: float
    horizon_s: float
    track_id: IntArray
    mode: IntArray
    class_index: IntArray
    confidence: FloatArray
    near_reversal: BoolArray
    speed_mps: FloatArray
    heading_rad: FloatArray
    body_radius_m: FloatArray
    reach_xy_m: FloatArray

    def __post_init__(self) -> None:
        _freeze_fields(
            self,
            ("confidence", "speed_mps", "heading_rad", "body_radius_m", "reach_xy_m"),
            np.float64,
        )
        _freeze_fields(self, ("track_id", "mode", "class_index"), np.int64)
        _freeze_fields(self, ("near_reversal",), np.bool_)
        m = self.track_id.shape[0]
        for name in (
            "mode",
            "class_index",
            "confidence",
            "near_reversal",
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
    :class:`safety.stopping.Tier` order) and ``margin_m`` chosen by the stopping model's
    ``margin_for``, the ``closing_speed_mps`` the governor must assume, the classification
    ``confidence`` (0 when unscored) and the ``near_reversal`` flag. The arrays are exactly
    what :meth:`safety.governor.Governor.command` takes per obstacle.
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
        _freeze_fields(self, ("margin_m", "closing_speed_mps", "confidence"), np.float64)
        _freeze_fields(self, ("track_id", "mode", "class_index", "tier"), np.int64)
        _freeze_fields(self, ("near_reversal",), np.bool_)
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
