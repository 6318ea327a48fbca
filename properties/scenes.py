"""Deterministic synthetic inputs for the clustering and tracking checks (SR-TRK-*).

* :func:`room_scan`: a ray-cast 2D LiDAR scan of a rectangular room with circular and box
  obstacles (the benchmark scene: 1080 beams, 8 obstacles);
* :func:`occlusion_sequence`: a multi-target detection sequence with occlusions, missed
  detections and clutter, and its ground truth, for the re-identification evaluation.

Every random choice comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.track.metrics import PositionsFrame
from pipeline.track.tracker import Detections
from pipeline.types import FloatArray, Scan

__all__ = ["Obstacle", "OcclusionScene", "occlusion_sequence", "random_obstacles", "room_scan"]


@dataclass(frozen=True, slots=True)
class Obstacle:
    """A circle (``half_w_m == 0``: radius ``radius_m``) or a box (half sizes, yaw)."""

    x_m: float
    y_m: float
    radius_m: float = 0.0
    half_w_m: float = 0.0
    half_l_m: float = 0.0
    yaw_rad: float = 0.0


def _ray_circle(c: FloatArray, s: FloatArray, ob: Obstacle) -> FloatArray:
    b = c * ob.x_m + s * ob.y_m
    disc = b * b - (ob.x_m**2 + ob.y_m**2 - ob.radius_m**2)
    t = b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((disc >= 0.0) & (t > 0.0), t, np.inf)


def _ray_segments(c: FloatArray, s: FloatArray, segs: FloatArray) -> FloatArray:
    """Distance along each ray (c, s) to the nearest of the segments (k, 4) or inf."""
    if segs.shape[0] == 0:
        return np.full(c.shape, np.inf)
    ax, ay, bx, by = (segs[:, i][None, :] for i in range(4))
    ex, ey = bx - ax, by - ay
    cc, ss = c[:, None], s[:, None]
    den = cc * ey - ss * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ax * ey - ay * ex) / den
        u = (ax * ss - ay * cc) / den
    hit = (np.abs(den) > 1e-12) & (t > 0.0) & (u >= 0.0) & (u <= 1.0)
    nearest: FloatArray = np.where(hit, t, np.inf).min(axis=1)
    return nearest


def _box_segments(ob: Obstacle) -> FloatArray:
    cy, sy = math.cos(ob.yaw_rad), math.sin(ob.yaw_rad)
    corners = [
        (ob.x_m + cy * u - sy * v, ob.y_m + sy * u + cy * v)
        for u, v in (
            (ob.half_l_m, ob.half_w_m),
            (-ob.half_l_m, ob.half_w_m),
            (-ob.half_l_m, -ob.half_w_m),
            (ob.half_l_m, -ob.half_w_m),
        )
    ]
    return np.array([(*corners[i], *corners[(i + 1) % 4]) for i in range(4)])


def room_scan(
    obstacles: list[Obstacle],
    rng: np.random.Generator,
    n_beams: int = 1080,
    fov_rad: float = 1.5 * math.pi,
    room: tuple[float, float, float, float] = (-4.0, 9.0, -6.0, 6.0),
    noise_std_m: float = 0.01,
    stamp_s: float = 0.0,
    seq: int = 0,
) -> Scan:
    """Ray-cast one scan from the origin inside the room ``(xmin, xmax, ymin, ymax)``."""
    angles = np.linspace(-fov_rad / 2.0, fov_rad / 2.0, n_beams, endpoint=fov_rad < 2 * math.pi)
    c, s = np.cos(angles), np.sin(angles)
    x0, x1, y0, y1 = room
    walls = np.array([[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]])
    boxes = [_box_segments(o) for o in obstacles if o.half_w_m > 0.0]
    segs = np.concatenate([walls, *boxes]) if boxes else walls
    r = _ray_segments(c, s, segs)
    for ob in obstacles:
        if ob.half_w_m == 0.0:
            r = np.minimum(r, _ray_circle(c, s, ob))
    r = r + rng.normal(0.0, noise_std_m, n_beams)
    return Scan(stamp_s=stamp_s, angles_rad=angles, ranges_m=r, seq=seq, source="room_scan")


def random_obstacles(rng: np.random.Generator, n: int) -> list[Obstacle]:
    """``n`` obstacles in front of the sensor: legs and poles (circles), carts and pallets."""
    out = []
    for _ in range(n):
        x, y = float(rng.uniform(0.8, 7.5)), float(rng.uniform(-5.0, 5.0))
        if rng.random() < 0.5:
            out.append(Obstacle(x, y, radius_m=float(rng.uniform(0.05, 0.4))))
        else:
            out.append(
                Obstacle(
                    x,
                    y,
                    half_w_m=float(rng.uniform(0.1, 0.4)),
                    half_l_m=float(rng.uniform(0.2, 0.8)),
                    yaw_rad=float(rng.uniform(-math.pi, math.pi)),
                )
            )
    return out


@dataclass(frozen=True, slots=True)
class OcclusionScene:
    """A detection sequence with its ground truth and what was hidden."""

    frames: list[tuple[Detections, PositionsFrame]]
    n_occlusions: int
    occluded_frames: int


def occlusion_sequence(
    rng: np.random.Generator,
    n_targets: int = 8,
    n_frames: int = 300,
    period_s: float = 0.1,
    occlusion_frames: tuple[int, int] = (8, 30),
    occlusions_per_target: int = 2,
    p_miss: float = 0.03,
    clutter_per_frame: float = 0.5,
    noise_std_m: float = 0.03,
) -> OcclusionScene:
    """Constant-velocity targets with gentle turns, hidden for whole stretches of frames.

    Targets keep their size (width, length) with 5 % measurement noise; each is hidden
    ``occlusions_per_target`` times for a uniform number of frames in ``occlusion_frames``;
    visible targets are still missed with probability ``p_miss``; clutter is Poisson with mean
    ``clutter_per_frame`` per frame, uniform over the area with small sizes. The truth lists
    every target in every frame (occluded ones too: they are still there).
    """
    area = 12.0
    pos = rng.uniform(-area, area, (n_targets, 2))
    heading = rng.uniform(-math.pi, math.pi, n_targets)
    speed = rng.uniform(0.2, 1.2, n_targets)
    size = np.stack([rng.uniform(0.2, 0.6, n_targets), rng.uniform(0.6, 1.4, n_targets)], 1)
    hidden = np.zeros((n_frames, n_targets), dtype=bool)
    n_occ = 0
    for k in range(n_targets):
        starts = np.sort(rng.choice(np.arange(15, n_frames - 40), occlusions_per_target, False))
        for start in starts:
            length = int(rng.integers(occlusion_frames[0], occlusion_frames[1] + 1))
            hidden[start : start + length, k] = True
            n_occ += 1
    frames: list[tuple[Detections, PositionsFrame]] = []
    for f in range(n_frames):
        heading += rng.normal(0.0, 0.03, n_targets)
        vel = speed[:, None] * np.stack([np.cos(heading), np.sin(heading)], 1)
        pos = pos + vel * period_s
        # Bounce off the area's edges so targets stay in the scene.
        out = np.abs(pos) > area
        heading = np.where(out.any(axis=1), heading + math.pi, heading)
        pos = np.clip(pos, -area, area)
        seen = ~hidden[f] & (rng.random(n_targets) >= p_miss)
        z = pos[seen] + rng.normal(0.0, noise_std_m, (int(seen.sum()), 2))
        wl = size[seen] * (1.0 + rng.normal(0.0, 0.05, (int(seen.sum()), 2)))
        n_clutter = int(rng.poisson(clutter_per_frame))
        cz = rng.uniform(-area, area, (n_clutter, 2))
        cwl = rng.uniform(0.05, 0.3, (n_clutter, 2))
        allz = np.concatenate([z, cz])
        allwl = np.concatenate([wl, cwl])
        stamp = f * period_s
        det = Detections(stamp, allz[:, 0], allz[:, 1], allwl[:, 0], allwl[:, 1])
        frames.append((det, PositionsFrame(np.arange(n_targets), pos.copy())))
    return OcclusionScene(frames, n_occ, int(hidden.sum()))
