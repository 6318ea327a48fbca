"""Scan sanitation and clustering properties (SR-TRK-1, SR-TRK-2, SR-TIM-3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.cluster.dbscan import cluster_points, dbscan_points
from pipeline.config import SafecaseConfig, overridden
from pipeline.points import ScanError, scan_to_points
from pipeline.types import Scan
from properties.oracles.tracking import (
    compare_partitions,
    geos_hull_area,
    geos_min_rect,
    sklearn_dbscan,
)
from properties.scenes import random_obstacles, room_scan

CODE_POINTS = ["pipeline/points.py"]
CODE_CLUSTER = ["pipeline/cluster/dbscan.py", "pipeline/shape/box.py"]

special = st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, 0.01, 250.0])


@st.composite
def raw_scans(draw: st.DrawFn) -> Scan:
    """Scans whose ranges mix valid values with NaN, inf, negative, tiny and huge ones."""
    n = draw(st.integers(1, 400))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    ranges = rng.uniform(0.0, 40.0, n)
    bad = rng.random(n) < draw(st.floats(0.0, 1.0))
    picks = draw(st.lists(special, min_size=1, max_size=7))
    ranges[bad] = np.array(picks)[rng.integers(0, len(picks), int(bad.sum()))]
    start = draw(st.floats(-10.0, 10.0))
    span = draw(st.floats(0.1, 2 * math.pi))
    return Scan(stamp_s=0.0, angles_rad=start + np.linspace(0.0, span, n), ranges_m=ranges)


@pytest.mark.requirement("SR-TRK-1", code=CODE_POINTS)
@given(scan=raw_scans())
def test_sanitation_drops_and_counts_every_bad_range(
    scan: Scan, safecase_config: SafecaseConfig
) -> None:
    cfg = safecase_config.scan
    pts = scan_to_points(scan, cfg)
    r = scan.ranges_m
    d = pts.drops
    finite = np.isfinite(r)
    assert d.n_nan == int(np.isnan(r).sum())
    assert d.n_inf == int(np.isinf(r).sum())
    assert d.n_below_min == int((finite & (r < cfg.min_range_m)).sum())
    assert d.n_above_max == int((finite & (r > cfg.max_range_m)).sum())
    assert d.n_valid + d.n_dropped == scan.n_beams == d.n_beams
    assert pts.n == d.n_valid
    # Never passed on: every point is finite and in range, and is its own beam's range.
    assert np.all(np.isfinite(pts.x_m))
    assert np.all(np.isfinite(pts.y_m))
    assert np.all((pts.range_m >= cfg.min_range_m) & (pts.range_m <= cfg.max_range_m))
    assert np.array_equal(pts.range_m, r[pts.beam_index])
    assert np.unique(pts.beam_index).shape[0] == pts.n
    assert np.all(np.diff(pts.angle_rad) >= 0.0)
    current().count("sanitation", "beams dropped", d.n_dropped)
    current().count("sanitation", "beams kept", d.n_valid)


@st.composite
def obstacle_scans(draw: st.DrawFn) -> Scan:
    """Ray-cast scans of a room with obstacles, any beam count and field of view (some 360)."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    n_obs = draw(st.integers(0, 12))
    n_beams = draw(st.integers(16, 1440))
    fov = draw(st.sampled_from([math.pi, 1.5 * math.pi, 2 * math.pi]))
    noise = draw(st.sampled_from([0.0, 0.005, 0.02, 0.06]))
    return room_scan(random_obstacles(rng, n_obs), rng, n_beams, fov, noise_std_m=noise)


