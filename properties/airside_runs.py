"""Ray-cast runs of the apron scenarios through the perception chain, scored against the
simulator's ground truth (SR-TRK-7, SR-TRK-8, SR-TRK-9).

A run keeps the robot standing at its start (the scenarios start it at rest) and feeds every
scan through :meth:`pipeline.perception.Perception.track` in the world frame (the scanner's
true pose as odometry). The frames of one simulation are kept, so that two chains (Hungarian
and JPDA, re-identification on and off) see the very same scans.

Truth per scan: the objects with at least ``cluster.min_points`` returns, each at the centroid
of its true hit points (what a perfect clusterer would report: a partly seen object is where
its seen part is). A track's object is the majority beam owner of the cluster that updated it
(:func:`cluster_owners`); a re-identification is *false* when that object differs from the one
the track last followed before it went dormant. Tracks whose last object is static structure
(racks, cones, stairs) are left out of the scored hypotheses, as "don't care" regions are in
CLEAR-MOT benchmarks: the truth lists objects only, and a tracker that follows a cone is
neither right nor wrong about the objects.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.frames import checked_pose
from pipeline.perception import Perception, Stopwatch, Tracked
from pipeline.sources.sim.airside_scenarios import AIRSIDE_SCENARIOS
from pipeline.sources.sim.scenarios import simulation_for_spec
from pipeline.sources.sim.simulation import SimFrame
from pipeline.sources.sim.truth import ScanTruth
from pipeline.track.jpda import JpdaAssociator
from pipeline.track.metrics import PositionsFrame, TrackingQuality, evaluate, frame_from_tracks
from pipeline.types import FloatArray, Frame, IntArray, ScanPoints

__all__ = [
    "ChainScore",
    "airside_frames",
    "cluster_owners",
    "motmetrics_counts",
    "score_chain",
    "true_points",
    "visible_truth",
]

NO_OWNER = -1


def airside_frames(
    config: SafecaseConfig, name: str, seed: int, duration_s: float
) -> list[SimFrame]:
    """Every frame of one seeded run of an apron scenario with the robot standing."""
    _, builder = AIRSIDE_SCENARIOS[name]
    layout = np.random.default_rng(np.random.SeedSequence(seed).spawn(3)[0])
    sim = simulation_for_spec(config, builder(layout, duration_s), name, seed, duration_s)
    frames = []
    sim.command(0.0)
    while (frame := sim.next_frame()) is not None:
        frames.append(frame)
        sim.command(0.0)
    return frames


def true_points(truth: ScanTruth, angles_rad: FloatArray) -> tuple[IntArray, FloatArray]:
    """Owner and exact world position of every beam that returned (ranges without noise)."""
    beams = truth.beams
    ok = np.isfinite(beams.true_range_m) & ~beams.dropout
    x0, y0, yaw = truth.scanner_pose
    r, a = beams.true_range_m[ok], angles_rad[ok] + yaw
    xy = np.stack([x0 + r * np.cos(a), y0 + r * np.sin(a)], axis=1)
    return beams.owner_id[ok], xy


def visible_truth(truth: ScanTruth, angles_rad: FloatArray, min_points: int) -> PositionsFrame:
    """Objects with at least ``min_points`` returns, at the centroid of their hit points."""
    owner, xy = true_points(truth, angles_rad)
    ids, inverse, counts = np.unique(owner, return_inverse=True, return_counts=True)
    sx = np.bincount(inverse, weights=xy[:, 0])
    sy = np.bincount(inverse, weights=xy[:, 1])
    keep = (ids >= 0) & (counts >= min_points)
    return PositionsFrame(ids[keep], np.stack([sx[keep], sy[keep]], axis=1) / counts[keep, None])


def cluster_owners(
    points: ScanPoints, labels: IntArray, n_clusters: int, truth: ScanTruth
) -> tuple[IntArray, FloatArray]:
    """Per cluster: its majority beam owner (object id, or a negative structure / no-return
    code) and that owner's share of its points."""
    member = labels >= 0
    owners = truth.beams.owner_id[points.beam_index[member]]
    if n_clusters == 0 or owners.shape[0] == 0:
        return np.full(n_clusters, NO_OWNER, dtype=np.int64), np.zeros(n_clusters)
    keys, inverse = np.unique(owners, return_inverse=True)
    table = np.zeros((n_clusters, keys.shape[0]), dtype=np.int64)
    np.add.at(table, (labels[member], inverse), 1)
    best = table.argmax(axis=1)
    share = table[np.arange(n_clusters), best] / np.maximum(table.sum(axis=1), 1)
    return keys[best].astype(np.int64), share


