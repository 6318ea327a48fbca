"""The per-track feature vector of the classifier, vectorised over all tracks (SR-CLS-2).

One code path for training and run time: :func:`track_features` reads only the tracker's
snapshot (:class:`~pipeline.types.Tracks`) and the clusters of the same cycle. The ten
features of the source material come first, in column order (:data:`FEATURE_NAMES`):

==========================  ================================================================
bbox_width_m                width of the track's latest oriented box (short side) [m]
bbox_length_m               length of that box (long side) [m]
bbox_area_m2                width x length [m^2]
point_density_per_m2        points per box area of the cluster that updated the track this
                            cycle; NaN when no cluster did (a coasting track)
velocity_magnitude_mps      speed of the filtered velocity [m/s]
velocity_direction_rad      angle between the velocity and the line of sight from the object
                            to the robot, in [0, pi]: 0 heads straight at the robot, pi
                            straight away (robot-relative, independent of the map frame)
decel_estimate_mps2         least-squares deceleration of the filtered speed over the
                            tracker's window (``track.decel_window_s``), > 0 when slowing
track_age_frames            cycles since the track was born
size_variance_m2            variance of width plus that of length over the size window
is_near_reversal            1 when speed < ``predict.near_reversal_speed_mps`` (0.3 m/s) and
                            deceleration > ``predict.near_reversal_decel_mps2`` (0.4 m/s^2),
                            else 0
==========================  ================================================================

Five track-memory features follow (:data:`MEMORY_FEATURE_NAMES`). The source's ten describe the
current cycle only; on the simulator's held-out runs they leave two errors the tracker can
answer: a part-view of a forklift (a fork tip, a mast past an occluder: a third of the forklift
rows have a box under 0.8 m) looks like a person or a cart, and a forklift that stopped half a
second ago looks like one parked for a minute. With these five the held-out accuracy of the
three forklift states rises by 3-5 points (docs/findings/classification.md).

==========================  ================================================================
range_m                     distance from the robot to the track's position [m] (far
                            objects return fewer, sparser points)
max_width_m                 largest box width the track has shown since birth [m]
max_length_m                largest box length the track has shown since birth [m]
peak_speed_mps              highest filtered speed in the track's history
                            (``track.history_frames``) [m/s]
time_since_moving_s         seconds from the newest history entry at or above
                            ``predict.near_reversal_speed_mps`` to the newest entry; NaN
                            when no entry of the history is that fast
==========================  ================================================================

Two group features close the row (:data:`GROUP_FEATURE_NAMES`). A track's *partners* are the
other tracks of the cycle whose position is within :data:`GROUP_RADIUS_M` of its own and whose
velocity differs from its own by at most :data:`GROUP_SPEED_MPS`: parts that move together, as
the fork tines and the mast of one truck do when the clustering cuts them apart. (Both bounds
are part of the feature's definition, not configuration: the model is trained with them.)

==========================  ================================================================
group_length_m              the largest ``max_length_m`` among the track's partners [m]; 0
                            when it has none
group_gap_m                 distance from the track's position to its nearest partner's [m];
                            NaN when it has none
==========================  ================================================================

Six end features follow (:data:`END_FEATURE_NAMES`). A truck seen through a gap between racks,
or past a nearer object, shows only the part between the occluders: its clipped ends stay at
the occluders' edges while it moves, so its centroid, and with it the filtered velocity,
barely moves. The tracker keeps each update's cluster ends and whether a nearer return bounded
them (:mod:`pipeline.shape.ends`); these columns read the newest :data:`END_WINDOW` entries of
that history (NaN with fewer than :data:`END_MIN_ENTRIES` entries that have ends). End speeds
are least-squares speeds of an end's position over those entries [m/s].

==========================  ================================================================
ends_occluded               how many ends (0, 1, 2) of this cycle's cluster are occluded; NaN
                            for a coasting track
end_speed_max_mps           the faster of the two ends' speeds
free_end_speed_mps          the faster of the ends that stayed free over the whole window; NaN
                            when neither did
end_speed_min_mps           the slower of the two ends' speeds
end_occluded_share          share of occluded ends over the window, in [0, 1]
end_mid_speed_mps           speed of the midpoint between the ends (the centroid of a straight
                            view, measured rather than filtered)
==========================  ================================================================

Frames. The velocity must be the object's own (ground) velocity, so the tracker should run in
an odometry or map frame: :func:`pipeline.track.tracker.detections_in_frame` moves the
clusters' centroids there from the scanner frame with the scanner's pose. ``robot_xy_m`` is then the
robot's position in that frame. (Tracking in the moving robot's own frame adds the robot's velocity
to every track and its acceleration to every deceleration estimate; the training data use the
odometry frame.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config import PredictSection
from pipeline.types import BoolArray, Clusters, FloatArray, TrackFeatures, Tracks

__all__ = [
    "END_FEATURE_NAMES",
    "END_MIN_ENTRIES",
    "END_WINDOW",
    "FEATURE_NAMES",
    "GROUP_FEATURE_NAMES",
    "GROUP_RADIUS_M",
    "GROUP_SPEED_MPS",
    "MEMORY_FEATURE_NAMES",
    "N_FEATURES",
    "SOURCE_FEATURE_NAMES",
    "TrackFeatureExtractor",
    "feature_index",
    "track_features",
]

SOURCE_FEATURE_NAMES: tuple[str, ...] = (
    "bbox_width_m",
    "bbox_length_m",
    "bbox_area_m2",
    "point_density_per_m2",
    "velocity_magnitude_mps",
    "velocity_direction_rad",
    "decel_estimate_mps2",
    "track_age_frames",
    "size_variance_m2",
    "is_near_reversal",
)
MEMORY_FEATURE_NAMES: tuple[str, ...] = (
    "range_m",
    "max_width_m",
    "max_length_m",
    "peak_speed_mps",
    "time_since_moving_s",
)
GROUP_FEATURE_NAMES: tuple[str, ...] = ("group_length_m", "group_gap_m")
END_FEATURE_NAMES: tuple[str, ...] = (
    "ends_occluded",
    "end_speed_max_mps",
    "free_end_speed_mps",
    "end_speed_min_mps",
    "end_occluded_share",
    "end_mid_speed_mps",
)
FEATURE_NAMES: tuple[str, ...] = (
    SOURCE_FEATURE_NAMES + MEMORY_FEATURE_NAMES + GROUP_FEATURE_NAMES + END_FEATURE_NAMES
)
GROUP_RADIUS_M = 2.5
"""Largest distance between two partners' positions [m]. The simulated counterbalance truck's
tine tips are 1.15 m ahead of its mast and 3.45 m ahead of its rear: 2.5 m joins a tip to the
mast and the body's near faces, not to a truck in the next aisle (3.5 m wide)."""
GROUP_SPEED_MPS = 0.5
"""Largest difference between two partners' velocities [m/s]. Set, like the radius, before the
dev run that chose the two columns (docs/findings/classification.md); neither was tuned."""
END_WINDOW = 10
"""History entries (updates, newest last) the end features look back over: 1 s at 10 Hz."""
END_MIN_ENTRIES = 3
"""Fewest entries with ends in that window for an end speed; fewer give NaN."""
N_FEATURES = len(FEATURE_NAMES)


