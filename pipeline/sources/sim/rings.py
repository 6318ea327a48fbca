"""A simulated multi-ring LiDAR whose lower rings hit painted ground (#25; SR-MRK-1).

RS32 class: 32 rings from ``markings.elevation_min_deg`` to ``elevation_max_deg`` (-25..+15 deg
by default), spaced densely near the horizon and sparsely at the ends (:data:`RS32_PROFILE`,
an approximation of the class, not a datasheet copy), ``n_columns`` firings a revolution, mounted
``mount_z_m`` above flat ground at ``mount_x_m`` ahead of the robot's centre. Rays below the
horizon hit the ground (``z = 0``) unless a vertical cylinder (a person, a pole) blocks them
first; rays that hit nothing within :data:`MAX_RANGE_M` give no return. Objects are only such
cylinders; the 2-D simulator's world is not ray-cast here.

Intensity of a return (arbitrary units; :data:`GAIN` at ``ref_range_m`` for a surface of
reflectivity 1 hit head-on)::

    I_raw = GAIN * rho * cos(incidence) * (ref_range / range)^2 * (1 + intensity_std * N(0, 1))

clipped at 0, where ``rho`` is the surface's reflectivity (:class:`Surface`: retro-reflective
paint, asphalt with a per-return texture spread, wet paint losing a fraction of its own). The
beam's footprint on the ground, ``range x divergence / sin(depression)`` long along the ray,
is sampled at three points, so a return at a stripe's edge (or far away, where the footprint
is long) mixes paint and asphalt. Ranges carry ``range_std_m`` noise. Every random draw comes
from the passed :class:`numpy.random.Generator`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import MarkingsSection
from pipeline.frames import to_parent
from pipeline.sensors.marking_map import MarkingMap
from pipeline.sensors.markings import RingScan
from pipeline.types import FloatArray, Pose

__all__ = [
    "GAIN",
    "MAX_RANGE_M",
    "RS32_PROFILE",
    "Cylinders",
    "RingTruth",
    "Surface",
    "ring_elevations_deg",
    "ring_scan",
]

GAIN = 100.0
MAX_RANGE_M = 100.0
# Ring elevations of the RS32 class on its native -25..+15 deg span: 0.33 deg apart around the
# horizon, widening to about 5 deg at the ends. Scaled linearly to the configured span.
RS32_PROFILE: tuple[float, ...] = (
    -25.0, -19.6, -15.4, -12.3, -10.0, -8.3, -7.0, -6.0, -5.3, -4.7, -4.0,
    -3.3, -3.0, -2.7, -2.3, -2.0, -1.7, -1.3, -1.0, -0.7, -0.3, 0.0,
    0.3, 0.7, 1.0, 1.3, 1.7, 3.0, 5.0, 7.0, 10.0, 15.0,
)  # fmt: skip
# Offsets along the footprint's length at which the surface is sampled (a box filter).
_FOOTPRINT = np.array([-1.0 / 3.0, 0.0, 1.0 / 3.0])


@dataclass(frozen=True, slots=True)
class Surface:
    """Ground reflectivities: ``paint`` (retro-reflective, dry), ``asphalt`` with a relative
    per-return spread ``asphalt_spread`` (texture, patches), and ``paint_loss``: the fraction of
    the paint's reflectivity lost to water (0 dry; up to 0.8 wet, #25)."""

    paint: float = 0.6
    asphalt: float = 0.1
    asphalt_spread: float = 0.2
    paint_loss: float = 0.0

    def __post_init__(self) -> None:
        if not (0.0 < self.asphalt < self.paint <= 1.0):
            raise ValueError(f"Surface: need 0 < asphalt < paint <= 1, got {self}")
        if not (0.0 <= self.paint_loss < 1.0 and 0.0 <= self.asphalt_spread < 1.0):
            raise ValueError(f"Surface: paint_loss and asphalt_spread must be in [0, 1): {self}")

    @property
    def wet_paint(self) -> float:
        """The paint's reflectivity after the loss."""
        return self.paint * (1.0 - self.paint_loss)


@dataclass(frozen=True, slots=True)
class Cylinders:
    """Vertical cylinders standing on the ground in the map frame: centres ``(x_m, y_m)``,
    ``radius_m``, ``height_m``, ``reflectivity`` (a retro-reflective vest is about 0.8)."""

    x_m: FloatArray
    y_m: FloatArray
    radius_m: FloatArray
    height_m: FloatArray
    reflectivity: FloatArray

    @staticmethod
    def none() -> Cylinders:
        """No objects."""
        e = np.zeros(0)
        return Cylinders(e, e, e, e, e)


@dataclass(frozen=True, slots=True)
class RingTruth:
    """What each return of a :func:`ring_scan` really hit: ``paint_fraction`` of its footprint
    on paint (0 off the ground), ``on_ground`` (else a cylinder), and its map-frame position."""

    paint_fraction: FloatArray
    on_ground: FloatArray
    map_x_m: FloatArray
    map_y_m: FloatArray


def ring_elevations_deg(config: MarkingsSection) -> FloatArray:
    """The 32 ring elevations [deg] (:data:`RS32_PROFILE` scaled to the configured span)."""
    base = np.array(RS32_PROFILE, dtype=np.float64)
    frac = (base - base[0]) / (base[-1] - base[0])
    span = config.elevation_max_deg - config.elevation_min_deg
    return np.asarray(config.elevation_min_deg + frac * span, dtype=np.float64)


