"""Straight lines and circular arcs fitted to marking points by RANSAC (SR-MRK-2).

:func:`ransac_line` draws ``iterations`` pairs of points from a passed
:class:`numpy.random.Generator`, scores every candidate line at once (a trials x points table
of perpendicular distances), keeps the one of least truncated squared distance (MSAC: each
point costs its squared distance, at most ``inlier_m`` squared; ties: the first drawn) and
refines it by total least squares over its inliers (the principal axis), once more
re-selecting the inliers of the refined line. :func:`ransac_circle` does the same with triples
of points and their circumcircles (radius bounded), refined twice by the algebraic (Kasa)
least-squares circle of the inliers. :func:`fit_features` fits both to the points no feature
has claimed yet, round by round, and takes an arc only when it explains clearly more points
than the best line, so a straight stripe is never bent into a large arc.

The line fits are cross-checked against scikit-learn's ``RANSACRegressor`` on the same points
(properties/test_markings.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import MarkingsSection
from pipeline.types import BoolArray, FloatArray, IntArray

__all__ = [
    "ARC_OVER_LINE",
    "Arc",
    "Features",
    "Line",
    "arc_distance",
    "circle_lsq",
    "fit_features",
    "line_distance",
    "ransac_circle",
    "ransac_line",
]

# An arc must explain this many times the points of the best line to be taken instead of it.
ARC_OVER_LINE = 1.25


@dataclass(frozen=True, slots=True)
class Line:
    """A fitted straight stripe: its centre line from ``(x0_m, y0_m)`` to ``(x1_m, y1_m)`` (the
    extent of its inliers), ``n_inliers`` points within the tolerance, their ``rms_m``."""

    x0_m: float
    y0_m: float
    x1_m: float
    y1_m: float
    n_inliers: int
    rms_m: float

    @property
    def length_m(self) -> float:
        """End to end [m]."""
        return math.hypot(self.x1_m - self.x0_m, self.y1_m - self.y0_m)


@dataclass(frozen=True, slots=True)
class Arc:
    """A fitted arc: centre ``(cx_m, cy_m)``, ``radius_m``, from ``start_rad`` counter-clockwise
    over ``sweep_rad`` (> 0, the extent of its inliers); ``n_inliers`` and their ``rms_m``."""

    cx_m: float
    cy_m: float
    radius_m: float
    start_rad: float
    sweep_rad: float
    n_inliers: int
    rms_m: float


@dataclass(frozen=True, slots=True)
class Features:
    """Lines and arcs of one set of points; ``feature_of_point`` (n,) is each point's feature
    (lines first, then arcs, numbered in that order), -1 for a point no feature claimed."""

    lines: tuple[Line, ...]
    arcs: tuple[Arc, ...]
    feature_of_point: IntArray


def line_distance(
    x_m: FloatArray, y_m: FloatArray, px: float, py: float, ux: float, uy: float
) -> FloatArray:
    """Perpendicular distance of points to the infinite line through ``(px, py)`` along unit
    ``(ux, uy)`` [m]."""
    return np.abs((x_m - px) * uy - (y_m - py) * ux)


def arc_distance(x_m: FloatArray, y_m: FloatArray, cx: float, cy: float, r: float) -> FloatArray:
    """Distance of points to the full circle of centre ``(cx, cy)`` and radius ``r`` [m]."""
    return np.abs(np.hypot(x_m - cx, y_m - cy) - r)


def _msac_best(dist: FloatArray, inlier_m: float) -> int:
    """The trial (row) of least truncated squared distance (MSAC): among candidates with
    about as many inliers, the one they fit tightest, so a stray point that happens to fall
    inside a looser model's band does not win it the draw (ties: the first drawn)."""
    cost = np.minimum(dist * dist, inlier_m * inlier_m).sum(axis=1)
    return int(np.argmin(cost))


def _principal_axis(x: FloatArray, y: FloatArray) -> tuple[float, float, float, float]:
    mx, my = float(x.mean()), float(y.mean())
    cov = np.cov(np.stack([x - mx, y - my]), bias=True)
    _w, v = np.linalg.eigh(cov)
    ux, uy = float(v[0, 1]), float(v[1, 1])
    return mx, my, ux, uy