def feature_index(name: str) -> int:
    """Column of the feature called ``name`` (raises ``KeyError`` naming the known ones)."""
    try:
        return FEATURE_NAMES.index(name)
    except ValueError:
        raise KeyError(f"unknown feature {name!r}; known: {', '.join(FEATURE_NAMES)}") from None


def track_features(
    tracks: Tracks,
    clusters: Clusters | None,
    predict: PredictSection,
    robot_xy_m: tuple[float, float] = (0.0, 0.0),
) -> TrackFeatures:
    """The features of every track of ``tracks`` (module docstring), one row per track.

    ``clusters`` are the clusters of the same cycle (the ones the tracker's ``detection_index``
    refers to); without them the point density is NaN. ``robot_xy_m`` is the robot's position
    in the tracking frame. Served requirements: SR-CLS-1, SR-CLS-2.
    """
    n = tracks.n
    out: FloatArray = np.empty((n, N_FEATURES))
    width, length = tracks.width_m, tracks.length_m
    out[:, 0] = width
    out[:, 1] = length
    out[:, 2] = width * length
    density = np.full(n, np.nan)
    if clusters is not None:
        det = tracks.detection_index
        have = (det >= 0) & (det < clusters.n)
        density[have] = clusters.point_density_per_m2[det[have]]
    out[:, 3] = density
    vx, vy = tracks.state[:, 2], tracks.state[:, 3]
    speed = np.hypot(vx, vy)
    out[:, 4] = speed
    # Line of sight from the object to the robot; the angle between two vectors from the
    # cross and dot products (well conditioned at 0 and pi, unlike acos).
    lx = robot_xy_m[0] - tracks.state[:, 0]
    ly = robot_xy_m[1] - tracks.state[:, 1]
    out[:, 5] = np.abs(np.arctan2(vx * ly - vy * lx, vx * lx + vy * ly))
    decel = tracks.decel_mps2
    out[:, 6] = decel
    out[:, 7] = tracks.age_frames
    out[:, 8] = tracks.size_variance_m2
    out[:, 9] = (
        (speed < predict.near_reversal_speed_mps) & (decel > predict.near_reversal_decel_mps2)
    ).astype(np.float64)
    out[:, 10] = np.hypot(lx, ly)
    out[:, 11] = tracks.max_width_m
    out[:, 12] = tracks.max_length_m
    out[:, 13:15] = _speed_memory(tracks, predict.near_reversal_speed_mps)
    out[:, 15:17] = _group(tracks)
    out[:, 17:23] = _end_motion(tracks)
    return TrackFeatures(
        stamp_s=tracks.stamp_s, track_id=tracks.track_id, status=tracks.status, values=out
    )


