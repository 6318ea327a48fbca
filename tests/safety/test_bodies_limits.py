"""Outline bodies and the mapped structure, function by function (SR-AVL-6, SR-AVL-8).

The mutation campaign (SR-EVD-5; docs/findings/mutation.md) found the remembered hulls of
coasting still objects and the mapped zones exercised only by the closed-loop campaigns, which
mutants are not run against; and the wiring of the rest unwatched: which cluster updated a
track, which position sigma grows a hull, which track a row belongs to. Every body here is
checked against the cluster's own returns with shapely: the polygon holds each return at least
the grown distance inside its boundary (less the polygon's chord), so a hull of the wrong
cluster, in the wrong frame or grown by the wrong sigma fails.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from pipeline.cluster.dbscan import cluster_scan
from pipeline.config import default_config
from pipeline.frames import Pose, to_parent
from pipeline.static_map import StaticMap
from pipeline.track.kalman import largest_std
from pipeline.types import (
    Clusters,
    ConvexPolygons,
    FloatArray,
    PredictionMode,
    Predictions,
    Scan,
    ScanPoints,
    Tracks,
)
from properties.fusion_cases import make_tracks
from safety.bodies import (
    OnMapMemory,
    SeenHulls,
    StillHulls,
    cluster_hulls,
    hull_bodies,
    mapped_rows,
    mapped_zones,
    still_zones,
    tracks_on_map,
)
from safety.geometry.envelopes import grown_polygons
from safety.obstacles import bodies_now

BODIES = ["safety/bodies.py"]
CONFIG = default_config()
PS = CONFIG.predict
K = PS.velocity_sigmas
SIDES = PS.disc_sides
N_BEAMS = 1080
ANGLES = np.linspace(-math.pi, math.pi, N_BEAMS, endpoint=False)
POSE: Pose = (1.0, -0.5, 0.3)
FOOTPRINT, CONE = int(PredictionMode.FOOTPRINT), int(PredictionMode.CONE)


def _scan() -> tuple[ScanPoints, Clusters]:
    """Two clusters in the robot frame: an arc at 4 m (beams 500-539), one at 6 m (700-740)."""
    ranges = np.full(N_BEAMS, np.nan)
    ranges[500:540] = 4.0
    ranges[700:741] = 6.0
    points, clusters = cluster_scan(Scan(0.0, ANGLES, ranges), CONFIG)
    assert clusters.n == 2
    assert math.hypot(clusters.centroid_x_m[0], clusters.centroid_y_m[0]) < 5.0  # the 4 m arc
    return points, clusters


def _returns(points: ScanPoints, clusters: Clusters, k: int, pose: Pose) -> FloatArray:
    """The returns of cluster ``k`` in the tracking frame, (n, 2)."""
    mine = clusters.point_labels == k
    x, y = to_parent(pose, points.x_m[mine], points.y_m[mine])
    return np.stack([x, y], axis=1)


def _tracks(ids: list[int], xy: FloatArray, det: list[int], sigma_m: list[float]) -> Tracks:
    """Tracks ``ids`` at ``xy`` updated by clusters ``det`` (-1: coasting), each with position
    sigmas (``sigma_m``, ``sigma_m / 2``) and a large velocity variance."""
    tracks = make_tracks(0.0, xy)
    cov = np.zeros((len(ids), 4, 4))
    for i, s in enumerate(sigma_m):
        cov[i] = np.diag([s * s, 0.25 * s * s, 9.0, 9.0])
    return replace(tracks, track_id=np.array(ids), detection_index=np.array(det), covariance=cov)


def _predictions(track_id: list[int], mode: list[int]) -> Predictions:
    """Rows of ``track_id`` in ``mode``, each a point region with a 0.3 m body."""
    m = len(track_id)
    return Predictions(
        stamp_s=0.0,
        horizon_s=1.0,
        track_id=np.array(track_id),
        mode=np.array(mode),
        class_index=np.zeros(m, dtype=np.int64),
        confidence=np.ones(m),
        near_reversal=np.zeros(m, dtype=bool),
        person_compatible=np.zeros(m, dtype=bool),
        speed_mps=np.zeros(m),
        heading_rad=np.full(m, math.nan),
        body_radius_m=np.full(m, 0.3),
        reach_xy_m=np.zeros((m, 3, 2)),
    )


def _polygon(polygons: ConvexPolygons, j: int) -> shapely.Polygon:
    count = int(polygons.counts[j])
    return shapely.Polygon(polygons.vertices_m[:, :count, j].T)


def _holds(polygon: shapely.Polygon, returns: FloatArray, grown_m: float) -> None:
    """``polygon`` holds every return at least ``grown_m`` (less the disc's chord) inside, and
    reaches no further than ``grown_m`` (plus rounding) beyond the returns' hull."""
    inside = grown_m * math.cos(math.pi / SIDES) - 1e-9
    for x, y in returns:
        point = shapely.Point(x, y)
        assert polygon.contains(point)
        assert polygon.exterior.distance(point) >= inside, (
            polygon.exterior.distance(point),
            inside,
        )
    hull = shapely.MultiPoint([tuple(p) for p in returns]).convex_hull
    assert polygon.hausdorff_distance(hull) <= grown_m / math.cos(math.pi / SIDES) + 1e-6


def _same(a: ConvexPolygons, i: int, b: ConvexPolygons, j: int) -> bool:
    return bool(_polygon(a, i).hausdorff_distance(_polygon(b, j)) < 1e-12)


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_a_row_seen_this_cycle_is_its_cluster_grown_by_its_largest_position_sigma() -> None:
    """Tracks 4 (cluster 0), 7 (coasting) and 9 (a detection index past the clusters: not a
    cluster) in rows ordered 9, 4, 7: only track 4's row becomes a hull, grown by K times its
    larger position sigma (0.2 m); the others keep their discs."""
    points, clusters = _scan()
    xy = np.array([[0.0, 0.0], [2.0, 2.0], [3.0, -3.0]])
    tracks = _tracks([4, 7, 9], xy, [0, -1, clusters.n], [0.2, 0.2, 0.2])
    pred = _predictions([9, 4, 7], [CONE, CONE, CONE])
    rows = np.ones(3, dtype=bool)
    discs = bodies_now(pred, tracks, rows, SIDES)
    seen = SeenHulls.of(rows, pred, tracks, clusters, POSE, PS)
    assert seen.column.tolist() == [-1, 0, -1]
    out = hull_bodies(rows, discs, seen)
    _holds(_polygon(out, 1), _returns(points, clusters, 0, POSE), K * 0.2)
    assert _same(out, 0, discs, 0)
    assert _same(out, 2, discs, 2)
    assert hull_bodies(~rows, discs, seen) is discs
    # a row not asked for is not built
    assert hull_bodies(rows, discs, SeenHulls.of(~rows, pred, tracks, clusters, POSE, PS)) is discs


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_a_body_from_the_cycle_s_batch_equals_its_own_batch() -> None:
    """The cycle grows every asked-for hull in one batch; what each user takes from it (any
    subset, any order) is bit for bit the batch of just those rows: vertices, padding, counts,
    slack; an empty take is an empty batch."""
    _, clusters = _scan()
    xy = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, -1.0], [3.0, 0.0]])
    tracks = _tracks([3, 4, 7, 9], xy, [0, 1, 1, -1], [0.05, 0.3, 0.2, 0.1])
    pred = _predictions([9, 7, 4, 3], [FOOTPRINT, CONE, FOOTPRINT, CONE])
    seen = SeenHulls.of(np.ones(4, dtype=bool), pred, tracks, clusters, POSE, PS)
    assert seen.column.tolist() == [-1, 0, 1, 2]
    row = np.searchsorted(tracks.track_id, pred.track_id)
    for rows in ([1], [2], [3], [3, 1], [1, 2, 3], [2, 3], []):
        idx = np.array(rows, dtype=np.int64)
        det = tracks.detection_index[row[idx]]
        sigma = K * largest_std(tracks.covariance[row[idx], :2, :2])
        alone = grown_polygons(cluster_hulls(clusters, det, POSE), sigma, SIDES)
        got = seen.take(idx)
        np.testing.assert_array_equal(got.vertices_m, alone.vertices_m)
        np.testing.assert_array_equal(got.counts, alone.counts)
        np.testing.assert_array_equal(got.slack_m, alone.slack_m)


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_a_still_object_seen_this_cycle_is_zoned_by_its_cluster_s_hull() -> None:
    """Predicted zones (safety.bodies.still_zones) of five tracks: still (footprint) rows
    updated by cluster 0 and by cluster 1 become that cluster's hull in the tracking frame,
    grown by K times the track's larger position sigma (0.1 m and 0.3 m); a cone row updated by
    cluster 0, a still row coasting and one whose detection index is past the clusters keep
    their reach region grown by the body disc."""
    points, clusters = _scan()
    offsets = clusters.hull_offsets
    assert np.diff(offsets)[0] != np.diff(offsets)[1]  # hulls of different vertex counts
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0]])
    tracks = _tracks([2, 5, 7, 9, 11], xy, [0, 1, 0, -1, clusters.n], [0.1, 0.3, 0.1, 0.1, 0.1])
    pred = _predictions([2, 5, 7, 9, 11], [FOOTPRINT, FOOTPRINT, CONE, FOOTPRINT, FOOTPRINT])
    zones = still_zones(
        pred, SeenHulls.of(np.ones(5, dtype=bool), pred, tracks, clusters, POSE, PS), PS
    )
    discs = grown_polygons(pred.reach_xy_m, pred.body_radius_m, SIDES)
    assert zones.n == 5
    for j, k, sigma in ((0, 0, 0.1), (1, 1, 0.3)):
        hull = slice(int(offsets[k]), int(offsets[k + 1]))
        hx, hy = to_parent(POSE, clusters.hull_x_m[hull], clusters.hull_y_m[hull])
        want = grown_polygons(np.stack([hx, hy], axis=1)[None], np.array([K * sigma]), SIDES)
        assert _same(zones, j, want, 0), j
        _holds(_polygon(zones, j), _returns(points, clusters, k, POSE), K * sigma)
    for j in (2, 3, 4):
        assert _same(zones, j, discs, j), j


