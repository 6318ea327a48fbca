"""A second scanner merged with the first, per cycle, in the robot frame (SR-LID-1, SR-LID-2).

A robot with a front and a rear scanner sees all round although each scanner covers 270 deg.
Each cycle, :meth:`SecondScanner.merge` takes the first scanner's points and the frame's
second scan (:class:`~pipeline.types.SecondScan`) and decides, by the second scan's own stamp:

- **fresh** (the freshness guard with the first scanner's bound, ``monitors.scan_max_age_s``
  and ``monitors.clock_skew_s``: the latency the stopping proof assumes): its beams are
  sanitised with the ``scan`` section's limits, placed in the robot frame by the
  ``scan2.mount_*`` pose, moved to the first scan's stamp by odometry when both scans carry a
  pose (the robot moved between the two stamps), and merged;
- **blocked** (more than ``monitors.max_blocked_fraction`` of its beams below the minimum
  range: a covered window), **stale** or **absent**: left out. The first scanner's points go
  on alone; the report says why, and the safety side decides what the robot does meanwhile
  (:mod:`safety.model.second_scanner`).

The merged points are re-expressed about the robot's origin: bearing ``atan2(y, x)``, range
``hypot(x, y)``, sorted by bearing. The clustering's angular neighbour window
(:mod:`pipeline.cluster.dbscan`) holds for any common origin, so it stays exact on the union;
the cluster ends' occlusion test (:mod:`pipeline.shape.ends`) then reads "nearer to the robot's
origin" for "nearer to the scanner". The second scanner's beams are numbered after the
first's (``beam_index`` + the first scan's beam count), so no beam of one is adjacent to a beam
of the other. ``drops`` stays the first scanner's: the scan monitors judge the first scanner;
the second's drop counts are in its report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from pipeline.config import MonitorSection, ScanSection, SecondScanSection
from pipeline.frames import to_child, to_parent
from pipeline.points import scan_to_points
from pipeline.roles import FreshnessGuard
from pipeline.types import DropCounts, Frame, ScanPoints

__all__ = ["SecondScanReport", "SecondScanState", "SecondScanner", "merge_points"]


class SecondScanState(str, Enum):
    """What became of a cycle's second scan."""

    MERGED = "merged"
    STALE = "stale"
    BLOCKED = "blocked"
    ABSENT = "absent"


@dataclass(frozen=True, slots=True)
class SecondScanReport:
    """One cycle's account of the second scanner (SR-LID-2), written to the audit log.

    ``stamp_s`` is the second scan's stamp and ``age_s`` its age when judged [s] (None when
    absent); ``n_points`` how many of its points were merged; ``drops`` its beams' drop counts
    (None when it was not sanitised); ``shift_m`` the largest distance odometry moved one of its
    points to the first scan's stamp [m].
    """

    state: SecondScanState
    stamp_s: float | None = None
    age_s: float | None = None
    n_points: int = 0
    drops: DropCounts | None = None
    shift_m: float = 0.0

    @property
    def merged(self) -> bool:
        """Whether the second scanner's points are in this cycle's points."""
        return self.state is SecondScanState.MERGED


def merge_points(first: ScanPoints, second: ScanPoints) -> ScanPoints:
    """The union of two robot-frame point sets about the robot's origin (module docstring).

    ``second``'s ``beam_index`` is offset by ``first.drops.n_beams``; the result keeps
    ``first``'s stamp and drop counts. Serves SR-LID-1.
    """
    x_m = np.concatenate([first.x_m, second.x_m])
    y_m = np.concatenate([first.y_m, second.y_m])
    beam = np.concatenate([first.beam_index, second.beam_index + first.drops.n_beams])
    angle = np.arctan2(y_m, x_m)
    # arctan2 gives (-pi, pi]; the sweep order wants [-pi, pi) as scan_to_points has it.
    angle = np.where(angle >= math.pi, angle - 2.0 * math.pi, angle)
    order = np.argsort(angle, kind="stable")
    return ScanPoints(
        stamp_s=first.stamp_s,
        x_m=x_m[order],
        y_m=y_m[order],
        angle_rad=angle[order],
        range_m=np.hypot(x_m, y_m)[order],
        beam_index=beam[order],
        drops=first.drops,
    )


@dataclass(frozen=True)
class SecondScanner:
    """The second scanner's part of the points stage (module docstring). ``guard`` is the
    freshness formula (:func:`safety.model.freshness.is_fresh`)."""

    scan: ScanSection
    second: SecondScanSection
    monitors: MonitorSection
    guard: FreshnessGuard

    def merge(
        self, frame: Frame, first: ScanPoints, now_s: float
    ) -> tuple[ScanPoints, SecondScanReport]:
        """``first`` with the frame's second scan merged when it is fresh and not blocked at
        decision time ``now_s`` [s], and the report of what was done (SR-LID-1, SR-LID-2)."""
        second = frame.second
        if second is None:
            return first, SecondScanReport(SecondScanState.ABSENT)
        stamp = second.scan.stamp_s
        age = now_s - stamp
        mon = self.monitors
        if not bool(self.guard(now_s, stamp, mon.scan_max_age_s, mon.clock_skew_s)):
            return first, SecondScanReport(SecondScanState.STALE, stamp, age)
        mount = (self.second.mount_x_m, self.second.mount_y_m, self.second.mount_yaw_rad)
        points = scan_to_points(second.scan, self.scan, mount)
        drops = points.drops
        if drops.n_below_min > mon.max_blocked_fraction * drops.n_beams:
            return first, SecondScanReport(SecondScanState.BLOCKED, stamp, age, 0, drops)
        x_m, y_m = points.x_m, points.y_m
        shift = 0.0
        if frame.pose is not None and second.pose is not None and frame.pose != second.pose:
            # Robot frame at the second stamp -> odometry -> robot frame at the first stamp.
            x_m, y_m = to_child(frame.pose, *to_parent(second.pose, x_m, y_m))
            shift = float(np.max(np.hypot(x_m - points.x_m, y_m - points.y_m), initial=0.0))
        moved = ScanPoints(
            points.stamp_s, x_m, y_m, points.angle_rad, points.range_m, points.beam_index, drops
        )
        report = SecondScanReport(SecondScanState.MERGED, stamp, age, points.n, drops, shift)
        return merge_points(first, moved), report