def _speed_memory(tracks: Tracks, moving_mps: float) -> FloatArray:
    """Per track: the peak filtered speed of its history [m/s] and the seconds since its newest
    history entry at or above ``moving_mps`` (NaN when none is), shape (n, 2)."""
    out: FloatArray = np.full((tracks.n, 2), np.nan)
    speed, stamp = tracks.history_speed_mps, tracks.history_t_s
    have = ~np.isnan(speed)
    any_entry = have.any(axis=1)
    out[any_entry, 0] = np.where(have, speed, -np.inf)[any_entry].max(axis=1)
    moving = have & (speed >= moving_mps)
    seen = moving.any(axis=1)
    last_moving = np.where(moving, stamp, -np.inf)[seen].max(axis=1)
    newest = np.where(have, stamp, -np.inf)[seen].max(axis=1)
    out[seen, 1] = newest - last_moving
    return out


def _group(tracks: Tracks) -> FloatArray:
    """Per track: the largest ``max_length_m`` of its partners (0 when none) and the distance to
    its nearest partner (NaN when none), shape (n, 2) (module docstring)."""
    x, y, vx, vy = (tracks.state[:, k] for k in range(4))
    gap = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    partner = (
        (gap <= GROUP_RADIUS_M)
        & (np.hypot(vx[:, None] - vx[None, :], vy[:, None] - vy[None, :]) <= GROUP_SPEED_MPS)
        & ~np.eye(tracks.n, dtype=bool)
    )
    out: FloatArray = np.full((tracks.n, 2), np.nan)
    out[:, 0] = np.where(partner, tracks.max_length_m[None, :], 0.0).max(axis=1, initial=0.0)
    some = partner.any(axis=1)
    out[some, 1] = np.where(partner, gap, np.inf)[some].min(axis=1, initial=np.inf)
    return out


def _end_motion(tracks: Tracks) -> FloatArray:
    """Per track, the :data:`END_FEATURE_NAMES` columns, shape (n, 6) (module docstring)."""
    n = tracks.n
    out: FloatArray = np.full((n, len(END_FEATURE_NAMES)), np.nan)
    updated = tracks.detection_index >= 0
    out[updated, 0] = tracks.history_end_occluded[updated, -1, :].sum(axis=1)
    w = min(END_WINDOW, tracks.history_t_s.shape[1])
    t = tracks.history_t_s[:, -w:]
    xy = tracks.history_end_xy_m[:, -w:, :]
    occ = tracks.history_end_occluded[:, -w:, :]
    valid = ~(np.isnan(t) | np.isnan(xy).any(axis=2) | np.isnan(occ).any(axis=2))
    k = valid.sum(axis=1)
    kk = np.maximum(k, 1)
    # Least-squares velocity of each end coordinate over the valid entries.
    tc = np.where(valid, t - (np.where(valid, t, 0.0).sum(axis=1) / kk)[:, None], 0.0)
    sxx = (tc * tc).sum(axis=1)
    mean = np.where(valid[:, :, None], xy, 0.0).sum(axis=1) / kk[:, None]
    dev = np.where(valid[:, :, None], xy - mean[:, None, :], 0.0)
    vel = (tc[:, :, None] * dev).sum(axis=1) / np.where(sxx > 0.0, sxx, 1.0)[:, None]
    speed = np.hypot(vel[:, 0::2], vel[:, 1::2])  # (n, 2): first end, last end
    ok = k >= END_MIN_ENTRIES
    out[ok, 1] = speed[ok].max(axis=1)
    free: BoolArray = ~np.any(valid[:, :, None] & (occ > 0.0), axis=1)
    some_free = ok & free.any(axis=1)
    out[some_free, 2] = np.where(free, speed, -np.inf)[some_free].max(axis=1)
    out[ok, 3] = speed[ok].min(axis=1)
    out[ok, 4] = np.where(valid[:, :, None], occ, 0.0).sum(axis=(1, 2))[ok] / (2.0 * k[ok])
    mid = 0.5 * (vel[:, 0:2] + vel[:, 2:4])
    out[ok, 5] = np.hypot(mid[ok, 0], mid[ok, 1])
    return out


@dataclass(frozen=True)
class TrackFeatureExtractor:
    """The feature role's default: :func:`track_features` with the ``predict`` section."""

    config: PredictSection

    def features(
        self, tracks: Tracks, clusters: Clusters | None, robot_xy_m: tuple[float, float]
    ) -> TrackFeatures:
        """The feature row of every track (robot position in the tracking frame)."""
        return track_features(tracks, clusters, self.config, robot_xy_m)