def ransac_line(
    x_m: FloatArray, y_m: FloatArray, inlier_m: float, iterations: int, rng: np.random.Generator
) -> tuple[tuple[float, float, float, float], BoolArray] | None:
    """The best line ``(px, py, ux, uy)`` (a point and a unit direction) and its inlier mask,
    or None for fewer than two distinct points (module docstring)."""
    n = x_m.shape[0]
    if n < 2:
        return None
    a = rng.integers(0, n, iterations)
    b = (a + rng.integers(1, n, iterations)) % n  # a second point, never the first
    dx, dy = x_m[b] - x_m[a], y_m[b] - y_m[a]
    length = np.hypot(dx, dy)
    good = length > 1e-9
    if not good.any():
        return None
    a, dx, dy, length = a[good], dx[good], dy[good], length[good]
    ux, uy = dx / length, dy / length
    dist = np.abs(
        (x_m[None, :] - x_m[a, None]) * uy[:, None] - (y_m[None, :] - y_m[a, None]) * ux[:, None]
    )
    best = _msac_best(dist, inlier_m)
    inliers = dist[best] <= inlier_m
    line = (float(x_m[a[best]]), float(y_m[a[best]]), float(ux[best]), float(uy[best]))
    for _ in range(2):
        if inliers.sum() < 2:
            break
        line = _principal_axis(x_m[inliers], y_m[inliers])
        inliers = line_distance(x_m, y_m, *line) <= inlier_m
    return line, inliers


def circle_lsq(x_m: FloatArray, y_m: FloatArray) -> tuple[float, float, float] | None:
    """The algebraic (Kasa) least-squares circle ``(cx, cy, r)`` of three or more points, or
    None when they are (nearly) collinear."""
    if x_m.shape[0] < 3:
        return None
    mx, my = float(x_m.mean()), float(y_m.mean())
    u, v = x_m - mx, y_m - my  # centred for conditioning
    a = np.stack([u, v, np.ones_like(u)], axis=1)
    sol, _, rank, _ = np.linalg.lstsq(a, u * u + v * v, rcond=None)
    if rank < 3:
        return None
    cx, cy = 0.5 * sol[0], 0.5 * sol[1]
    r2 = sol[2] + cx * cx + cy * cy
    if not (np.isfinite(r2) and r2 > 0):
        return None
    return float(cx + mx), float(cy + my), float(math.sqrt(r2))


def ransac_circle(
    x_m: FloatArray,
    y_m: FloatArray,
    inlier_m: float,
    radius_m: tuple[float, float],
    iterations: int,
    rng: np.random.Generator,
) -> tuple[tuple[float, float, float], BoolArray] | None:
    """The best circle ``(cx, cy, r)`` with ``r`` in ``radius_m`` and its inlier mask, or None
    (module docstring)."""
    n = x_m.shape[0]
    if n < 3:
        return None
    # Three distinct points per trial: the first three of a random permutation of each row.
    idx = np.argsort(rng.random((iterations, n)), axis=1)[:, :3]
    ax, ay = x_m[idx[:, 0]], y_m[idx[:, 0]]
    bx, by = x_m[idx[:, 1]] - ax, y_m[idx[:, 1]] - ay
    cx, cy = x_m[idx[:, 2]] - ax, y_m[idx[:, 2]] - ay
    d = 2.0 * (bx * cy - by * cx)
    ok = np.abs(d) > 1e-9
    safe = np.where(ok, d, 1.0)
    ux = (cy * (bx * bx + by * by) - by * (cx * cx + cy * cy)) / safe
    uy = (bx * (cx * cx + cy * cy) - cx * (bx * bx + by * by)) / safe
    r = np.hypot(ux, uy)
    ok &= (r >= radius_m[0]) & (r <= radius_m[1])
    if not ok.any():
        return None
    ox, oy, r = (ax + ux)[ok], (ay + uy)[ok], r[ok]
    dist = np.abs(np.hypot(x_m[None, :] - ox[:, None], y_m[None, :] - oy[:, None]) - r[:, None])
    best = _msac_best(dist, inlier_m)
    circle = (float(ox[best]), float(oy[best]), float(r[best]))
    inliers = dist[best] <= inlier_m
    for _ in range(2):
        refined = circle_lsq(x_m[inliers], y_m[inliers])
        if refined is None or not radius_m[0] <= refined[2] <= radius_m[1]:
            break
        circle = refined
        inliers = arc_distance(x_m, y_m, *circle) <= inlier_m
    return circle, inliers


