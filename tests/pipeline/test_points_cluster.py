"""Examples for scan sanitation and clustering (SR-TRK-1, SR-TRK-2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.cluster.dbscan import cluster_points, cluster_scan, dbscan_points, neighbour_pairs
from pipeline.config import default_config, overridden
from pipeline.points import ScanError, scan_to_points
from pipeline.shape.box import convex_hulls
from pipeline.types import Scan


@pytest.mark.requirement("SR-TRK-1", code=["pipeline/points.py"])
def test_each_kind_of_bad_range_is_counted_under_its_reason() -> None:
    ranges = np.array([1.0, math.nan, math.inf, -math.inf, 0.01, -2.0, 31.0, 2.0])
    scan = Scan(stamp_s=1.0, angles_rad=np.linspace(0.0, 1.0, 8), ranges_m=ranges)
    pts = scan_to_points(scan, default_config().scan)
    d = pts.drops
    assert (d.n_valid, d.n_nan, d.n_inf, d.n_below_min, d.n_above_max) == (2, 1, 2, 2, 1)
    assert pts.beam_index.tolist() == [0, 7]
    assert pts.x_m[0] == pytest.approx(1.0)


@pytest.mark.requirement("SR-TIM-3", code=["pipeline/points.py"])
def test_a_scan_over_max_beams_is_refused_naming_the_cap() -> None:
    config = overridden(default_config(), {"scan": {"max_beams": 16}}).scan
    scan = Scan(stamp_s=0.0, angles_rad=np.linspace(0, 1, 17), ranges_m=np.ones(17), seq=4)
    with pytest.raises(ScanError, match=r"17 beams; expected at most scan.max_beams = 16"):
        scan_to_points(scan, config)


def test_mount_pose_moves_points_into_the_robot_frame() -> None:
    config = overridden(
        default_config(), {"scan": {"mount_x_m": 0.5, "mount_yaw_rad": math.pi / 2}}
    ).scan
    pts = scan_to_points(
        Scan(stamp_s=0.0, angles_rad=np.zeros(1), ranges_m=np.full(1, 2.0)), config
    )
    assert (pts.x_m[0], pts.y_m[0]) == pytest.approx((0.5, 2.0))


def test_neighbours_are_found_across_the_wrap_of_a_full_turn() -> None:
    # Two points straddling +-pi, 0.1 m apart at 3 m: only the wrap finds them.
    a = np.array([-math.pi + 0.01, math.pi - 0.02])
    r = np.array([3.0, 3.0])
    order = np.argsort(a)
    i, _, _ = neighbour_pairs(r * np.cos(a), r * np.sin(a), a[order], r[order], 0.15)
    assert len(i) == 1


def test_border_point_joins_its_nearest_core_point() -> None:
    # Two dense groups on a line with a border point between them, nearer the right one.
    x = np.array([0.0, 0.05, 0.1, 0.3, 0.42, 0.47, 0.52])
    pts = scan_to_points(
        Scan(stamp_s=0.0, angles_rad=np.zeros(7) + np.arange(7) * 1e-9, ranges_m=1.0 + x),
        default_config().scan,
    )
    result = dbscan_points(pts, 0.15, 3)
    assert result.n_clusters == 2
    assert not result.is_core[3]
    assert result.labels[3] == result.labels[4]  # 0.12 m to the right core, 0.2 m to the left


def test_cluster_geometry_of_a_square_box() -> None:
    # Points on the four sides of a 1 m x 0.5 m box rotated 30 degrees.
    s = np.linspace(0, 1, 21)
    side = np.concatenate(
        [np.c_[s, 0 * s], np.c_[s, 0 * s + 0.5], np.c_[0 * s, s / 2], np.c_[0 * s + 1, s / 2]]
    )
    yaw = math.radians(30)
    rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    xy = side @ rot.T + [3.0, 1.0]
    labels = np.zeros(xy.shape[0], dtype=np.int64)
    _, _, off = convex_hulls(side[:, 0], side[:, 1], labels, 1)  # exactly collinear sides
    assert off.tolist() == [0, 4]
    angle = np.arctan2(xy[:, 1], xy[:, 0])
    order = np.argsort(angle)
    pts = scan_to_points(
        Scan(stamp_s=0.0, angles_rad=angle[order], ranges_m=np.hypot(*xy[order].T)),
        default_config().scan,
    )
    clusters = cluster_points(
        pts, overridden(default_config(), {"cluster": {"eps_m": 0.3}}).cluster
    )
    assert clusters.n == 1
    assert clusters.width_m[0] == pytest.approx(0.5)
    assert clusters.length_m[0] == pytest.approx(1.0)
    assert clusters.heading_rad[0] == pytest.approx(yaw)
    assert clusters.area_m2[0] == pytest.approx(0.5)


def test_size_filter_and_counts() -> None:
    angles = np.linspace(-0.5, 0.5, 200)
    ranges = np.full(200, 5.0)
    ranges[::50] = 2.0  # isolated points: noise
    _, clusters = cluster_scan(
        Scan(stamp_s=0.0, angles_rad=angles, ranges_m=ranges), default_config()
    )
    assert clusters.counts.n_noise_points >= 4
    assert np.all(clusters.n_points >= 4)
    assert (
        clusters.n
        == clusters.counts.n_found - clusters.counts.n_too_small - clusters.counts.n_too_large
    )
