"""Search-based L-shape fitting, all clusters of a scan at once (SR-TRK-7).

Zhang et al., "Efficient L-Shape Fitting for Vehicle Detection Using Laser Scanners" (IEEE IV
2017): for every orientation ``theta`` of a grid over [0, pi/2), project a cluster's points on
``e1 = (cos theta, sin theta)`` and ``e2 = (-sin theta, cos theta)`` (``c1``, ``c2``) and score
the rectangle aligned with them by one criterion:

* **closeness** (the paper's choice): ``D1`` is whichever of ``max(c1) - c1`` and
  ``c1 - min(c1)`` has the smaller Euclidean norm over the cluster (the points hug that edge),
  ``D2`` likewise; the score is ``sum 1 / max(min(D1, D2), d0)`` with ``d0`` the floor
  ``cluster.lshape_closeness_floor_m``;
* **area**: minus the rectangle's area;
* **variance**: minus the variances of ``D1`` over the points nearer edge 1 (``D1 < D2``)
  and of ``D2`` over those nearer edge 2.

The orientation of the best score wins (the first on a tie). The fit is **accepted** when both
edges are seen: the points within ``cluster.lshape_inlier_m`` of edge 1 (``D1 <= D2``) and of
edge 2 number at least ``cluster.lshape_min_edge_inliers`` each (the source's "more than 5"),
and straight lines fitted to each edge's inliers (principal axis) are perpendicular within
``cluster.lshape_perpendicular_tol_deg``. A rejected cluster, or one with fewer than twice the
minimum inliers in all, keeps the minimum-area box (:mod:`pipeline.shape.box`).

The search is exhaustive on the grid (no coarse-to-fine step), so it equals a scalar
implementation of the same criterion on the same grid (``properties/oracles/lshape.py``).
Work: one (angles x points) block per scan, at most 90 / step x ``scan.max_beams`` values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from pipeline.config import ClusterSection
from pipeline.shape.box import cluster_geometry
from pipeline.types import BoolArray, Clusters, FloatArray, IntArray, Partition, ScanPoints

__all__ = ["CRITERIA", "LShapeFit", "LShapeShapes", "Workspace", "angle_grid", "lshape_fit"]

CRITERIA = ("closeness", "area", "variance")


@dataclass(frozen=True, slots=True)
class LShapeFit:
    """The fit of ``n`` clusters. ``accepted`` says whether the L-shape replaces the box;
    ``orientation_rad`` is the best ``theta`` in [0, pi/2); ``heading_rad`` the direction of the
    rectangle's longer side in [-pi/2, pi/2), ``width_m <= length_m`` its sides; ``score`` the
    criterion's best value; ``inliers`` (n, 2) the inlier count of each edge;
    ``perpendicular_error_rad`` how far the two edge lines are from perpendicular (NaN where
    an edge has fewer than two inliers). Clusters not searched (too few points) have
    ``accepted`` False and NaN geometry."""

    accepted: BoolArray
    orientation_rad: FloatArray
    heading_rad: FloatArray
    width_m: FloatArray
    length_m: FloatArray
    score: FloatArray
    inliers: IntArray
    perpendicular_error_rad: FloatArray


def angle_grid(step_deg: float) -> FloatArray:
    """The orientations searched: ``ceil(90 / step)`` evenly spaced angles from 0 below pi/2."""
    n = max(math.ceil(90.0 / step_deg - 1e-9), 1)
    grid: FloatArray = np.arange(n, dtype=np.float64) * (0.5 * math.pi / n)
    return grid


def _wrap_half_pi(angle: FloatArray) -> FloatArray:
    """A line direction (modulo pi) in [-pi/2, pi/2)."""
    return np.mod(angle + 0.5 * math.pi, math.pi) - 0.5 * math.pi


class Workspace:
    """Reused (angles x points) buffers: fresh blocks this large cost page faults every scan."""

    def __init__(self) -> None:
        self._buffers: dict[str, FloatArray] = {}

    def get(self, name: str, shape: tuple[int, int]) -> FloatArray:
        """A buffer of at least ``shape``, viewed at ``shape`` (contents undefined)."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape[0] != shape[0] or buf.shape[1] < shape[1]:
            buf = np.empty((shape[0], max(shape[1], 256)))
            self._buffers[name] = buf
        return buf[:, : shape[1]]


