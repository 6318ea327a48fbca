"""Heading errors of the shape estimators and of the tracks on ray-cast apron scans, by what
the view shows and by range (SR-TRK-7).

Per scan and per cluster that one object owns (at least 80 % of its points), of the box-like
kinds (tug, covered baggage cart, platform cart, robot, container):

* **view**: what the cluster holds of the object's true rectangle (its model's bounding box at
  its true pose): a face is *seen* when at least 6 of the cluster's points (at their exact,
  noise-free positions) lie on it (nearest face) spanning at least 0.3 m. ``two faces``, ``one
  face``, or ``sliver`` (no face seen so: a grazing view, a far or mostly hidden object). It
  is the cluster, not all the object's returns, that counts: at a grazing angle the far face's
  returns are sparser than DBSCAN's reach and split off;
* **range**: scanner to the object's centre;
* **orientation error**: the estimate's rectangle against the true one, modulo 90 deg (what a
  rectangle fit can know); **axis error**: the estimate's long side against the true heading,
  modulo 180 deg (containers, nearly square, are left out of this one).

Track headings (:attr:`pipeline.track.tracker.Tracker.last_headings`) are compared with the
true heading modulo 360 deg once the flip is resolved, modulo 180 deg before; beside them, the
heading the prediction uses today for a near-reversal cone
(:func:`pipeline.predict.confirmed_heading_rad`: the centroid history's direction, else a
certain velocity's, else unknown), modulo 360 deg.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pipeline.config import PredictSection, SafecaseConfig, overridden
from pipeline.frames import checked_pose
from pipeline.perception import Perception, Tracked
from pipeline.predict import confirmed_heading_rad
from pipeline.shape.box import BoxShapes
from pipeline.shape.lshape import lshape_fit
from pipeline.sources.sim.simulation import SimFrame
from pipeline.sources.sim.truth import KIND_NAMES, ScanTruth
from pipeline.track.kalman import largest_std
from pipeline.types import Clusters, FloatArray, Frame, IntArray, Partition, TrackStatus
from properties.airside_runs import cluster_owners

__all__ = [
    "BOX_KINDS",
    "RANGE_BINS_M",
    "VIEWS",
    "HeadingSamples",
    "angle_error_deg",
    "heading_samples",
    "view_of",
]

BOX_KINDS = ("baggage_tug", "dolly", "cart", "amr", "uld_container")
SQUARE_KINDS = ("uld_container",)
VIEWS = ("two faces", "one face", "sliver")
RANGE_BINS_M = (0.0, 5.0, 10.0, 15.0, 30.0)
MIN_FACE_POINTS = 6
MIN_FACE_SPAN_M = 0.3


def angle_error_deg(estimate: FloatArray, truth: FloatArray, period_rad: float) -> FloatArray:
    """|estimate - truth| modulo ``period_rad``, folded into [0, period / 2], in degrees."""
    d = np.mod(estimate - truth + 0.5 * period_rad, period_rad) - 0.5 * period_rad
    return np.degrees(np.abs(d))


def view_of(
    xy_m: FloatArray,
    centre: tuple[float, float],
    heading_rad: float,
    length_m: float,
    width_m: float,
) -> str:
    """What the returns ``xy_m`` (k, 2) show of the rectangle (module docstring)."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    dx, dy = xy_m[:, 0] - centre[0], xy_m[:, 1] - centre[1]
    u, v = c * dx + s * dy, -s * dx + c * dy
    # Nearest face: 0 front (+u), 1 back, 2 left (+v), 3 right.
    gap = np.stack([0.5 * length_m - u, 0.5 * length_m + u, 0.5 * width_m - v, 0.5 * width_m + v])
    face = np.argmin(np.abs(gap), axis=0)
    along = np.where(face < 2, v, u)
    seen = 0
    for f in range(4):
        on = face == f
        if np.count_nonzero(on) >= MIN_FACE_POINTS and np.ptp(along[on]) >= MIN_FACE_SPAN_M:
            seen += 1
    return VIEWS[0] if seen >= 2 else VIEWS[1] if seen == 1 else VIEWS[2]