@st.composite
def point_soups(draw: st.DrawFn) -> Scan:
    """Random ranges close to the sensor (some inside eps): dense, irregular neighbourhoods."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    n = draw(st.integers(1, 600))
    angles = np.sort(rng.uniform(-math.pi, math.pi, n))
    low = draw(st.sampled_from([0.0, 0.05, 0.5]))
    ranges = rng.uniform(low, low + draw(st.floats(0.3, 6.0)), n)
    return Scan(stamp_s=0.0, angles_rad=angles, ranges_m=ranges)


def _check_against_sklearn(scan: Scan, config: SafecaseConfig) -> None:
    pts = scan_to_points(scan, config.scan)
    eps, ms = config.cluster.eps_m, config.cluster.min_samples
    ours = dbscan_points(pts, eps, ms)
    xy = np.stack([pts.x_m, pts.y_m], axis=1)
    ref_labels, ref_core = sklearn_dbscan(xy, eps, ms)
    diff = compare_partitions(xy, ours, ref_labels, ref_core, eps)
    rec = current()
    rec.count("points", "points", pts.n)
    rec.count("points", "border points", int(((ours.labels >= 0) & ~ours.is_core).sum()))
    rec.count("points", "border points assigned unlike sklearn (allowed)", diff.border_vs_ref)
    rec.count("clusters", "clusters", ours.n_clusters)
    assert diff.agrees, diff


@pytest.mark.requirement("SR-TRK-2", kind="cross-check", code=CODE_CLUSTER)
@settings(max_examples=examples(100))
@given(scan=obstacle_scans())
def test_partition_equals_sklearn_on_ray_cast_scans(
    scan: Scan, safecase_config: SafecaseConfig
) -> None:
    _check_against_sklearn(scan, safecase_config)


@pytest.mark.requirement("SR-TRK-2", kind="cross-check", code=CODE_CLUSTER)
@settings(max_examples=examples(100))
@given(scan=point_soups(), eps=st.floats(0.05, 0.6), min_samples=st.integers(1, 8))
def test_partition_equals_sklearn_on_point_soups_any_parameters(
    scan: Scan, eps: float, min_samples: int, safecase_config: SafecaseConfig
) -> None:
    config = overridden(safecase_config, {"cluster": {"eps_m": eps, "min_samples": min_samples}})
    _check_against_sklearn(scan, config)


@pytest.mark.requirement("SR-TRK-2", kind="cross-check", code=CODE_CLUSTER)
@settings(max_examples=examples(60))
@given(scan=obstacle_scans())
def test_cluster_geometry_matches_geos(scan: Scan, safecase_config: SafecaseConfig) -> None:
    pts = scan_to_points(scan, safecase_config.scan)
    clusters = cluster_points(pts, safecase_config.cluster)
    for k in range(clusters.n):
        member = clusters.point_labels == k
        xy = np.stack([pts.x_m[member], pts.y_m[member]], axis=1)
        hull = clusters.hull(k)
        # Counter-clockwise and convex: every turn strictly left.
        if hull.shape[0] >= 3:
            e = np.roll(hull, -1, axis=0) - hull
            turn = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
            assert np.all(turn > 0.0)
        area = 0.5 * float(
            np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
        )
        assert area == pytest.approx(geos_hull_area(xy), rel=1e-9, abs=1e-12)
        width, length = geos_min_rect(xy)
        assert clusters.area_m2[k] == pytest.approx(width * length, rel=1e-7, abs=1e-10)
        assert clusters.width_m[k] <= clusters.length_m[k]
        # The box covers every point of the cluster.
        h = clusters.heading_rad[k]
        u = np.array([math.cos(h), math.sin(h)])
        along, across = xy @ u, xy @ np.array([-u[1], u[0]])
        assert np.ptp(along) <= clusters.length_m[k] + 1e-9
        assert np.ptp(across) <= clusters.width_m[k] + 1e-9
        assert clusters.n_points[k] == xy.shape[0]
        assert clusters.centroid_x_m[k] == pytest.approx(xy[:, 0].mean(), abs=1e-12)
        current().count("geometry", "clusters checked", 1)


@pytest.mark.requirement("SR-TIM-3", code=CODE_CLUSTER + CODE_POINTS)
@settings(max_examples=examples(50))
@given(
    scan=obstacle_scans(),
    max_clusters=st.integers(1, 6),
    max_beams=st.integers(16, 1500),
)
def test_clustering_work_is_capped(
    scan: Scan, max_clusters: int, max_beams: int, safecase_config: SafecaseConfig
) -> None:
    config = overridden(
        safecase_config,
        {"cluster": {"max_clusters": max_clusters}, "scan": {"max_beams": max_beams}},
    )
    if scan.n_beams > max_beams:
        with pytest.raises(ScanError, match="max_beams"):
            scan_to_points(scan, config.scan)
        current().count("caps", "scans refused over max_beams", 1)
        return
    pts = scan_to_points(scan, config.scan)
    clusters = cluster_points(pts, config.cluster)
    assert clusters.n <= max_clusters
    c = clusters.counts
    assert clusters.n + c.n_over_cap + c.n_too_small + c.n_too_large == c.n_found
    assert np.all(clusters.n_points >= config.cluster.min_points)
    assert np.all(clusters.n_points <= config.cluster.max_points)
    current().count("caps", "clusters dropped over the cap", c.n_over_cap)
