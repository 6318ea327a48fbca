"""Scan sanitation: polar beams to Cartesian points in the robot frame (requirement SR-TRK-1).

A beam becomes a point only when its range is a finite number inside
``[scan.min_range_m, scan.max_range_m]``. Every other beam is dropped and counted by reason
(NaN, +/-inf, below minimum, above maximum) in :class:`pipeline.types.DropCounts`, which the
runtime monitors read; nothing is guessed or clamped. A scan with more beams than
``scan.max_beams`` is refused with :class:`ScanError` so per-cycle work stays bounded (SR-TIM-3).

Points are returned sorted by sensor bearing wrapped to [-pi, pi): the clustering stage uses
that order to find neighbours in a narrow angular window instead of over all pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import ScanSection
from pipeline.errors import SafecaseError
from pipeline.types import DropCounts, Pose, Scan, ScanPoints

__all__ = ["RangeFilter", "ScanError", "scan_to_points"]

_TWO_PI = 2.0 * math.pi


class ScanError(SafecaseError, ValueError):
    """A scan the pipeline refuses to process (too many beams for the configured cap)."""


def scan_to_points(scan: Scan, config: ScanSection, mount: Pose | None = None) -> ScanPoints:
    """Sanitize ``scan`` and convert its valid beams to robot-frame points (SR-TRK-1).

    Ranges are in metres, angles in radians (sensor frame, counter-clockwise); the sensor pose
    ``mount`` (default the section's ``(mount_x_m, mount_y_m, mount_yaw_rad)``; a second
    scanner's is its own) maps them into the robot frame. Raises :class:`ScanError` when
    ``scan.n_beams`` exceeds ``config.max_beams`` (SR-TIM-3).
    """
    mount_x, mount_y, mount_yaw = (
        (config.mount_x_m, config.mount_y_m, config.mount_yaw_rad) if mount is None else mount
    )
    if scan.n_beams > config.max_beams:
        raise ScanError(
            f"scan {scan.source or '<unnamed>'} seq {scan.seq}: {scan.n_beams} beams; "
            f"expected at most scan.max_beams = {config.max_beams}"
        )
    ranges = scan.ranges_m
    finite = np.isfinite(ranges)
    n_nan = int(np.count_nonzero(np.isnan(ranges)))
    n_inf = int(ranges.shape[0] - n_nan - np.count_nonzero(finite))
    # Comparisons with NaN/inf are done on finite values only so the categories stay disjoint.
    finite_ranges = np.where(finite, ranges, config.min_range_m)
    below = finite & (finite_ranges < config.min_range_m)
    above = finite & (finite_ranges > config.max_range_m)
    valid = finite & ~below & ~above
    drops = DropCounts(
        n_beams=scan.n_beams,
        n_valid=int(np.count_nonzero(valid)),
        n_nan=n_nan,
        n_inf=n_inf,
        n_below_min=int(np.count_nonzero(below)),
        n_above_max=int(np.count_nonzero(above)),
    )
    index = np.flatnonzero(valid)
    range_m = ranges[index]
    # Bearing in the robot frame, wrapped to [-pi, pi) so that sorting gives the sweep order.
    angle = np.mod(scan.angles_rad[index] + mount_yaw + math.pi, _TWO_PI) - math.pi
    if angle.shape[0] > 1 and np.any(np.diff(angle) < 0.0):
        order = np.argsort(angle, kind="stable")
        angle, range_m, index = angle[order], range_m[order], index[order]
    x_m = mount_x + range_m * np.cos(angle)
    y_m = mount_y + range_m * np.sin(angle)
    return ScanPoints(
        stamp_s=scan.stamp_s,
        x_m=x_m,
        y_m=y_m,
        angle_rad=angle,
        range_m=range_m,
        beam_index=index.astype(np.int64),
        drops=drops,
    )


@dataclass(frozen=True)
class RangeFilter:
    """The scan filter role's default: :func:`scan_to_points` with the ``scan`` section."""

    config: ScanSection

    def points(self, scan: Scan) -> ScanPoints:
        """The valid beams of ``scan`` as robot-frame points, the others counted."""
        return scan_to_points(scan, self.config)