@dataclass(frozen=True)
class ChainScore:
    """One chain over one run: CLEAR-MOT and GOSPA (:func:`pipeline.track.metrics.evaluate`),
    the re-identifications and how many gave a track to another object, the track stage's time
    per cycle [s], JPDA's account (clusters of tracks sharing detections, enumerated, fallen
    back to the cascade, the largest bound on joint events) and the frames scored."""

    quality: TrackingQuality
    reids: int
    false_reids: int
    track_wall_s: FloatArray
    jpda_clusters: int
    jpda_enumerated: int
    jpda_fallbacks: int
    jpda_max_hypotheses: int
    truths: tuple[PositionsFrame, ...]
    hypotheses: tuple[PositionsFrame, ...]


def score_chain(
    config: SafecaseConfig, frames: Sequence[SimFrame], match_threshold_m: float = 1.0
) -> ChainScore:
    """Run the tracking half of the chain ``config`` describes over ``frames`` and score it."""
    chain = Perception.from_config(config, tracking_only=True)
    truths, hyps, walls = [], [], []
    last_object: dict[int, int] = {}  # track id -> object of its last update
    reid_before: dict[int, int] = {}  # track id -> its reid count last cycle
    reids = false_reids = 0
    jpda = [0, 0, 0, 0]
    for sim_frame in frames:
        truth = sim_frame.truth
        frame = Frame(
            sim_frame.scan, sim_frame.observation.stamp_s, pose=checked_pose(truth.scanner_pose)
        )
        watch = Stopwatch()
        tracked = chain.track(frame, watch)
        walls.append(watch.wall_s["track"])
        _account(tracked, truth, last_object, reid_before, counts := [0, 0])
        reids += counts[0]
        false_reids += counts[1]
        assoc = getattr(chain.tracker, "associator", None)
        if isinstance(assoc, JpdaAssociator) and assoc.last is not None:
            jpda[0] += assoc.last.n_clusters
            jpda[1] += assoc.last.n_jpda
            jpda[2] += assoc.last.n_fallback
            jpda[3] = max(jpda[3], assoc.last.max_hypotheses)
        truths.append(visible_truth(truth, sim_frame.scan.angles_rad, config.cluster.min_points))
        scored = frame_from_tracks(tracked.tracks)
        on_object = np.array([last_object.get(int(i), 0) >= 0 for i in scored.ids], dtype=bool)
        hyps.append(PositionsFrame(scored.ids[on_object], scored.xy_m[on_object]))
    quality = evaluate(truths, hyps, match_threshold_m)
    return ChainScore(
        quality,
        reids,
        false_reids,
        np.array(walls),
        jpda[0],
        jpda[1],
        jpda[2],
        jpda[3],
        tuple(truths),
        tuple(hyps),
    )


def _account(
    tracked: Tracked,
    truth: ScanTruth,
    last_object: dict[int, int],
    reid_before: dict[int, int],
    counts: list[int],
) -> None:
    """Count this cycle's re-identifications (``counts[0]``) and the false ones (``[1]``)."""
    tracks, clusters = tracked.tracks, tracked.clusters
    owner, share = cluster_owners(tracked.points, clusters.point_labels, clusters.n, truth)
    for k in range(tracks.n):
        tid, det = int(tracks.track_id[k]), int(tracks.detection_index[k])
        now = int(owner[det]) if det >= 0 and share[det] >= 0.5 else None
        before = reid_before.get(tid, int(tracks.reid_count[k]))
        if int(tracks.reid_count[k]) > before:
            counts[0] += 1
            if now is None or now != last_object.get(tid, now):
                counts[1] += 1
        reid_before[tid] = int(tracks.reid_count[k])
        if now is not None:
            last_object[tid] = now


def motmetrics_counts(
    truths: Sequence[PositionsFrame], hyps: Sequence[PositionsFrame], threshold_m: float = 1.0
) -> dict[str, float]:
    """py-motmetrics' CLEAR-MOT counts for the same frames (independent oracle)."""
    import motmetrics

    acc = motmetrics.MOTAccumulator(auto_id=True)
    for gt, hy in zip(truths, hyps, strict=True):
        d = np.hypot(
            gt.xy_m[:, None, 0] - hy.xy_m[None, :, 0], gt.xy_m[:, None, 1] - hy.xy_m[None, :, 1]
        )
        acc.update(gt.ids.tolist(), hy.ids.tolist(), np.where(d <= threshold_m, d, np.nan))
    names = ["num_switches", "num_fragmentations", "num_misses", "num_false_positives", "mota"]
    summary = motmetrics.metrics.create().compute(acc, metrics=names, name="run")
    return {name: float(summary[name].iloc[0]) for name in names}


def timed(seconds: float) -> str:
    """Milliseconds for a table."""
    return f"{1e3 * seconds:.2f}"
