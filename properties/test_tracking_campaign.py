"""Campaigns: re-identification on versus off, and the real logs end to end (SR-TRK-2, -5)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from evidence.profiles import active_profile
from evidence.record import current
from pipeline.cluster import cluster_scan, dbscan_points
from pipeline.config import SafecaseConfig
from pipeline.points import scan_to_points
from pipeline.track.metrics import compare_reid
from pipeline.track.tracker import Detections, Tracker, TrackerError
from properties.oracles.tracking import compare_partitions, sklearn_dbscan
from properties.real_logs import MISSING_REASON, REAL_DATA, streams
from properties.scenes import occlusion_sequence

CODE = ["pipeline/track/tracker.py", "pipeline/track/lifecycle.py", "pipeline/track/metrics.py"]
SOURCE_TARGET_REDUCTION = 0.30


@pytest.mark.requirement("SR-TRK-5", kind="campaign", code=CODE)
def test_reidentification_cuts_id_switches_by_30_percent(safecase_config: SafecaseConfig) -> None:
    """Deterministic occlusion sequences (8 targets, 30 s, 2 occlusions of 0.8-3 s each)."""
    seeds = range(5 if active_profile() != "certify" else 40)
    totals = {"reid_on": np.zeros(9), "reid_off": np.zeros(9)}
    rows = []
    for seed in seeds:
        scene = occlusion_sequence(np.random.default_rng(1000 + seed))
        result = compare_reid(scene.frames, safecase_config.track)
        for name, q in result.items():
            totals[name] += [
                q.id_switches,
                q.fragmentations,
                q.mota,
                q.motp_m,
                q.position_rmse_m,
                q.gospa_mean_m,
                q.n_hypothesis_ids,
                q.n_truth_ids,
                1,
            ]
        on, off = result["reid_on"], result["reid_off"]
        rows.append([seed, scene.n_occlusions, off.id_switches, on.id_switches])
    table = []
    for name, t in totals.items():
        n = t[8]
        table.append(
            [
                name,
                int(t[0]),
                int(t[1]),
                f"{t[2] / n:.3f}",
                f"{t[3] / n:.3f}",
                f"{t[4] / n:.3f}",
                f"{t[5] / n:.3f}",
                int(t[6]),
                int(t[7]),
            ]
        )
    reduction = 1.0 - totals["reid_on"][0] / totals["reid_off"][0]
    rec = current()
    rec.table(
        "re-identification on vs off",
        [
            "setting",
            "ID switches",
            "fragmentations",
            "MOTA",
            "MOTP m",
            "position RMSE m",
            "mean GOSPA m (c=2, p=2)",
            "track IDs",
            "truth IDs",
        ],
        table,
        caption=f"{len(seeds)} seeded sequences; ID switches {reduction:.0%} fewer with "
        f"re-identification (source target {SOURCE_TARGET_REDUCTION:.0%})",
    )
    rec.table("per sequence", ["seed", "occlusions", "ID switches off", "ID switches on"], rows)
    rec.counts("re-identification", {"ID switch reduction %": round(100 * reduction, 1)})
    assert reduction >= SOURCE_TARGET_REDUCTION


def _require_real_data() -> None:
    if not REAL_DATA.is_dir():
        pytest.skip(MISSING_REASON)


@pytest.mark.requirement(
    "SR-TRK-5", kind="campaign", code=["pipeline/cluster.py", "pipeline/sources/logs.py", *CODE]
)
def test_every_scan_of_the_real_logs_is_clustered_and_tracked(
    safecase_config: SafecaseConfig,
) -> None:
    """Every scan of every log, under every profile; the tracker restarts on a clock jump back."""
    _require_real_data()
    rec = current()
    rows = []
    all_cycle_s: list[float] = []
    for name, read in streams():
        tracker = Tracker(safecase_config.track)
        n_scans = n_points = n_clusters = restarts = n_reid = 0
        drops = np.zeros(4, dtype=np.int64)
        ids: set[int] = set()
        cluster_s, track_s = [], []
        beams = set()
        for scan in read():
            t0 = time.perf_counter()
            points, clusters = cluster_scan(scan, safecase_config)
            t1 = time.perf_counter()
            detections = Detections.from_clusters(clusters)
            try:
                tracks = tracker.step(detections)
            except TrackerError:
                # The log's clock ran backwards: the runtime would stop and start afresh.
                restarts += 1
                tracker = Tracker(safecase_config.track)
                tracks = tracker.step(detections)
            t2 = time.perf_counter()
            cluster_s.append(t1 - t0)
            track_s.append(t2 - t1)
            n_scans += 1
            beams.add(scan.n_beams)
            n_points += points.n
            d = points.drops
            drops += [d.n_nan, d.n_inf, d.n_below_min, d.n_above_max]
            n_clusters += clusters.n
            ids.update(tracks.track_id.tolist())
            assert tracker.last_counts is not None
            n_reid += tracker.last_counts.n_reidentified
            assert d.n_valid + d.n_dropped == scan.n_beams
        assert n_scans > 0, f"{name}: no scans read"
        all_cycle_s.extend(np.add(cluster_s, track_s).tolist())
        rec.samples(f"{name}: cluster per scan", cluster_s, unit="s")
        rec.samples(f"{name}: track per scan", track_s, unit="s")
        rows.append(
            [
                name,
                n_scans,
                "/".join(str(b) for b in sorted(beams)),
                n_points,
                *drops.tolist(),
                n_clusters,
                len(ids),
                n_reid,
                restarts,
                f"{np.percentile(np.add(cluster_s, track_s), 50) * 1e3:.2f}",
                f"{np.percentile(np.add(cluster_s, track_s), 99) * 1e3:.2f}",
            ]
        )
        rec.count("real logs", "scans processed", n_scans)
    rec.table(
        "real logs: clustering and tracking over every scan",
        [
            "stream",
            "scans",
            "beams",
            "points",
            "NaN",
            "inf",
            "below min",
            "above max",
            "clusters",
            "track IDs",
            "re-identifications",
            "tracker restarts (clock back)",
            "p50 ms",
            "p99 ms",
        ],
        rows,
        caption="robot-frame tracking without ego-motion compensation: on the moving-robot "
        "logs static structure moves in the robot frame, hence many IDs",
    )
    rec.samples("all streams: cluster + track per scan", all_cycle_s, unit="s")


@pytest.mark.requirement("SR-TRK-2", kind="cross-check", code=["pipeline/cluster.py"])
def test_partition_equals_sklearn_on_the_real_logs(safecase_config: SafecaseConfig) -> None:
    """Every 10th scan under ci, every scan under certify."""
    _require_real_data()
    stride = 1 if active_profile() == "certify" else 10
    eps, ms = safecase_config.cluster.eps_m, safecase_config.cluster.min_samples
    rec = current()
    rec.note(f"cross-checked every {stride} scan(s) of each stream (profile {active_profile()})")
    rows = []
    for name, read in streams():
        n = border_vs_ref = failures = 0
        for index, scan in enumerate(read()):
            if index % stride:
                continue
            points = scan_to_points(scan, safecase_config.scan)
            ours = dbscan_points(points, eps, ms)
            xy = np.stack([points.x_m, points.y_m], axis=1)
            diff = compare_partitions(xy, ours, *sklearn_dbscan(xy, eps, ms), eps)
            failures += int(not diff.agrees)
            border_vs_ref += diff.border_vs_ref
            n += 1
        rows.append([name, n, failures, border_vs_ref])
        rec.count("real logs", "scans cross-checked", n)
        rec.count("real logs", "scans disagreeing", failures)
    rec.table(
        "real logs against scikit-learn DBSCAN",
        ["stream", "scans checked", "partitions differing", "border points unlike sklearn"],
        rows,
    )
    assert all(r[2] == 0 for r in rows), rows
