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
  ``track.dormant_after_misses`` cycles of coasting (a dormant track gets no prediction);
* **on the site's map** (:func:`mapped_rows`, SR-AVL-8): an object of unknown motion whose
  cluster this cycle lies wholly on the static map (every return covered,
  :func:`pipeline.static_map.clusters_on_map`) is the mapped structure, which does not move:
  the governor reads the distance along the path to its hull body, as for a still object,
  instead of the distance in any direction; its closing speed and margin stay those of an
  object of unknown motion. Nor is a track last updated by such a cluster (this cycle, or
  coasting since, :class:`OnMapMemory`) held to the object-speed domain
  (:func:`safety.obstacles.faster_than_the_domain`): a fragment of a rack face whose visible
  part slides along the face as the robot drives by is not an object moving that fast.

Hulls are in the tracking frame (the clusters' robot frame moved by the pose).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.config import PredictSection
from pipeline.frames import Pose, to_parent
from pipeline.static_map import StaticMap, clusters_on_map
from pipeline.track.kalman import largest_std
from pipeline.types import (
    BoolArray,
    Clusters,
    ConvexPolygons,
    FloatArray,
    IntArray,
    PredictionMode,
    Predictions,
    ScanPoints,
    Tracks,
)
from safety.geometry.envelopes import grown_polygons
from safety.obstacles import bodies_now, with_columns

__all__ = [
    "OnMapMemory",
    "SeenHulls",
    "StillHulls",
    "cluster_hulls",
    "hull_bodies",
    "mapped_rows",
    "mapped_zones",
    "still_zones",
    "tracks_on_map",
]


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
    return row, _updating_cluster(tracks, clusters)[row]


def _updating_cluster(tracks: Tracks, clusters: Clusters) -> IntArray:
    """Per track: the cluster that updated it this cycle, or -1."""
    det = tracks.detection_index
    found: IntArray = np.where((det >= 0) & (det < clusters.n), det, -1)
    return found


@dataclass(frozen=True)
class SeenHulls:
    """The outline bodies of the prediction rows seen this cycle, grown in one batch (SR-AVL-6):
    each row's cluster hull (tracking frame) grown by ``predict.velocity_sigmas`` times its
    track's larger position sigma. The still zones, the unknown rows' bodies and the mapped
    zones all read theirs from here (one hull batch a cycle instead of one each).

    ``column`` (per prediction row) is the row's polygon in ``polygons``, -1 where the row was
    not seen this cycle or not asked for.
    """

    column: IntArray
    polygons: ConvexPolygons

    @classmethod
    def of(
        cls,
        rows: BoolArray,
        pred: Predictions,
        tracks: Tracks,
        clusters: Clusters,
        pose: Pose,
        predict_section: PredictSection,
    ) -> SeenHulls:
        """The bodies of the prediction ``rows`` whose track a cluster updated this cycle."""
        track_row, det = _seen(pred, tracks, clusters)
        which = np.flatnonzero(rows & (det >= 0))
        column = np.full(det.shape, -1, dtype=np.int64)
        column[which] = np.arange(which.size)
        sigma = predict_section.velocity_sigmas * largest_std(
            tracks.covariance[track_row[which], :2, :2]
        )
        hulls = cluster_hulls(clusters, det[which], pose)
        return cls(column, grown_polygons(hulls, sigma, predict_section.disc_sides))

    def take(self, rows: IntArray) -> ConvexPolygons:
        """The bodies of prediction ``rows`` (each seen and asked for), padded to their own
        largest vertex count, as a batch of just these rows would be."""
        polygons = self.polygons.take(self.column[rows])
        k = int(polygons.counts.max(initial=3))
        return ConvexPolygons(polygons.vertices_m[:, :k], polygons.counts, polygons.slack_m)


def still_zones(
    pred: Predictions, seen: SeenHulls, predict_section: PredictSection
) -> ConvexPolygons:
    """Predicted zones (no margin), tracking frame: each row's reach region grown by its
    body disc; a still object (footprint mode) seen this cycle is its cluster's convex hull
    grown by its position uncertainty instead (a rack bay's disc would cover the aisle)."""
    zones = grown_polygons(pred.reach_xy_m, pred.body_radius_m, predict_section.disc_sides)
    still = (pred.mode == int(PredictionMode.FOOTPRINT)) & (seen.column >= 0)
    if not still.any():
        return zones
    idx = np.flatnonzero(still)
    return with_columns(zones, idx, seen.take(idx))


def hull_bodies(rows: BoolArray, bodies: ConvexPolygons, seen: SeenHulls) -> ConvexPolygons:
    """``bodies`` (one per row of ``rows``) with the rows seen this cycle replaced by their
    cluster's hull grown by their position uncertainty (module docstring)."""
    sel = np.flatnonzero(rows)
    hit = seen.column[sel] >= 0
    if not hit.any():
        return bodies
    return with_columns(bodies, np.flatnonzero(hit), seen.take(sel[hit]))


def tracks_on_map(
    tracks: Tracks, clusters: Clusters, points: ScanPoints, pose: Pose, static_map: StaticMap
) -> BoolArray:
    """Per track: updated this cycle by a cluster lying wholly on ``static_map`` (module
    docstring; points and clusters in the robot frame, the map in the tracking frame)."""
    det = _updating_cluster(tracks, clusters)
    x_m, y_m = to_parent(pose, points.x_m, points.y_m)
    on = clusters_on_map(static_map, clusters.point_labels, x_m, y_m, clusters.n)
    found: BoolArray = (det >= 0) & on[np.maximum(det, 0)]
    return found


def mapped_rows(rows: BoolArray, pred: Predictions, tracks: Tracks, on_map: BoolArray) -> BoolArray:
    """The prediction rows among ``rows`` whose track is ``on_map`` (:func:`tracks_on_map`)."""
    found: BoolArray = rows & on_map[np.searchsorted(tracks.track_id, pred.track_id)]
    return found


def mapped_zones(
    zones: ConvexPolygons,
    mapped: BoolArray,
    pred: Predictions,
    tracks: Tracks,
    seen: SeenHulls,
    sides: int,
) -> ConvexPolygons:
    """``zones`` (one per prediction row) with each ``mapped`` row's replaced by its cluster's
    hull grown by its position uncertainty (the body of :func:`hull_bodies`), or its body disc
    (``sides`` sides) while it coasts."""
    if not mapped.any():
        return zones
    hulls = hull_bodies(mapped, bodies_now(pred, tracks, mapped, sides), seen)
    return with_columns(zones, np.flatnonzero(mapped), hulls)


@dataclass
class OnMapMemory:
    """Per track, whether the cluster that last updated it lay wholly on the map (SR-AVL-8):
    a track coasting since such an update was last seen as the fixed structure."""

    _last: dict[int, bool] = field(default_factory=dict)

    def update(self, track_id: IntArray, detection_index: IntArray, on_map: BoolArray) -> BoolArray:
        """Per track (``Tracks.track_id``, ``Tracks.detection_index``): updated this cycle by a
        cluster on the map (``on_map``, from :func:`tracks_on_map`), or not updated since such
        an update; forgets tracks no longer listed."""
        updated = detection_index >= 0
        last: dict[int, bool] = {}
        out = np.zeros(track_id.shape, dtype=bool)
        for k, tid in enumerate(track_id.tolist()):
            last[tid] = bool(on_map[k]) if updated[k] else self._last.get(tid, False)
            out[k] = last[tid]
        self._last = last
        return out


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
