"""Examples for the L-shape fit and its shape role (SR-TRK-7)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.cluster.dbscan import DbscanClusterer
from pipeline.config import default_config, overridden
from pipeline.errors import ConfigError
from pipeline.perception import Perception
from pipeline.points import RangeFilter
from pipeline.shape.box import BoxShapes
from pipeline.shape.lshape import LShapeShapes, angle_grid, lshape_fit
from pipeline.types import FloatArray, Scan


def _l_points(heading_rad: float, length_m: float = 3.0, width_m: float = 1.5) -> FloatArray:
    a = np.linspace(0.0, length_m, 60)
    b = np.linspace(0.0, width_m, 30)
    pts = np.concatenate([np.stack([a, 0 * a], 1), np.stack([0 * b, b], 1)])
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    out: FloatArray = pts @ np.array([[c, s], [-s, c]]) + np.array([6.0, 2.0])
    return out


def _labels(n: int) -> np.ndarray:
    return np.zeros(n, dtype=np.int64)


def test_the_grid_covers_a_quarter_turn_evenly() -> None:
    grid = angle_grid(1.0)
    assert grid.shape == (90,)
    assert grid[0] == 0.0
    assert grid[-1] < math.pi / 2
    assert angle_grid(7.0).shape == (13,)


@pytest.mark.parametrize("heading_deg", [0.0, 17.0, 45.0, 71.0, -30.0])
def test_an_l_is_accepted_with_its_heading_and_sides(heading_deg: float) -> None:
    pts = _l_points(math.radians(heading_deg))
    fit = lshape_fit(pts[:, 0], pts[:, 1], _labels(len(pts)), 1, default_config().cluster)
    assert fit.accepted[0]
    err = (fit.heading_rad[0] - math.radians(heading_deg) + math.pi / 2) % math.pi - math.pi / 2
    assert abs(err) <= math.radians(0.5) + 1e-9
    assert fit.length_m[0] == pytest.approx(3.0, abs=0.05)
    assert fit.width_m[0] == pytest.approx(1.5, abs=0.05)
    assert fit.inliers[0].min() >= 6


def test_a_single_face_is_refused_and_the_box_kept() -> None:
    a = np.linspace(0.0, 3.0, 80)
    x, y = 5.0 + a * 0.8, 1.0 + a * 0.6
    fit = lshape_fit(x, y, _labels(80), 1, default_config().cluster)
    assert not fit.accepted[0]


def test_too_few_inliers_on_an_edge_refuses_the_fit() -> None:
    pts = _l_points(0.3)
    cfg = overridden(default_config(), {"cluster": {"lshape_min_edge_inliers": 40}}).cluster
    fit = lshape_fit(pts[:, 0], pts[:, 1], _labels(len(pts)), 1, cfg)
    assert not fit.accepted[0]  # the short edge has 30 points


def test_two_faces_far_from_perpendicular_are_refused() -> None:
    # Two 2 m faces meeting at 60 deg: both edges hold inliers, but they are not an L.
    a = np.linspace(0.0, 2.0, 60)
    side = np.stack([a * math.cos(math.pi / 3), a * math.sin(math.pi / 3)], 1)
    pts = np.concatenate([np.stack([a, 0 * a], 1), side]) + np.array([5.0, 1.0])
    fit = lshape_fit(pts[:, 0], pts[:, 1], _labels(len(pts)), 1, default_config().cluster)
    assert fit.inliers[0].min() >= 6
    assert fit.perpendicular_error_rad[0] > math.radians(15.0)
    assert not fit.accepted[0]


def test_small_and_absent_clusters_are_not_searched() -> None:
    cfg = default_config().cluster
    x = np.array([0.0, 0.1, 0.2])
    fit = lshape_fit(x, x, _labels(3), 1, cfg)
    assert not fit.accepted[0]
    assert np.isnan(fit.heading_rad[0])
    empty = lshape_fit(np.zeros(0), np.zeros(0), _labels(0), 0, cfg)
    assert empty.accepted.shape == (0,)


def _corner_scan() -> Scan:
    """A 3 x 1.5 m box seen at a corner, 6 m ahead (exact ranges, 1080 beams)."""
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    ranges = np.full(1080, np.nan)
    h = math.radians(30.0)
    rot = np.array([[math.cos(h), math.sin(h)], [-math.sin(h), math.cos(h)]])
    corners = np.array([[0, 0], [3, 0], [3, 1.5], [0, 1.5]]) @ rot + np.array([6.0, -1.0])
    for i, a in enumerate(angles):
        d = np.array([math.cos(a), math.sin(a)])
        best = np.inf
        for k in range(4):
            p, q = corners[k], corners[(k + 1) % 4]
            e = q - p
            den = d[0] * e[1] - d[1] * e[0]
            if abs(den) < 1e-12:
                continue
            t = (p[0] * e[1] - p[1] * e[0]) / den
            u = (p[0] * d[1] - p[1] * d[0]) / den
            if t > 0 and 0 <= u <= 1:
                best = min(best, t)
        ranges[i] = best if np.isfinite(best) else np.nan
    return Scan(0.0, angles, ranges)


def test_the_role_replaces_only_accepted_boxes() -> None:
    cfg = default_config()
    points = RangeFilter(cfg.scan).points(_corner_scan())
    partition = DbscanClusterer(cfg.cluster).partition(points)
    box = BoxShapes(cfg.cluster).clusters(points, partition)
    lshape = LShapeShapes(cfg.cluster).clusters(points, partition)
    assert box.n == lshape.n == 1
    assert np.array_equal(box.centroid_x_m, lshape.centroid_x_m)
    assert np.array_equal(box.hull_x_m, lshape.hull_x_m)
    err = (lshape.heading_rad[0] - math.radians(30.0) + math.pi / 2) % math.pi - math.pi / 2
    assert abs(err) < math.radians(1.0)
    box_err = (box.heading_rad[0] - math.radians(30.0) + math.pi / 2) % math.pi - math.pi / 2
    assert abs(box_err) > math.radians(10.0)  # the box lies along the L's hypotenuse
    assert lshape.area_m2[0] == pytest.approx(lshape.width_m[0] * lshape.length_m[0])


def test_the_chain_takes_the_configured_estimator() -> None:
    lshape = overridden(default_config(), {"cluster": {"shape_estimator": "lshape"}})
    assert isinstance(Perception.from_config(lshape, tracking_only=True).shapes, LShapeShapes)
    chain = Perception.from_config(default_config(), tracking_only=True)
    assert isinstance(chain.shapes, BoxShapes)


def test_bad_estimator_settings_are_refused_naming_the_key() -> None:
    with pytest.raises(ConfigError) as caught:
        overridden(default_config(), {"cluster": {"shape_estimator": "ellipse"}})
    (line,) = caught.value.lines
    assert "cluster.shape_estimator" in line
    assert "'ellipse'" in line
    assert "'box', 'lshape'" in line
    with pytest.raises(ConfigError, match=r"cluster\.lshape_angle_step_deg"):
        overridden(default_config(), {"cluster": {"lshape_angle_step_deg": 0.0}})
