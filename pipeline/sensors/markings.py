"""Retro-reflective ground markings from a multi-ring LiDAR's intensity (#25; SR-MRK-1, SR-MRK-2).

A horizontal 2-D scanner cannot see floor paint; a multi-ring LiDAR's lower rings hit the
ground, and retro-reflective paint returns several times the intensity of asphalt. The
detector, on one revolution (:class:`RingScan`, robot frame, ``z`` up from the ground under the
robot):

1. ground separation: returns within 3 tolerances of ``z = 0`` and ``max_ground_range_m``
   seed a least-squares plane ``z = a x + b y + c``; returns within ``ground_tolerance_m`` of
   it are ground (a person's retro-reflective vest is above it and never a marking);
2. range normalisation: ``I_norm = I_raw (range / ref_range_m)^2`` (:func:`normalised`),
   divided by the incidence cosine against the fitted plane when ``incidence_correction``
   (received power of a diffuse surface falls as ``cos(incidence) / range^2``);
3. threshold: a ground return is paint when ``I_norm > threshold_factor x`` the median ground
   ``I_norm`` of the scan (most of the ground is asphalt, so the median is asphalt's level);
4. a bird's-eye grid of ``bev_cell_m`` cells (each occupied cell is the mean of its returns),
   clustered with the project's DBSCAN (:func:`pipeline.cluster.dbscan.dbscan_points`);
5. lines and arcs per cluster (:mod:`pipeline.sensors.marking_fit`).

Map matching of the fitted features is :mod:`pipeline.sensors.localisation`. Everything here
is a localisation aid: nothing in the perception or safety chain reads it (SR-MRK-4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.cluster.dbscan import dbscan_points
from pipeline.config import MarkingsSection
from pipeline.errors import SafecaseError
from pipeline.sensors.marking_fit import Arc, Line, fit_features
from pipeline.types import BoolArray, FloatArray, IntArray, freeze_fields
from pipeline.types.tracking import DropCounts, ScanPoints

__all__ = [
    "MIN_COS_INCIDENCE",
    "Markings",
    "RingScan",
    "RingScanError",
    "detect_markings",
    "normalised",
]

# Incidence cosines below this (grazing returns beyond ~85 deg) are clamped: dividing by a
# near-zero cosine would turn noise into paint.
MIN_COS_INCIDENCE = 0.02


class RingScanError(SafecaseError, ValueError):
    """A ring scan whose arrays disagree in length or hold non-finite values."""


@dataclass(frozen=True, slots=True)
class RingScan:
    """One revolution of a multi-ring LiDAR in the robot frame: returns at ``(x_m, y_m, z_m)``
    (``z_m`` up from the ground under the robot), ``range_m`` from the sensor at
    ``sensor_xyz_m``, raw ``intensity`` and ``ring`` index; stamped ``stamp_s``."""

    stamp_s: float
    x_m: FloatArray
    y_m: FloatArray
    z_m: FloatArray
    range_m: FloatArray
    intensity: FloatArray
    ring: IntArray
    sensor_xyz_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        freeze_fields(self, ("x_m", "y_m", "z_m", "range_m", "intensity"), np.float64)
        freeze_fields(self, ("ring",), np.int64)
        n = self.x_m.shape[0]
        for name in ("y_m", "z_m", "range_m", "intensity", "ring"):
            if getattr(self, name).shape != (n,):
                raise RingScanError(f"RingScan: {name} must have shape ({n},)")
        values = (self.x_m, self.y_m, self.z_m, self.range_m, self.intensity)
        if not all(np.isfinite(v).all() for v in values):
            raise RingScanError("RingScan: every coordinate, range and intensity must be finite")
        if n and (self.range_m <= 0).any():
            raise RingScanError("RingScan: ranges must be > 0")

    @property
    def n(self) -> int:
        """Number of returns."""
        return int(self.x_m.shape[0])


@dataclass(frozen=True, slots=True)
class Markings:
    """What the detector found in one scan (module docstring).

    Per return: ``is_ground``, ``i_norm`` (NaN off the ground), ``is_marking``. The scan's
    ``median_ground`` ``I_norm`` and the ``threshold`` applied. Per occupied bird's-eye cell:
    ``cell_x_m``, ``cell_y_m`` (robot frame), ``cell_feature`` (index into ``lines`` then
    ``arcs``, -1 for none). ``n_clusters`` kept clusters."""

    stamp_s: float
    is_ground: BoolArray
    i_norm: FloatArray
    is_marking: BoolArray
    median_ground: float
    threshold: float
    cell_x_m: FloatArray
    cell_y_m: FloatArray
    cell_feature: IntArray
    n_clusters: int
    lines: tuple[Line, ...]
    arcs: tuple[Arc, ...]

    def __post_init__(self) -> None:
        freeze_fields(self, ("is_ground", "is_marking"), np.bool_)
        freeze_fields(self, ("i_norm", "cell_x_m", "cell_y_m"), np.float64)
        freeze_fields(self, ("cell_feature",), np.int64)

    def feature_points(self) -> tuple[FloatArray, FloatArray]:
        """The cells some line or arc explains: what map matching aligns [m]."""
        on = self.cell_feature >= 0
        return self.cell_x_m[on], self.cell_y_m[on]


def normalised(intensity: FloatArray, range_m: FloatArray, ref_range_m: float) -> FloatArray:
    """``I_norm = I_raw (range / ref_range)^2`` (#25; SR-MRK-1)."""
    ratio = range_m / ref_range_m
    return intensity * (ratio * ratio)


def _ground(scan: RingScan, config: MarkingsSection) -> tuple[BoolArray, FloatArray]:
    """Ground mask and the fitted plane's unit normal (module docstring, step 1)."""
    tol = config.ground_tolerance_m
    horiz = np.hypot(scan.x_m - scan.sensor_xyz_m[0], scan.y_m - scan.sensor_xyz_m[1])
    near = horiz <= config.max_ground_range_m
    seed = near & (np.abs(scan.z_m) <= 3.0 * tol)
    normal = np.array([0.0, 0.0, 1.0])
    plane = np.zeros(3)
    if seed.sum() >= 3:
        a = np.stack([scan.x_m[seed], scan.y_m[seed], np.ones(int(seed.sum()))], axis=1)
        sol, _, rank, _ = np.linalg.lstsq(a, scan.z_m[seed], rcond=None)
        if rank == 3:
            plane = np.asarray(sol, dtype=np.float64)
            normal = np.array([-sol[0], -sol[1], 1.0]) / math.sqrt(1.0 + sol[0] ** 2 + sol[1] ** 2)
    height = scan.z_m - (plane[0] * scan.x_m + plane[1] * scan.y_m + plane[2])
    return near & (np.abs(height) <= tol), normal


def _bev_cells(x_m: FloatArray, y_m: FloatArray, cell_m: float) -> tuple[FloatArray, FloatArray]:
    """Occupied cells of the bird's-eye grid, each the mean of its points [m]."""
    if x_m.shape[0] == 0:
        return np.zeros(0), np.zeros(0)
    i = np.floor(x_m / cell_m).astype(np.int64)
    j = np.floor(y_m / cell_m).astype(np.int64)
    _, cell, count = np.unique(
        np.stack([i, j], axis=1), axis=0, return_inverse=True, return_counts=True
    )
    cell = cell.reshape(-1)
    return np.bincount(cell, x_m) / count, np.bincount(cell, y_m) / count


def _cluster_cells(
    x_m: FloatArray, y_m: FloatArray, sensor_xy: tuple[float, float], config: MarkingsSection
) -> IntArray:
    """Cluster label per cell (-1: noise or too small), by the project's DBSCAN."""
    n = x_m.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    dx, dy = x_m - sensor_xy[0], y_m - sensor_xy[1]
    angle = np.arctan2(dy, dx)
    angle = np.where(angle >= math.pi, angle - 2.0 * math.pi, angle)
    order = np.argsort(angle, kind="stable")
    points = ScanPoints(
        stamp_s=0.0,
        x_m=x_m[order],
        y_m=y_m[order],
        angle_rad=angle[order],
        range_m=np.hypot(dx, dy)[order],
        beam_index=order,
        drops=DropCounts(n, n, 0, 0, 0, 0),
    )
    raw = dbscan_points(points, config.cluster_eps_m, config.cluster_min_samples)
    sizes = np.bincount(raw.labels[raw.labels >= 0], minlength=raw.n_clusters)
    small = np.concatenate([sizes < config.min_cluster_cells, [True]])
    labels = np.where(small[raw.labels], -1, raw.labels)
    out = np.empty(n, dtype=np.int64)
    out[order] = labels
    return out


def detect_markings(scan: RingScan, config: MarkingsSection) -> Markings:
    """Markings of one revolution (module docstring; SR-MRK-1, SR-MRK-2).

    Deterministic: RANSAC draws from a generator seeded with ``ransac_seed`` afresh each scan.
    """
    is_ground, normal = _ground(scan, config)
    sx, sy, sz = scan.sensor_xyz_m
    i_norm = normalised(scan.intensity, scan.range_m, config.ref_range_m)
    if config.incidence_correction:
        ray = (
            np.stack([scan.x_m - sx, scan.y_m - sy, scan.z_m - sz], axis=1) / scan.range_m[:, None]
        )
        cos_inc = np.maximum(np.abs(ray @ normal), MIN_COS_INCIDENCE)
        i_norm = i_norm / cos_inc
    i_norm = np.where(is_ground, i_norm, np.nan)
    median = float(np.median(i_norm[is_ground])) if is_ground.any() else math.nan
    threshold = config.threshold_factor * median
    is_marking = is_ground & (np.nan_to_num(i_norm, nan=-math.inf) > threshold)
    cx, cy = _bev_cells(scan.x_m[is_marking], scan.y_m[is_marking], config.bev_cell_m)
    labels = _cluster_cells(cx, cy, (sx, sy), config)
    feature = np.full(cx.shape[0], -1, dtype=np.int64)
    lines: list[Line] = []
    arcs: list[Arc] = []
    rng = np.random.default_rng(config.ransac_seed)
    n_clusters = int(np.unique(labels[labels >= 0]).shape[0])
    for label in np.unique(labels[labels >= 0]):
        budget = config.max_features - len(lines) - len(arcs)
        if budget <= 0:
            break
        members = np.flatnonzero(labels == label)
        fits = fit_features(cx[members], cy[members], config, rng, budget)
        # Renumber: this cluster's lines after the lines so far; arcs are placed after all
        # lines once every cluster is done.
        own = fits.feature_of_point
        n_l = len(fits.lines)
        is_line = (own >= 0) & (own < n_l)
        is_arc = own >= n_l
        feature[members[is_line]] = len(lines) + own[is_line]
        feature[members[is_arc]] = -2 - (len(arcs) + own[is_arc] - n_l)
        lines.extend(fits.lines)
        arcs.extend(fits.arcs)
    arc_cells = feature <= -2
    feature[arc_cells] = len(lines) + (-2 - feature[arc_cells])
    return Markings(
        stamp_s=scan.stamp_s,
        is_ground=is_ground,
        i_norm=i_norm,
        is_marking=is_marking,
        median_ground=median,
        threshold=threshold,
        cell_x_m=cx,
        cell_y_m=cy,
        cell_feature=feature,
        n_clusters=n_clusters,
        lines=tuple(lines),
        arcs=tuple(arcs),
    )