def _covering_arc(angle_rad: FloatArray) -> tuple[float, float]:
    """The shortest counter-clockwise arc ``(start, sweep)`` covering every angle."""
    a = np.sort(np.mod(angle_rad, 2.0 * math.pi))
    gaps = np.diff(np.concatenate([a, [a[0] + 2.0 * math.pi]]))
    k = int(np.argmax(gaps))
    start = float(a[(k + 1) % a.shape[0]])
    return start, float(2.0 * math.pi - gaps[k])


def fit_features(
    x_m: FloatArray,
    y_m: FloatArray,
    config: MarkingsSection,
    rng: np.random.Generator,
    max_features: int | None = None,
) -> Features:
    """Lines and arcs from one cluster's points (module docstring; SR-MRK-2).

    Each round fits the best line and the best circle to the points no feature has claimed; the
    arc is taken only when it has more than ``ARC_OVER_LINE`` times the line's inliers (a short
    stripe fits a large circle as well as a line: the line wins), at least ``min_arc_inliers``;
    the line needs ``min_line_inliers`` inliers spanning ``min_line_length_m``. Fitting stops
    when neither is found or at ``max_features`` (default: the section's)."""
    cap = config.max_features if max_features is None else max_features
    n = x_m.shape[0]
    owner = np.full(n, -1, dtype=np.int64)
    lines: list[Line] = []
    arcs: list[tuple[Arc, IntArray]] = []
    free = np.ones(n, dtype=bool)
    radius = (config.arc_min_radius_m, config.arc_max_radius_m)
    while len(lines) + len(arcs) < cap:
        idx = np.flatnonzero(free)
        if idx.shape[0] < min(config.min_line_inliers, config.min_arc_inliers):
            break
        xs, ys = x_m[idx], y_m[idx]
        line = ransac_line(xs, ys, config.line_inlier_m, config.ransac_iterations, rng)
        n_line = 0
        if line is not None:
            (px, py, ux, uy), inl = line
            t = (xs[inl] - px) * ux + (ys[inl] - py) * uy
            if (
                inl.sum() >= config.min_line_inliers
                and float(np.ptp(t)) >= config.min_line_length_m
            ):
                n_line = int(inl.sum())
        circle = ransac_circle(xs, ys, config.arc_inlier_m, radius, config.ransac_iterations, rng)
        n_arc = 0 if circle is None else int(circle[1].sum())
        if (
            circle is not None
            and n_arc >= config.min_arc_inliers
            and n_arc > ARC_OVER_LINE * n_line
        ):
            (cx, cy, r), inl = circle
            res = arc_distance(xs[inl], ys[inl], cx, cy, r)
            start, sweep = _covering_arc(np.arctan2(ys[inl] - cy, xs[inl] - cx))
            rms = float(np.sqrt(np.mean(res * res)))
            arcs.append((Arc(cx, cy, r, start, sweep, n_arc, rms), idx[inl]))
        elif n_line and line is not None:
            (px, py, ux, uy), inl = line
            t = (xs[inl] - px) * ux + (ys[inl] - py) * uy
            res = line_distance(xs[inl], ys[inl], px, py, ux, uy)
            t0, t1 = float(t.min()), float(t.max())
            rms = float(np.sqrt(np.mean(res * res)))
            lines.append(Line(px + t0 * ux, py + t0 * uy, px + t1 * ux, py + t1 * uy, n_line, rms))
            owner[idx[inl]] = len(lines) - 1
        else:
            break
        free[idx[inl]] = False
    for k, (_, members) in enumerate(arcs):
        owner[members] = len(lines) + k
    return Features(tuple(lines), tuple(a for a, _ in arcs), owner)