def _edge_distances(
    c: FloatArray, lab: IntArray, starts: IntArray, out: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``D`` (distance to the edge the points hug, per the closeness rule) and the extremes.

    The points are centred (``sum c = 0`` in every cluster), so ``||hi - c||^2 = n hi^2 +
    sum c^2`` and the nearer-edge choice of the norm reduces to ``hi <= -lo``; ``c`` lies
    between the extremes, so ``D = |edge - c|``.
    """
    hi = np.maximum.reduceat(c, starts, axis=-1)
    lo = np.minimum.reduceat(c, starts, axis=-1)
    edge = np.where(hi <= -lo, hi, lo)
    np.take(edge, lab, axis=1, out=out)
    np.subtract(out, c, out=out)
    np.abs(out, out=out)
    return out, hi, lo


def _scores(
    d1: FloatArray,
    d2: FloatArray,
    extent: FloatArray,
    lab: IntArray,
    starts: IntArray,
    criterion: str,
    floor_m: float,
    tmp: FloatArray,
) -> FloatArray:
    """(angles, clusters) score of every candidate rectangle (module docstring)."""
    if criterion == "area":
        return -extent
    if criterion == "closeness":
        np.minimum(d1, d2, out=tmp)
        np.maximum(tmp, floor_m, out=tmp)
        np.reciprocal(tmp, out=tmp)
        return np.add.reduceat(tmp, starts, axis=-1)
    # variance: population variance of each edge's distances (0 for an empty edge)
    total = np.zeros(extent.shape)
    for d, mask in ((d1, d1 < d2), (d2, d2 < d1)):
        n = np.add.reduceat(mask.astype(np.float64), starts, axis=-1)
        s1 = np.add.reduceat(np.where(mask, d, 0.0), starts, axis=-1)
        safe = np.maximum(n, 1.0)
        mean = s1 / safe
        dev = np.where(mask, d - mean[..., lab], 0.0)
        total -= np.add.reduceat(dev * dev, starts, axis=-1) / safe
    return total


def _principal_angle(
    x: FloatArray, y: FloatArray, weight: FloatArray, lab: IntArray, n: int
) -> tuple[FloatArray, FloatArray]:
    """Direction of the principal axis of the weighted points of each cluster, and the count."""
    w = np.bincount(lab, weights=weight, minlength=n).astype(np.float64)
    safe = np.maximum(w, 1.0)
    mx = np.bincount(lab, weights=weight * x, minlength=n) / safe
    my = np.bincount(lab, weights=weight * y, minlength=n) / safe
    dx, dy = x - mx[lab], y - my[lab]
    sxx = np.bincount(lab, weights=weight * dx * dx, minlength=n)
    syy = np.bincount(lab, weights=weight * dy * dy, minlength=n)
    sxy = np.bincount(lab, weights=weight * dx * dy, minlength=n)
    return 0.5 * np.arctan2(2.0 * sxy, sxx - syy), w


def lshape_fit(
    x_m: FloatArray,
    y_m: FloatArray,
    labels: IntArray,
    n_clusters: int,
    config: ClusterSection,
    work: Workspace | None = None,
) -> LShapeFit:
    """Fit an L-shape to the points of each label ``0..n_clusters-1`` (module docstring).

    ``work`` holds buffers reused from one call to the next (the shape role keeps one)."""
    if config.lshape_criterion not in CRITERIA:
        raise ValueError(f"lshape_fit: criterion {config.lshape_criterion!r} not in {CRITERIA}")
    n = n_clusters
    nan = np.full(n, np.nan)
    accepted = np.zeros(n, dtype=bool)
    inliers = np.zeros((n, 2), dtype=np.int64)
    member = (labels >= 0) & (labels < n)
    counts = np.bincount(labels[member], minlength=n)
    searched = counts >= 2 * config.lshape_min_edge_inliers
    keep = np.flatnonzero(member)
    keep = keep[searched[labels[keep]]]
    if keep.shape[0] == 0:
        return LShapeFit(
            accepted, nan, nan.copy(), nan.copy(), nan.copy(), nan.copy(), inliers, nan
        )
    clusters = np.flatnonzero(searched)
    order = keep[np.argsort(labels[keep], kind="stable")]
    lab = np.searchsorted(clusters, labels[order])  # 0..m-1 over the searched clusters
    m = clusters.shape[0]
    size = np.bincount(lab, minlength=m)
    starts = np.cumsum(size) - size
    # Centred coordinates: the projections' extremes keep full precision far from the scanner.
    cx = np.bincount(lab, weights=x_m[order], minlength=m) / size
    cy = np.bincount(lab, weights=y_m[order], minlength=m) / size
    px, py = x_m[order] - cx[lab], y_m[order] - cy[lab]

    theta = angle_grid(config.lshape_angle_step_deg)
    work = work if work is not None else Workspace()
    shape = (theta.shape[0], lab.shape[0])
    c1, c2, tmp = work.get("c1", shape), work.get("c2", shape), work.get("tmp", shape)
    cos, sin = np.cos(theta), np.sin(theta)
    np.multiply.outer(cos, px, out=c1)
    c1 += np.multiply.outer(sin, py, out=tmp)
    np.multiply.outer(cos, py, out=c2)
    c2 -= np.multiply.outer(sin, px, out=tmp)
    d1, hi1, lo1 = _edge_distances(c1, lab, starts, work.get("d1", shape))
    d2, hi2, lo2 = _edge_distances(c2, lab, starts, work.get("d2", shape))
    extent = (hi1 - lo1) * (hi2 - lo2)
    criterion, floor_m = config.lshape_criterion, config.lshape_closeness_floor_m
    score = _scores(d1, d2, extent, lab, starts, criterion, floor_m, tmp)
    best = np.argmax(score, axis=0)  # first maximum: ties go to the smaller angle
    cols = np.arange(m)
    e1 = hi1[best, cols] - lo1[best, cols]
    e2 = hi2[best, cols] - lo2[best, cols]
    orientation = theta[best]

    # Acceptance: both edges carry enough inliers and their fitted lines are perpendicular.
    k = best[lab]
    point = np.arange(lab.shape[0])
    pd1, pd2 = d1[k, point], d2[k, point]
    on_1 = (pd1 <= pd2) & (pd1 <= config.lshape_inlier_m)
    on_2 = (pd2 < pd1) & (pd2 <= config.lshape_inlier_m)
    a1, n1 = _principal_angle(px, py, on_1.astype(np.float64), lab, m)
    a2, n2 = _principal_angle(px, py, on_2.astype(np.float64), lab, m)
    apart = np.abs(_wrap_half_pi(a1 - a2))
    perpendicular_error = np.where((n1 >= 2) & (n2 >= 2), 0.5 * math.pi - apart, np.nan)
    tol = math.radians(config.lshape_perpendicular_tol_deg)
    need = config.lshape_min_edge_inliers
    ok = (n1 >= need) & (n2 >= need) & (perpendicular_error <= tol)

    long_is_1 = e1 >= e2
    heading = _wrap_half_pi(np.where(long_is_1, orientation, orientation + 0.5 * math.pi))
    out = {
        "orientation_rad": orientation,
        "heading_rad": heading,
        "width_m": np.minimum(e1, e2),
        "length_m": np.maximum(e1, e2),
        "score": score[best, cols],
        "perpendicular_error_rad": perpendicular_error,
    }
    full = {name: nan.copy() for name in out}
    for name, values in out.items():
        full[name][clusters] = values
    accepted[clusters] = ok
    inliers[clusters, 0] = n1.astype(np.int64)
    inliers[clusters, 1] = n2.astype(np.int64)
    return LShapeFit(accepted=accepted, inliers=inliers, **full)


@dataclass(frozen=True)
class LShapeShapes:
    """The shape role's L-shape estimator: the minimum-area geometry of every cluster
    (:func:`pipeline.shape.box.cluster_geometry`), with the box replaced by the L-shape
    rectangle where the fit is accepted (SR-TRK-7)."""

    config: ClusterSection
    work: Workspace = field(default_factory=Workspace, compare=False, repr=False)

    def clusters(self, points: ScanPoints, partition: Partition) -> Clusters:
        """The kept clusters of ``partition`` with their geometry."""
        base = cluster_geometry(points, partition, self.config)
        labels, n = partition.point_labels, partition.n_clusters
        fit = lshape_fit(points.x_m, points.y_m, labels, n, self.config, self.work)
        use = fit.accepted
        if not use.any():
            return base
        width = np.where(use, fit.width_m, base.width_m)
        length = np.where(use, fit.length_m, base.length_m)
        area = width * length
        return replace(
            base,
            width_m=width,
            length_m=length,
            heading_rad=np.where(use, fit.heading_rad, base.heading_rad),
            area_m2=area,
            point_density_per_m2=base.n_points / np.maximum(area, self.config.density_min_area_m2),
        )