@dataclass
class HeadingSamples:
    """Per-cluster samples (view, range bin, kind, errors) and per-track samples."""

    view: list[str] = field(default_factory=list)
    range_bin: list[int] = field(default_factory=list)
    kind: list[str] = field(default_factory=list)
    box_orientation_deg: list[float] = field(default_factory=list)
    lshape_orientation_deg: list[float] = field(default_factory=list)
    box_axis_deg: list[float] = field(default_factory=list)
    lshape_axis_deg: list[float] = field(default_factory=list)
    accepted: list[bool] = field(default_factory=list)
    track_speed_mps: list[float] = field(default_factory=list)
    track_resolved: list[bool] = field(default_factory=list)
    track_error_deg: list[float] = field(default_factory=list)
    cone_error_deg: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every list as an array."""
        return {name: np.asarray(value) for name, value in vars(self).items()}


def heading_samples(
    config: SafecaseConfig, frames: Sequence[SimFrame], samples: HeadingSamples
) -> None:
    """Add the samples of one run (its frames, in order) to ``samples``; tracks come from the
    L-shape chain ``config`` describes (``cluster.shape_estimator`` forced to "lshape")."""
    chain_config = overridden(config, {"cluster": {"shape_estimator": "lshape"}})
    chain = Perception.from_config(chain_config, tracking_only=True)
    box = BoxShapes(config.cluster)
    for sim_frame in frames:
        truth = sim_frame.truth
        frame = Frame(
            sim_frame.scan, sim_frame.observation.stamp_s, pose=checked_pose(truth.scanner_pose)
        )
        tracked = chain.track(frame)
        points, clusters = tracked.points, tracked.clusters
        labels = clusters.point_labels
        boxes = box.clusters(points, _partition(clusters))
        fit = lshape_fit(points.x_m, points.y_m, labels, clusters.n, chain_config.cluster)
        owner, share = cluster_owners(points, labels, clusters.n, truth)
        x0, y0, yaw = (float(v) for v in truth.scanner_pose)
        r_true = truth.beams.true_range_m[points.beam_index]
        a_true = sim_frame.scan.angles_rad[points.beam_index] + yaw
        exact = np.stack([x0 + r_true * np.cos(a_true), y0 + r_true * np.sin(a_true)], axis=1)
        ids = truth.object_id.tolist()
        for k in range(clusters.n):
            if share[k] < 0.8 or int(owner[k]) not in ids:
                continue
            i = ids.index(int(owner[k]))
            kind = KIND_NAMES[int(truth.kind[i])]
            if kind not in BOX_KINDS:
                continue
            mine = exact[labels == k]
            centre = (float(truth.x_m[i]), float(truth.y_m[i]))
            h = float(truth.heading_rad[i])
            samples.view.append(
                view_of(mine, centre, h, float(truth.length_m[i]), float(truth.width_m[i]))
            )
            rng_m = math.hypot(centre[0] - truth.scanner_pose[0], centre[1] - truth.scanner_pose[1])
            samples.range_bin.append(int(np.searchsorted(RANGE_BINS_M, rng_m, side="right") - 1))
            samples.kind.append(kind)
            box_h = float(boxes.heading_rad[k]) + yaw
            ls_h = (
                float(fit.heading_rad[k]) if fit.accepted[k] else float(boxes.heading_rad[k])
            ) + yaw
            samples.box_orientation_deg.append(
                float(angle_error_deg(np.array(box_h), np.array(h), 0.5 * math.pi))
            )
            samples.lshape_orientation_deg.append(
                float(angle_error_deg(np.array(ls_h), np.array(h), 0.5 * math.pi))
            )
            square = kind in SQUARE_KINDS
            samples.box_axis_deg.append(
                math.nan
                if square
                else float(angle_error_deg(np.array(box_h), np.array(h), math.pi))
            )
            samples.lshape_axis_deg.append(
                math.nan if square else float(angle_error_deg(np.array(ls_h), np.array(h), math.pi))
            )
            samples.accepted.append(bool(fit.accepted[k]))
        _track_samples(tracked, owner, share, truth, config.predict, samples)


def _partition(clusters: Clusters) -> Partition:
    """The partition the clusters were made from (to shape them again with the box)."""
    return Partition(clusters.stamp_s, clusters.point_labels, clusters.n, clusters.counts)


def _track_samples(
    tracked: Tracked,
    owner: IntArray,
    share: FloatArray,
    truth: ScanTruth,
    predict: PredictSection,
    samples: HeadingSamples,
) -> None:
    """Track headings against the truth, and the prediction's own heading for comparison."""
    tracks, headings = tracked.tracks, tracked.headings
    if headings is None or tracks.n == 0:
        return
    speed = np.hypot(tracks.state[:, 2], tracks.state[:, 3])
    sigma_v = largest_std(tracks.covariance[:, 2:, 2:])
    cone = confirmed_heading_rad(tracks, speed, sigma_v, predict)
    ids = truth.object_id.tolist()
    for j in range(tracks.n):
        det = int(tracks.detection_index[j])
        if det < 0 or tracks.status[j] != TrackStatus.CONFIRMED or share[det] < 0.8:
            continue
        if int(owner[det]) not in ids or np.isnan(headings.heading_rad[j]):
            continue
        i = ids.index(int(owner[det]))
        kind = KIND_NAMES[int(truth.kind[i])]
        if kind not in BOX_KINDS or kind in SQUARE_KINDS:
            continue
        period = 2.0 * math.pi if headings.resolved[j] else math.pi
        true_h = truth.heading_rad[i : i + 1]
        samples.track_speed_mps.append(float(truth.speed_mps[i]))
        samples.track_resolved.append(bool(headings.resolved[j]))
        samples.track_error_deg.append(
            float(angle_error_deg(headings.heading_rad[j : j + 1], true_h, period)[0])
        )
        samples.cone_error_deg.append(
            float(angle_error_deg(cone[j : j + 1], true_h, 2.0 * math.pi)[0])
        )