@pytest.mark.requirement("SR-AVL-8", kind="example", code=BODIES)
def test_a_track_is_on_the_map_when_its_cluster_this_cycle_lies_on_it() -> None:
    """A map covering cluster 0's returns in the tracking frame (robot away from the origin):
    the track it updated is on the map, not the one cluster 1 updated, nor a coasting one or one
    updated by a detection that is no cluster; a row is mapped only if asked for and on it."""
    points, clusters = _scan()
    near = _returns(points, clusters, 0, POSE)
    part = np.asarray(shapely.MultiPoint([tuple(p) for p in near]).buffer(0.05).exterior.coords)
    site = StaticMap.from_parts([part[:-1]], 0.05, 0.05)
    tracks = _tracks([2, 5, 8, 11], np.zeros((4, 2)), [0, 1, -1, clusters.n], [0.1] * 4)
    on = tracks_on_map(tracks, clusters, points, POSE, site)
    assert on.tolist() == [True, False, False, False]
    assert not tracks_on_map(tracks, clusters, points, (0.0, 0.0, 0.0), site).any()
    pred = _predictions([11, 2, 5, 2], [CONE] * 4)
    rows = np.array([True, True, True, False])
    assert mapped_rows(rows, pred, tracks, on).tolist() == [False, True, False, False]


