"""Campaigns: re-identification on versus off, and the real logs end to end (SR-TRK-2, -5)."""

from __future__ import annotations

import numpy as np
import pytest

from evidence.profiles import active_profile, certifying
from evidence.record import current
from pipeline.cluster.dbscan import dbscan_points
from pipeline.config import SafecaseConfig
from pipeline.perception import Perception, Stopwatch
from pipeline.points import scan_to_points
from pipeline.track.metrics import compare_reid
from properties.ahead import ahead
from properties.oracles.tracking import compare_partitions, sklearn_dbscan
from properties.real_logs import MISSING_REASON, REAL_DATA, streams
from properties.scenes import occlusion_sequence

CODE = ["pipeline/track/tracker.py", "pipeline/track/lifecycle.py", "pipeline/track/metrics.py"]
SOURCE_TARGET_REDUCTION = 0.30


@pytest.mark.requirement("SR-TRK-5", kind="campaign", code=CODE)
@ahead
def test_reidentification_cuts_id_switches_by_30_percent(safecase_config: SafecaseConfig) -> None:
    """Deterministic occlusion sequences (8 targets, 30 s, 2 occlusions of 0.8-3 s each)."""
    seeds = range(5 if not certifying() else 40)
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
    "SR-TRK-5",
    kind="campaign",
    code=["pipeline/cluster/dbscan.py", "pipeline/sources/logs/__init__.py", *CODE],
)
@ahead
def test_every_scan_of_the_real_logs_is_clustered_and_tracked(
    safecase_config: SafecaseConfig,
) -> None:
    """Every scan of every log, under every profile, through the stamp rule of the log sources."""
    _require_real_data()
    rec = current()
    rows = []
    all_cycle_s: list[float] = []
    for source in streams():
        name = source.name
        chain = Perception.from_config(safecase_config, tracking_only=True)
        n_scans = n_points = n_clusters = n_reid = 0
        drops = np.zeros(4, dtype=np.int64)
        ids: set[int] = set()
        cluster_s, track_s = [], []
        beams = set()
        for frame in source.frames():
            scan = frame.scan
            assert scan is not None  # a log delivers a scan in every frame
            watch = Stopwatch()
            tracked = chain.track(frame, watch)
            points, clusters, tracks = tracked.points, tracked.clusters, tracked.tracks
            w = watch.wall_s
            cluster_s.append(w["points"] + w["cluster"] + w["shape"])
            track_s.append(w["track"])
            n_scans += 1
            beams.add(scan.n_beams)
            n_points += points.n
            d = points.drops
            drops += [d.n_nan, d.n_inf, d.n_below_min, d.n_above_max]
            n_clusters += clusters.n
            ids.update(tracks.track_id.tolist())
            assert tracked.counts is not None
            n_reid += tracked.counts.n_reidentified
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
                "-" if source.stamps.restamp_hz is None else f"{source.stamps.restamp_hz:.3g} Hz",
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
            "re-stamped at",
            "p50 ms",
            "p99 ms",
        ],
        rows,
        caption="the CARMEN logs are tracked in their odometry frame; the bags and the "
        "BreezySLAM log carry no odometry pose and are tracked in the robot frame (on a moving "
        "robot static structure then moves, hence many IDs)",
    )
    rec.samples("all streams: cluster + track per scan", all_cycle_s, unit="s")


@pytest.mark.requirement("SR-TRK-2", kind="cross-check", code=["pipeline/cluster/dbscan.py"])
@ahead
def test_partition_equals_sklearn_on_the_real_logs(safecase_config: SafecaseConfig) -> None:
    """Every 10th scan under ci, every scan under certify."""
    _require_real_data()
    stride = 1 if certifying() else 10
    eps, ms = safecase_config.cluster.eps_m, safecase_config.cluster.min_samples
    rec = current()
    rec.note(f"cross-checked every {stride} scan(s) of each stream (profile {active_profile()})")
    rows = []
    for source in streams():
        name = source.name
        n = border_vs_ref = failures = 0
        for index, scan in enumerate(source.scans()):
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