def _cylinder_hits(
    sx: float, sy: float, hx: FloatArray, hy: FloatArray, cyl: Cylinders
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Horizontal distance to the first cylinder along each ray (inf for none), its index and
    the cosine between the horizontal ray and the surface normal there."""
    n = hx.shape[0]
    if cyl.x_m.shape[0] == 0:
        return np.full(n, np.inf), np.zeros(n, dtype=np.int64), np.ones(n)
    ox, oy = cyl.x_m[None, :] - sx, cyl.y_m[None, :] - sy
    b = hx[:, None] * ox + hy[:, None] * oy
    disc = b * b - (ox * ox + oy * oy - cyl.radius_m[None, :] ** 2)
    u = np.where(disc >= 0, b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
    u = np.where(u > 0, u, np.inf)
    k = np.argmin(u, axis=1)
    rows = np.arange(n)
    dist = u[rows, k]
    safe = np.where(np.isfinite(dist), dist, 0.0)
    nx = (sx + safe * hx - cyl.x_m[k]) / cyl.radius_m[k]
    ny = (sy + safe * hy - cyl.y_m[k]) / cyl.radius_m[k]
    return dist, k, np.abs(nx * hx + ny * hy)


def ring_scan(
    config: MarkingsSection,
    pose: Pose,
    marking_map: MarkingMap,
    surface: Surface,
    rng: np.random.Generator,
    *,
    stamp_s: float = 0.0,
    cylinders: Cylinders | None = None,
) -> tuple[RingScan, RingTruth]:
    """One revolution from the robot at ``pose`` (map frame) over ``marking_map`` (module
    docstring), and what each return hit."""
    cyl = Cylinders.none() if cylinders is None else cylinders
    elev = np.deg2rad(ring_elevations_deg(config))
    n_col = config.n_columns
    az = -math.pi + 2.0 * math.pi * np.arange(n_col) / n_col
    ring = np.repeat(np.arange(elev.shape[0]), n_col)
    e, a = elev[ring], np.tile(az, elev.shape[0])
    ce, se = np.cos(e), np.sin(e)
    h = config.mount_z_m
    mount = (config.mount_x_m, 0.0)
    # Slant range to the ground (rays below the horizon) and to the first cylinder.
    t_ground = np.where(se < 0, h / np.maximum(-se, 1e-12), np.inf)
    sx, sy = to_parent(pose, mount[0], mount[1])
    hx, hy = np.cos(a + pose[2]), np.sin(a + pose[2])
    u_cyl, k_cyl, cos_cyl = _cylinder_hits(sx, sy, hx, hy, cyl)
    t_cyl = u_cyl / ce
    z_cyl = np.where(np.isfinite(t_cyl), h + np.where(np.isfinite(t_cyl), t_cyl, 0.0) * se, -1.0)
    cyl_ok = np.isfinite(t_cyl) & (z_cyl >= 0.0)
    if cyl.x_m.shape[0]:
        cyl_ok &= z_cyl <= cyl.height_m[k_cyl]
    hit_cyl = cyl_ok & (t_cyl < t_ground)
    t = np.where(hit_cyl, t_cyl, t_ground)
    keep = t <= MAX_RANGE_M
    ring, e, a, ce, se, t = ring[keep], e[keep], a[keep], ce[keep], se[keep], t[keep]
    hit_cyl, k_cyl, cos_cyl, hx, hy = hit_cyl[keep], k_cyl[keep], cos_cyl[keep], hx[keep], hy[keep]
    n = t.shape[0]
    # The footprint on the ground, sampled along the ray's horizontal direction.
    u = t * ce
    length = t * config.divergence_mrad * 1e-3 / np.maximum(-se, 1e-3)
    fx = sx + (u[:, None] + length[:, None] * _FOOTPRINT[None, :]) * hx[:, None]
    fy = sy + (u[:, None] + length[:, None] * _FOOTPRINT[None, :]) * hy[:, None]
    paint = marking_map.on_paint(fx.reshape(-1), fy.reshape(-1)).reshape(n, -1).mean(axis=1)
    paint = np.where(hit_cyl, 0.0, paint)
    asphalt = surface.asphalt * np.maximum(
        1.0 + surface.asphalt_spread * rng.standard_normal(n), 0.0
    )
    rho_ground = paint * surface.wet_paint + (1.0 - paint) * asphalt
    rho = np.where(hit_cyl, cyl.reflectivity[k_cyl] if cyl.x_m.shape[0] else 0.0, rho_ground)
    cos_inc = np.where(hit_cyl, cos_cyl * ce, -se)
    ratio = config.ref_range_m / t
    noise = 1.0 + config.intensity_std * rng.standard_normal(n)
    intensity = np.maximum(GAIN * rho * cos_inc * ratio * ratio * noise, 0.0)
    t_meas = np.maximum(t + config.range_std_m * rng.standard_normal(n), 1e-3)
    x = mount[0] + t_meas * ce * np.cos(a)
    y = mount[1] + t_meas * ce * np.sin(a)
    z = h + t_meas * se
    mx, my = to_parent(pose, mount[0] + u * np.cos(a), mount[1] + u * np.sin(a))
    scan = RingScan(
        stamp_s=stamp_s,
        x_m=x,
        y_m=y,
        z_m=z,
        range_m=t_meas,
        intensity=intensity,
        ring=ring,
        sensor_xyz_m=(mount[0], mount[1], h),
    )
    truth = RingTruth(paint, (~hit_cyl).astype(np.float64), mx, my)
    return scan, truth