@pytest.mark.requirement("SR-AVL-8", kind="example", code=BODIES)
def test_a_mapped_zone_is_the_cluster_hull_or_the_disc_while_it_coasts() -> None:
    """Mapped rows only: a row seen this cycle becomes its cluster's grown hull, a mapped row
    coasting its body disc; the others keep their zones; nothing mapped leaves the zones."""
    points, clusters = _scan()
    xy = np.array([[0.5, 0.5], [1.0, 1.0], [4.0, 4.0]])
    tracks = _tracks([1, 3, 6], xy, [1, -1, 0], [0.1, 0.1, 0.1])
    pred = _predictions([1, 3, 6], [CONE, CONE, CONE])
    zones = grown_polygons(np.full((3, 1, 2), 20.0), np.full(3, 0.5), SIDES)
    mapped = np.array([True, True, False])
    seen = SeenHulls.of(mapped, pred, tracks, clusters, POSE, PS)
    out = mapped_zones(zones, mapped, pred, tracks, seen, SIDES)
    _holds(_polygon(out, 0), _returns(points, clusters, 1, POSE), K * 0.1)
    disc = bodies_now(pred, tracks, np.array([False, True, False]), SIDES)
    assert _same(out, 1, disc, 0)
    assert _same(out, 2, zones, 2)
    assert mapped_zones(zones, ~np.ones(3, dtype=bool), pred, tracks, seen, SIDES) is zones


