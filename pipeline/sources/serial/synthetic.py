"""A deterministic synthetic scan source for the emulators (until the simulator lands).

:func:`synthetic_scans` ray-casts a rectangular room with a few moving round obstacles,
analytically and vectorised, and yields one :class:`Scan` per revolution. Every random
choice (room size, obstacles, noise, dropouts) comes from the ``numpy.random.Generator``
given, so the same seed gives the same scans. It serves requirement SR-DRV-* tests only; it
is not the simulator (``pipeline.sources.sim``) and makes no claim about realism.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from pipeline.types import Scan

__all__ = ["rplidar_angles", "scip_angles", "synthetic_scans"]

FloatArray = npt.NDArray[np.float64]


def rplidar_angles(n_beams: int) -> FloatArray:
    """``n_beams`` angles over a full turn in an RPLIDAR's clockwise sweep order (radians,
    counter-clockwise convention: 0, -step, -2 step, ...)."""
    return -np.arange(n_beams, dtype=np.float64) * (2.0 * np.pi / n_beams)


def scip_angles(
    first_step: int, last_step: int, front_step: int, steps_per_turn: int
) -> FloatArray:
    """The angles of SCIP steps ``first_step..last_step`` (radians, counter-clockwise)."""
    steps = np.arange(first_step, last_step + 1, dtype=np.float64)
    return (steps - front_step) * (2.0 * np.pi / steps_per_turn)


def synthetic_scans(
    rng: np.random.Generator,
    angles_rad: FloatArray,
    *,
    rate_hz: float = 10.0,
    count: int | None = None,
    max_range_m: float = 12.0,
    min_range_m: float = 0.05,
    noise_m: float = 0.005,
    dropout: float = 0.02,
    n_obstacles: int = 4,
    with_intensities: bool = False,
    start_s: float = 0.0,
    source: str = "synthetic",
) -> Iterator[Scan]:
    """Yield ``count`` scans (endlessly if None) of a room seen from its middle.

    Ranges beyond ``max_range_m`` or below ``min_range_m`` and random dropouts are NaN (no
    return). Intensities, when asked for, are qualities 0..63 falling with range.
    """
    angles = np.asarray(angles_rad, dtype=np.float64)
    half = rng.uniform(2.0, 8.0, size=2)  # room half-sizes (m)
    centres = rng.uniform(-0.8, 0.8, size=(n_obstacles, 2)) * half
    velocities = rng.normal(0.0, 0.5, size=(n_obstacles, 2))
    radii = rng.uniform(0.1, 0.5, size=n_obstacles)
    dx, dy = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        wall = np.minimum(
            np.where(dx != 0, half[0] / np.abs(dx), np.inf),
            np.where(dy != 0, half[1] / np.abs(dy), np.inf),
        )
    period = 1.0 / rate_hz
    index = 0
    while count is None or index < count:
        ranges = wall.copy()
        t = index * period
        for centre, velocity, radius in zip(centres, velocities, radii, strict=True):
            c = centre + velocity * t
            c = np.clip(c, -half + radius, half - radius)
            proj = c[0] * dx + c[1] * dy
            disc = proj**2 - (c @ c - radius**2)
            hit = (disc >= 0) & (proj > 0)
            near = proj - np.sqrt(np.where(hit, disc, 0.0))
            ranges = np.where(hit & (near > 0), np.minimum(ranges, near), ranges)
        ranges = ranges + rng.normal(0.0, noise_m, size=ranges.shape)
        lost = (rng.random(ranges.shape) < dropout) | (ranges > max_range_m)
        lost |= ranges < min_range_m
        ranges[lost] = np.nan
        intensities = None
        if with_intensities:
            intensities = np.where(lost, 0.0, np.clip(np.rint(63 - 4 * ranges), 1, 63))
        yield Scan(
            stamp_s=start_s + t,
            angles_rad=angles,
            ranges_m=ranges,
            intensities=intensities,
            beam_period_s=period / max(1, angles.shape[0]),
            seq=index,
            source=source,
        )
        index += 1
