"""Simulated 2D scanning LiDAR: beam layout, device presets and the sensor model (SR-SIM-1).

A :class:`Lidar` casts its beams from the scanner pose(s) into a
:class:`~pipeline.sources.sim.world.World` and returns the same :class:`~pipeline.types.Scan` a
serial driver produces, plus the per-beam ground truth (:class:`BeamTruth`). The sensor model,
applied to the exact geometric ranges in this order:

1. **mixed pixels**: at a depth jump larger than ``mixed_pixel_min_jump_m`` between two
   neighbouring beams that both hit something, with probability ``mixed_pixel_prob`` one of the
   two (chosen at random) returns a range drawn uniformly between the two surfaces, as a beam
   whose spot straddles an edge does;
2. **range noise**: zero-mean Gaussian with ``range_noise_std_m``, clipped at
   ``noise_clip_sigma`` standard deviations, so that every returned range lies within
   :attr:`LidarSpec.noise_bound_m` of its (possibly mixed) true value;
3. **range limits**: a measured range outside ``[min_range_m, max_range_m]`` is no return (NaN);
4. **dropouts**: each beam independently returns nothing (NaN) with ``dropout_prob``;
5. **weather** (only when one of its fields is set, :mod:`pipeline.sources.sim.weather`): a
   return beyond :attr:`LidarSpec.attenuated_max_range_m` (two-way extinction
   ``extinction_per_m``) is lost, each beam is lost with ``weather_dropout_prob``, and with
   ``backscatter_prob`` a beam returns a spurious range drawn uniformly from
   ``[min_range_m, backscatter_max_range_m]`` when that is nearer than its own return and
   than the surface it meets.

With ``time_skew`` the beams of one revolution are taken at their own times
``stamp_s + i * beam_period_s`` while the scanner and the objects move; otherwise every beam
sees the world at ``stamp_s`` and the scan reports ``beam_period_s = 0``. All randomness comes
from the ``numpy.random.Generator`` given; the same number of draws is made every scan, so a
seed reproduces a run bit for bit (SR-SIM-2). The weather's draws are made only when weather is
set, so a scanner without weather draws (and returns) exactly steps 1-4's numbers
(SR-SIM-6).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pipeline.sources.sim.raycast import NO_HIT, RayCaster, cast_per_beam
from pipeline.sources.sim.world import World
from pipeline.types import BoolArray, FloatArray, IntArray, Scan, frozen_array

__all__ = [
    "DEVICE_PRESETS",
    "NO_RETURN_ID",
    "STRUCTURE_ID",
    "BeamTruth",
    "Lidar",
    "LidarSpec",
    "ScannerPoses",
    "attenuated_range_m",
]

STRUCTURE_ID = -2  # per-beam owner of a beam that hit static structure
NO_RETURN_ID = -1  # per-beam owner of a beam that hit nothing within range

ScannerPoses = Callable[[FloatArray], FloatArray]
"""Scanner pose(s) in the world frame at the given times: ``(T,)`` -> ``(T, 3)`` (x, y, yaw)."""


def attenuated_range_m(max_range_m: float, extinction_per_m: float) -> float:
    """The farthest range [m] at which the clear-air threshold target still returns:
    ``R`` with ``R^2 exp(2 alpha R) = R0^2``, i.e. ``ln R + alpha R = ln R0``. Newton's method
    from ``R0`` on that concave increasing function: the first step lands below the root (at
    ``R0 / (1 + alpha R0) > 0``) and the iterates then rise monotonically to it."""
    if extinction_per_m <= 0.0:
        return max_range_m
    r = max_range_m
    target = math.log(max_range_m)
    for _ in range(60):
        f = math.log(r) + extinction_per_m * r - target
        step = f / (1.0 / r + extinction_per_m)
        r -= step
        if abs(step) <= 1e-12 * r:
            break
    return r


@dataclass(frozen=True, slots=True)
class LidarSpec:
    """Beam layout and sensor model of one scanner (metres, radians, seconds)."""

    name: str
    n_beams: int
    angle_min_rad: float
    angle_increment_rad: float
    scan_period_s: float
    min_range_m: float
    max_range_m: float
    range_noise_std_m: float = 0.0
    noise_clip_sigma: float = 3.0
    dropout_prob: float = 0.0
    mixed_pixel_prob: float = 0.0
    mixed_pixel_min_jump_m: float = 0.3
    time_skew: bool = False
    extinction_per_m: float = 0.0
    weather_dropout_prob: float = 0.0
    backscatter_prob: float = 0.0
    backscatter_max_range_m: float = 2.5

    def __post_init__(self) -> None:
        problems = []
        if self.n_beams < 2:
            problems.append(f"n_beams {self.n_beams} must be >= 2")
        if not (
            self.angle_increment_rad > 0
            and self.n_beams * self.angle_increment_rad <= 2 * math.pi + 1e-9
        ):
            problems.append(
                f"angle_increment_rad {self.angle_increment_rad} x n_beams must be in (0, 2 pi]"
            )
        if not (self.scan_period_s > 0):
            problems.append(f"scan_period_s {self.scan_period_s} must be > 0")
        if not (0 <= self.min_range_m < self.max_range_m):
            problems.append(
                f"need 0 <= min_range_m ({self.min_range_m}) < max_range_m ({self.max_range_m})"
            )
        if self.range_noise_std_m < 0 or self.noise_clip_sigma < 0:
            problems.append("range_noise_std_m and noise_clip_sigma must be >= 0")
        if not (math.isfinite(self.extinction_per_m) and self.extinction_per_m >= 0):
            problems.append(f"extinction_per_m {self.extinction_per_m} must be >= 0")
        if not self.backscatter_max_range_m > self.min_range_m:
            problems.append(
                f"backscatter_max_range_m {self.backscatter_max_range_m} must exceed "
                f"min_range_m {self.min_range_m}"
            )
        for name in (
            "dropout_prob",
            "mixed_pixel_prob",
            "weather_dropout_prob",
            "backscatter_prob",
        ):
            if not (0 <= getattr(self, name) <= 1):
                problems.append(f"{name} {getattr(self, name)} must be in [0, 1]")
        if problems:
            raise ValueError(f"LidarSpec {self.name}: " + "; ".join(problems))

    @property
    def angles_rad(self) -> FloatArray:
        """Beam angles in the scanner frame, counter-clockwise, 0 straight ahead."""
        index = np.arange(self.n_beams, dtype=np.float64)
        return np.asarray(self.angle_min_rad + self.angle_increment_rad * index, dtype=np.float64)

    @property
    def beam_period_s(self) -> float:
        """Time between two beams of a rotating scanner (scan period x increment / 2 pi)."""
        return self.scan_period_s * self.angle_increment_rad / (2 * math.pi)

    @property
    def noise_bound_m(self) -> float:
        """Largest range error added by noise (clip x standard deviation)."""
        return self.noise_clip_sigma * self.range_noise_std_m

    @property
    def full_circle(self) -> bool:
        """Whether the beams cover the whole circle (the last beam neighbours the first)."""
        return abs(self.n_beams * self.angle_increment_rad - 2 * math.pi) < 1e-9

    @property
    def weather_active(self) -> bool:
        """Whether any weather effect is set (then, and only then, weather draws are made)."""
        return (
            self.extinction_per_m > 0.0
            or self.weather_dropout_prob > 0.0
            or self.backscatter_prob > 0.0
        )

    @property
    def attenuated_max_range_m(self) -> float:
        """The farthest return under the two-way extinction: ``R`` with
        ``R^2 exp(2 extinction R) = max_range^2`` (SR-SIM-6)."""
        return attenuated_range_m(self.max_range_m, self.extinction_per_m)

    def exact(self) -> LidarSpec:
        """The same layout with every sensor effect off (exact geometric ranges)."""
        return replace(
            self,
            range_noise_std_m=0.0,
            dropout_prob=0.0,
            mixed_pixel_prob=0.0,
            extinction_per_m=0.0,
            weather_dropout_prob=0.0,
            backscatter_prob=0.0,
        )

    def with_changes(self, **changes: Any) -> LidarSpec:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    @staticmethod
    def generic(
        n_beams: int,
        fov_rad: float = 2 * math.pi,
        *,
        scan_rate_hz: float = 10.0,
        min_range_m: float = 0.05,
        max_range_m: float = 30.0,
        **sensor: Any,
    ) -> LidarSpec:
        """Evenly spaced beams over ``fov_rad`` centred straight ahead (a full circle starts
        at -pi and leaves out +pi, which is the same direction)."""
        if fov_rad >= 2 * math.pi - 1e-12:
            inc, start = 2 * math.pi / n_beams, -math.pi
        else:
            inc, start = fov_rad / (n_beams - 1), -fov_rad / 2
        return LidarSpec(
            name=f"generic_{n_beams}",
            n_beams=n_beams,
            angle_min_rad=start,
            angle_increment_rad=inc,
            scan_period_s=1.0 / scan_rate_hz,
            min_range_m=min_range_m,
            max_range_m=max_range_m,
            **sensor,
        )


def _urg04lx() -> LidarSpec:
    # SCIP 2.0 "PP" reply of the URG-04LX: DMIN 20 mm, DMAX 5600 mm, ARES 1024 steps per
    # revolution, AMIN 44, AMAX 725, AFRT 384 (front), SCAN 600 rpm.
    inc = 2 * math.pi / 1024
    return LidarSpec("hokuyo_urg04lx", 725 - 44 + 1, (44 - 384) * inc, inc, 0.1, 0.02, 5.6)


DEVICE_PRESETS: dict[str, Callable[[], LidarSpec]] = {
    "hokuyo_urg04lx": _urg04lx,
    # Hokuyo UST-10LX datasheet: 270 deg at 0.25 deg (1081 steps), 0.06-10 m, 25 ms per scan.
    "hokuyo_ust10lx": lambda: LidarSpec(
        "hokuyo_ust10lx", 1081, math.radians(-135.0), math.radians(0.25), 0.025, 0.06, 10.0
    ),
    # RPLIDAR A2M8: 8 kHz sampling (125 us per sample) at 10 Hz gives 800 samples per
    # revolution; Slamtec's datasheet range 0.15-12 m.
    "rplidar_a2": lambda: LidarSpec(
        "rplidar_a2", 800, -math.pi, 2 * math.pi / 800, 0.1, 0.15, 12.0
    ),
}


@dataclass(frozen=True, slots=True)
class BeamTruth:
    """Per-beam ground truth of one scan.

    ``true_range_m``: exact geometric range of the first hit (``inf``: nothing within
    ``max_range_m``). ``owner_id``: object id hit, :data:`STRUCTURE_ID` or :data:`NO_RETURN_ID`.
    ``mixed``: the beam returned a mixed pixel. ``dropout``: the beam was dropped at random.
    ``beam_time_s``: when each beam was taken. ``weather_lost``: the beam's return was lost to
    extinction or rain; ``spurious``: it returned a backscatter range (both all False without
    weather).
    """

    true_range_m: FloatArray
    owner_id: IntArray
    mixed: BoolArray
    dropout: BoolArray
    beam_time_s: FloatArray
    weather_lost: BoolArray
    spurious: BoolArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "true_range_m", frozen_array(self.true_range_m))
        object.__setattr__(self, "owner_id", frozen_array(self.owner_id, np.int64))
        object.__setattr__(self, "mixed", frozen_array(self.mixed, np.bool_))
        object.__setattr__(self, "dropout", frozen_array(self.dropout, np.bool_))
        object.__setattr__(self, "beam_time_s", frozen_array(self.beam_time_s))
        object.__setattr__(self, "weather_lost", frozen_array(self.weather_lost, np.bool_))
        object.__setattr__(self, "spurious", frozen_array(self.spurious, np.bool_))


class Lidar:
    """A scanner that produces :class:`Scan` objects from a world (one per call)."""

    def __init__(self, spec: LidarSpec, rng: np.random.Generator) -> None:
        self.spec = spec
        self._rng = rng
        self._caster = RayCaster()
        self._angles = spec.angles_rad
        self._static: tuple[int, FloatArray, FloatArray] | None = None

    def _static_edges(self, world: World) -> tuple[FloatArray, FloatArray]:
        if self._static is None or self._static[0] != id(world):
            st = world.structure.outline
            self._static = (id(world), st.vertices_m[st.edge_from], st.vertices_m[st.edge_to])
        return self._static[1], self._static[2]

    def geometric_ranges(
        self, world: World, poses: ScannerPoses, stamp_s: float
    ) -> tuple[FloatArray, IntArray, FloatArray]:
        """Exact first-hit ranges, the owner id of each beam and the beam times."""
        spec = self.spec
        n = spec.n_beams
        times: FloatArray
        if spec.time_skew:
            times = stamp_s + spec.beam_period_s * np.arange(n, dtype=np.float64)
        else:
            times = np.full(n, float(stamp_s))
        sa, sb = self._static_edges(world)
        dyn = world.dynamic_outline
        n_static = sa.shape[0]
        owners_of_edges = np.concatenate(
            [np.full(n_static, STRUCTURE_ID, dtype=np.int64), world.object_ids[world.edge_owner]]
        )
        if not spec.time_skew:
            pose = poses(times[:1])[0]
            dirs = np.stack([np.cos(pose[2] + self._angles), np.sin(pose[2] + self._angles)], 1)
            verts = world.object_vertices(times[:1])[0]
            a = np.concatenate([sa, verts[dyn.edge_from]], axis=0)
            b = np.concatenate([sb, verts[dyn.edge_to]], axis=0)
            ranges, edge = self._caster.cast_snapshot(pose[:2], dirs, a, b, spec.max_range_m)
        else:
            pose = poses(times)
            yaw = pose[:, 2] + self._angles
            dirs = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
            origins = np.ascontiguousarray(pose[:, :2])
            ranges, edge = self._caster.cast_moving_origin(origins, dirs, sa, sb, spec.max_range_m)
            if dyn.n_vertices:
                verts = world.object_vertices(times)  # (B, V, 2): each beam's own instant
                r_dyn, e_dyn = cast_per_beam(
                    origins, dirs, verts[:, dyn.edge_from], verts[:, dyn.edge_to], spec.max_range_m
                )
                closer = r_dyn < ranges
                ranges = np.where(closer, r_dyn, ranges)
                edge = np.where(closer, e_dyn + n_static, edge)
        owner = np.where(edge == NO_HIT, NO_RETURN_ID, owners_of_edges[np.maximum(edge, 0)])
        return ranges, owner.astype(np.int64), times

    def scan(
        self,
        world: World,
        poses: ScannerPoses,
        stamp_s: float,
        *,
        seq: int = 0,
        source: str = "sim",
    ) -> tuple[Scan, BeamTruth]:
        """One revolution starting at ``stamp_s``: the scan and its per-beam ground truth."""
        spec = self.spec
        true_r, owner, times = self.geometric_ranges(world, poses, stamp_s)
        n = spec.n_beams
        rng = self._rng
        # Fixed draws per scan, whatever the scene, so runs stay aligned across seeds' uses.
        noise = np.clip(rng.standard_normal(n), -spec.noise_clip_sigma, spec.noise_clip_sigma)
        u_mix = rng.random(n)
        u_side = rng.random(n)
        alpha = rng.random(n)
        u_drop = rng.random(n)
        measured = true_r.copy()
        mixed = np.zeros(n, dtype=np.bool_)
        if spec.mixed_pixel_prob > 0:
            nxt = np.roll(true_r, -1)
            with np.errstate(invalid="ignore"):  # inf - inf where both beams saw nothing
                step = np.abs(nxt - true_r)
            jump = np.isfinite(true_r) & np.isfinite(nxt) & (step > spec.mixed_pixel_min_jump_m)
            if not spec.full_circle:
                jump[-1] = False
            pick = np.flatnonzero(jump & (u_mix < spec.mixed_pixel_prob))
            take_next = u_side[pick] >= 0.5
            beam = np.where(take_next, (pick + 1) % n, pick)
            value = true_r[pick] + alpha[pick] * (nxt[pick] - true_r[pick])
            measured[beam] = value  # a beam picked twice keeps the later pick (deterministic)
            mixed[beam] = True
        measured = measured + noise * spec.range_noise_std_m
        out_of_range = ~((measured >= spec.min_range_m) & (measured <= spec.max_range_m))
        dropout = u_drop < spec.dropout_prob
        measured[out_of_range | dropout] = np.nan
        lost = spurious = np.zeros(n, dtype=bool)
        if spec.weather_active:
            measured, lost, spurious = self._weather(measured, true_r)
        scan = Scan(
            stamp_s=float(stamp_s),
            angles_rad=self._angles,
            ranges_m=measured,
            beam_period_s=spec.beam_period_s if spec.time_skew else 0.0,
            seq=seq,
            source=source,
        )
        truth = BeamTruth(true_r, owner, mixed, dropout, times, lost, spurious)
        return scan, truth

    def _weather(
        self, measured: FloatArray, true_r: FloatArray
    ) -> tuple[FloatArray, BoolArray, BoolArray]:
        """Weather effects on the measured ranges (module docstring, step 5): three fixed
        draws per beam whatever the scene. Droplets echo only in front of the surface the beam
        meets (``true_r``) and only when nearer than what the beam measured."""
        spec, rng = self.spec, self._rng
        n = spec.n_beams
        u_lost = rng.random(n)
        u_back = rng.random(n)
        u_range = rng.random(n)
        with np.errstate(invalid="ignore"):
            lost = np.isfinite(measured) & (
                (measured > spec.attenuated_max_range_m) | (u_lost < spec.weather_dropout_prob)
            )
        out = np.where(lost, np.nan, measured)
        echo = spec.min_range_m + u_range * (spec.backscatter_max_range_m - spec.min_range_m)
        # NaN (no return) counts as farther than any echo; inf (nothing hit) too.
        nearer = ~(out <= echo) & (echo < true_r)
        spurious = (u_back < spec.backscatter_prob) & nearer
        out[spurious] = echo[spurious]
        return out, lost, spurious