def _cycle(
    still: StillHulls,
    ids: list[int],
    xy: FloatArray,
    det: list[int],
    mode: list[int],
    sigma_m: float,
    pose: Pose = POSE,
) -> tuple[ConvexPolygons, ConvexPolygons, Clusters, ScanPoints]:
    points, clusters = _scan()
    tracks = _tracks(ids, xy, det, [sigma_m] * len(ids))
    pred = _predictions(ids, mode)
    zones = grown_polygons(xy[:, None, :], np.full(len(ids), 0.4), SIDES)
    return still.zones(zones, pred, tracks, clusters, pose, PS), zones, clusters, points


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_a_coasting_still_object_keeps_its_last_hull_moved_and_grown_for_max_coast_cycles() -> None:
    """Track 4 (still) is seen on cluster 0, then coasts: its zone is the hull it was seen with,
    moved by the track's displacement and grown by K times its current sigma, for ``max_coast``
    cycles, then its disc again. Track 7, moving when seen, is never remembered."""
    still = StillHulls(max_coast=2)
    at = np.array([[1.0, 2.0], [5.0, 5.0]])
    out, zones, clusters, points = _cycle(still, [4, 7], at, [0, 1], [FOOTPRINT, CONE], 0.1)
    assert _same(out, 0, zones, 0)
    assert _same(out, 1, zones, 1)
    seen = _returns(points, clusters, 0, POSE)
    shift = np.array([0.3, -0.1])
    for sigma in (0.15, 0.25):  # two cycles of coasting, the robot elsewhere
        moved = at + np.array([shift, [0.0, 0.0]])
        out, zones, _, _ = _cycle(
            still, [4, 7], moved, [-1, -1], [FOOTPRINT, FOOTPRINT], sigma, (0.0, 0.0, 0.0)
        )
        _holds(_polygon(out, 0), seen + shift, K * sigma)
        assert _same(out, 1, zones, 1)
    out, zones, _, _ = _cycle(still, [4, 7], at, [-1, -1], [FOOTPRINT, FOOTPRINT], 0.1)
    assert _same(out, 0, zones, 0)  # a third cycle of coasting: forgotten
    out, zones, _, _ = _cycle(still, [4, 7], at, [-1, -1], [FOOTPRINT, FOOTPRINT], 0.1)
    assert _same(out, 0, zones, 0)


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_a_hull_is_forgotten_with_its_track_and_on_reset() -> None:
    """A track that leaves the snapshot loses its hull: coming back under its id and coasting,
    it has its disc; so has every track after :meth:`StillHulls.reset`. Coasting is counted per
    track: a track seen again starts a new count."""
    at = np.array([[0.0, 0.0], [5.0, 5.0]])
    for forget in ("gone", "reset"):
        still = StillHulls(max_coast=3)
        _cycle(still, [4, 7], at, [0, 1], [FOOTPRINT, FOOTPRINT], 0.1)
        if forget == "gone":
            _cycle(still, [7], at[1:], [1], [FOOTPRINT], 0.1)
        else:
            still.reset()
        out, zones, _, _ = _cycle(still, [4, 7], at, [-1, -1], [FOOTPRINT, FOOTPRINT], 0.1)
        assert _same(out, 0, zones, 0), forget
        if forget == "gone":
            assert not _same(out, 1, zones, 1)  # track 7 was seen meanwhile: still remembered
        else:
            assert _same(out, 1, zones, 1)
    still = StillHulls(max_coast=1)
    for det in ([0, -1], [-1, -1], [0, -1], [-1, -1]):  # seen, coasting, seen, coasting
        out, zones, _, _ = _cycle(still, [4, 7], at, det, [FOOTPRINT, FOOTPRINT], 0.1)
        assert _same(out, 0, zones, 0) == (det[0] == 0), det


