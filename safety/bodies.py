"""Where an object's body is now, from its cluster's outline rather than a disc (SR-AVL-6).

The half-diagonal disc about a track's position (:func:`safety.obstacles.bodies_now`, the still
zones' fallback) covers the aisle for a rack bay 3.6 m long: a new rack cluster (a tentative
track, of unknown motion) or a rack whose cluster was not seen this cycle (it grew past the
cluster filter's 200 points, or split) then touches the robot's footprint, and the robot stops
for structure it has been driving along. Two refinements, each the argument the still zones
already rest on (an object's returns this cycle are where its body is; its cluster's convex hull
grown by ``predict.velocity_sigmas`` position sigmas holds them):

* **seen this cycle** (:func:`hull_bodies`): an object of unknown motion whose track was updated
  by a cluster this cycle is that cluster's hull grown by its position uncertainty; the
  Euclidean distance to it is what the governor reads (closing at the worst class speed in any
  direction, as before);
* **still and not seen** (:class:`StillHulls`): a still object (stationary or static class)
  whose track coasts keeps the hull it was last seen with, moved by the track's displacement
  since then and grown by its current (coasting, so growing) position uncertainty, for at most
  ``track.dormant_after_misses`` cycles of coasting (a dormant track gets no prediction).

Hulls are in the tracking frame (the clusters' robot frame moved by the pose).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.config import PredictSection
from pipeline.frames import Pose, to_parent
from pipeline.track.kalman import largest_std
from pipeline.types import (
    BoolArray,
    Clusters,
    ConvexPolygons,
    FloatArray,
    IntArray,
    PredictionMode,
    Predictions,
    Tracks,
)
from safety.geometry.envelopes import grown_polygons
from safety.obstacles import with_columns

__all__ = ["StillHulls", "cluster_hulls", "hull_bodies"]


def cluster_hulls(clusters: Clusters, index: IntArray, pose: Pose) -> FloatArray:
    """Hulls of clusters ``index`` in the tracking frame, (m, K, 2), each padded by repeating
    its last vertex."""
    start, size = clusters.hull_offsets[index], np.diff(clusters.hull_offsets)[index]
    width = int(size.max(initial=1))
    pick = start[:, None] + np.minimum(np.arange(width)[None, :], size[:, None] - 1)
    hx, hy = to_parent(pose, clusters.hull_x_m[pick], clusters.hull_y_m[pick])
    hulls: FloatArray = np.stack([hx, hy], axis=2)
    return hulls


def _seen(pred: Predictions, tracks: Tracks, clusters: Clusters) -> tuple[IntArray, IntArray]:
    """Per prediction row: its track's row and the cluster that updated it this cycle (-1)."""
    row = np.searchsorted(tracks.track_id, pred.track_id)
    det = tracks.detection_index[row]
    det = np.where((det >= 0) & (det < clusters.n), det, -1)
    return row, det


def hull_bodies(
    rows: BoolArray,
    bodies: ConvexPolygons,
    pred: Predictions,
    tracks: Tracks,
    clusters: Clusters,
    pose: Pose,
    predict_section: PredictSection,
) -> ConvexPolygons:
    """``bodies`` (one per row of ``rows``) with the rows seen this cycle replaced by their
    cluster's hull grown by their position uncertainty (module docstring)."""
    track_row, det = _seen(pred, tracks, clusters)
    sel = np.flatnonzero(rows)
    seen = det[sel] >= 0
    if not seen.any():
        return bodies
    which = sel[seen]
    sigma = predict_section.velocity_sigmas * largest_std(
        tracks.covariance[track_row[which], :2, :2]
    )
    hulls = cluster_hulls(clusters, det[which], pose)
    grown = grown_polygons(hulls, sigma, predict_section.disc_sides)
    return with_columns(bodies, np.flatnonzero(seen), grown)


@dataclass
class StillHulls:
    """The last hull of every still track seen, for the cycles it coasts (module docstring).

    ``max_coast`` bounds how many cycles a hull is used without its track being seen again.
    """

    max_coast: int
    _hull: dict[int, FloatArray] = field(default_factory=dict)
    _at: dict[int, FloatArray] = field(default_factory=dict)
    _coast: dict[int, int] = field(default_factory=dict)

    def reset(self) -> None:
        """Forget every hull."""
        self._hull.clear()
        self._at.clear()
        self._coast.clear()

    def zones(
        self,
        zones: ConvexPolygons,
        pred: Predictions,
        tracks: Tracks,
        clusters: Clusters,
        pose: Pose,
        predict_section: PredictSection,
    ) -> ConvexPolygons:
        """``zones`` (one per prediction row) with each coasting still row's disc replaced by
        its remembered hull; remembers the hulls of the still rows seen this cycle."""
        track_row, det = _seen(pred, tracks, clusters)
        still = pred.mode == int(PredictionMode.FOOTPRINT)
        live = {int(t) for t in tracks.track_id}
        for tid in [t for t in self._hull if t not in live]:
            self._forget(tid)
        seen = np.flatnonzero(still & (det >= 0))
        if seen.size:
            hulls = cluster_hulls(clusters, det[seen], pose)
            for k, row in enumerate(seen):
                tid = int(pred.track_id[row])
                self._hull[tid] = hulls[k]
                self._at[tid] = tracks.state[track_row[row], :2].copy()
                self._coast[tid] = 0
        coasting = [
            int(r) for r in np.flatnonzero(still & (det < 0)) if int(pred.track_id[r]) in self._hull
        ]
        used: list[int] = []
        moved: list[FloatArray] = []
        for r in coasting:
            tid = int(pred.track_id[r])
            self._coast[tid] += 1
            if self._coast[tid] > self.max_coast:
                self._forget(tid)
                continue
            shift = tracks.state[track_row[r], :2] - self._at[tid]
            used.append(r)
            moved.append(self._hull[tid] + shift)
        if not used:
            return zones
        idx = np.array(used, dtype=np.int64)
        width = max(h.shape[0] for h in moved)
        padded = np.stack(
            [np.concatenate([h, np.repeat(h[-1:], width - h.shape[0], 0)]) for h in moved]
        )
        sigma = predict_section.velocity_sigmas * largest_std(
            tracks.covariance[track_row[idx], :2, :2]
        )
        grown = grown_polygons(padded, sigma, predict_section.disc_sides)
        return with_columns(zones, idx, grown)

    def _forget(self, tid: int) -> None:
        self._hull.pop(tid, None)
        self._at.pop(tid, None)
        self._coast.pop(tid, None)