@pytest.mark.requirement("SR-AVL-8", kind="example", code=BODIES)
def test_the_on_map_memory_is_a_boolean_mask() -> None:
    """The memory's verdicts index rows: a bool array, also for tracks never seen."""
    memory = OnMapMemory()
    out = memory.update(np.array([1, 2]), np.array([-1, 0]), np.array([False, True]))
    assert out.dtype == np.bool_
    assert out.tolist() == [False, True]


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_hulls_seen_apart_coast_together_and_one_expiring_leaves_the_other() -> None:
    """Track 4 is seen on the 4 m arc, then track 7 on the 6 m arc (hulls of different vertex
    counts, remembered in different cycles); both coast together and both zones are their hulls.
    When track 4's coasting runs out first, track 7 (listed after it) keeps its hull."""
    still = StillHulls(max_coast=2)
    at = np.array([[1.0, 2.0], [5.0, 5.0]])
    modes = [FOOTPRINT, FOOTPRINT]
    _, _, clusters, points = _cycle(still, [4, 7], at, [0, -1], [FOOTPRINT, CONE], 0.1)
    assert np.diff(clusters.hull_offsets).tolist()[0] != np.diff(clusters.hull_offsets)[1]
    _cycle(still, [4, 7], at, [-1, 1], modes, 0.1)
    out, zones, _, _ = _cycle(still, [4, 7], at, [-1, -1], modes, 0.1)
    _holds(_polygon(out, 0), _returns(points, clusters, 0, POSE), K * 0.1)
    _holds(_polygon(out, 1), _returns(points, clusters, 1, POSE), K * 0.1)
    out, zones, _, _ = _cycle(still, [4, 7], at, [-1, -1], modes, 0.1)
    assert _same(out, 0, zones, 0)  # track 4: a third cycle of coasting
    _holds(_polygon(out, 1), _returns(points, clusters, 1, POSE), K * 0.1)


@pytest.mark.requirement("SR-AVL-6", kind="example", code=BODIES)
def test_nothing_is_remembered_for_tracks_that_are_gone() -> None:
    """The runtime runs for days: a hull, its anchor and its coasting count leave with their
    track or when coasting runs out, so the memory holds nothing once no track is left."""
    still = StillHulls(max_coast=1)
    at = np.array([[1.0, 2.0], [5.0, 5.0]])
    for first in range(0, 40, 2):
        ids = [first, first + 1]
        _cycle(still, ids, at, [0, 1], [FOOTPRINT, FOOTPRINT], 0.1)
        if first % 4 == 0:  # every other pair coasts out before it leaves
            for _ in range(2):
                _cycle(still, ids, at, [-1, -1], [FOOTPRINT, FOOTPRINT], 0.1)
            assert not still._hull
            assert not still._at
            assert not still._coast
    _cycle(still, [99], at[:1], [-1], [FOOTPRINT], 0.1)
    assert not still._hull
    assert not still._at
    assert not still._coast
