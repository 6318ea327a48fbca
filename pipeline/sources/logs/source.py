"""A recorded log as a source of frames: scans, odometry poses and the stamp rule (SR-TRK-5).

:class:`LogSource` reads a ROS 1 bag, a ROS 2 bag (folder, sqlite3 or MCAP), a bare MCAP file,
a CARMEN log or a BreezySLAM log, chosen by the path. Odometry, where the log has it (a
``nav_msgs/Odometry`` or ``/tf`` topic of a bag, the ``odom_*`` fields of CARMEN's FLASER
lines), gives
each frame the robot's pose at the scan's stamp, interpolated linearly between odometry
messages (yaw unwrapped); scans outside the odometry's time span are skipped and counted, never
given a guessed pose. Stamps follow :mod:`pipeline.sources.logs.stamps`: checked, or re-stamped
at a rate the user gives. Frames are delivered as recorded: ``received_s`` is the end of the
scan's sweep (its stamp plus the beams' duration).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from pipeline.sources.logs.bags import find_odometry, is_bag, read_bag, read_odometry
from pipeline.sources.logs.stamps import StampRule
from pipeline.sources.logs.text import (
    LogFormatError,
    read_breezyslam,
    read_carmen,
    read_carmen_odometry,
)
from pipeline.types import FloatArray, Frame, Pose, Scan

__all__ = ["LogSource", "log_kind", "poses_at"]

KINDS = ("bag", "carmen", "breezyslam")


def log_kind(path: Path) -> str:
    """``bag``, ``carmen`` or ``breezyslam`` by the path, or :class:`LogFormatError`."""
    name = path.name
    if is_bag(path):
        return "bag"
    if name.endswith((".log", ".log.gz", ".clf", ".clf.gz")):
        return "carmen"
    if name.endswith(".dat"):
        return "breezyslam"
    raise LogFormatError(
        f"{path}: unknown log format; allowed: a ROS 1 bag (.bag), a ROS 2 bag (folder with "
        "metadata.yaml), an MCAP file (.mcap), a CARMEN log (.log, .log.gz, .clf) or a "
        "BreezySLAM log (.dat)"
    )


def poses_at(odometry: FloatArray, stamps_s: FloatArray) -> FloatArray:
    """(n, 3) poses ``[x_m, y_m, yaw_rad]`` at ``stamps_s`` from odometry rows ``[stamp_s, x_m,
    y_m, yaw_rad]`` (sorted by stamp): linear in position and unwrapped yaw; NaN outside the
    odometry's span."""
    out = np.full((stamps_s.shape[0], 3), np.nan)
    if odometry.shape[0] == 0:
        return out
    order = np.argsort(odometry[:, 0], kind="stable")
    t, x, y = odometry[order, 0], odometry[order, 1], odometry[order, 2]
    yaw = np.unwrap(odometry[order, 3])
    inside = (stamps_s >= t[0]) & (stamps_s <= t[-1])
    s = stamps_s[inside]
    out[inside, 0] = np.interp(s, t, x)
    out[inside, 1] = np.interp(s, t, y)
    out[inside, 2] = np.interp(s, t, yaw)
    return out


@dataclass
class LogSource:
    """Frames of a recorded log (module docstring).

    ``scan_topic`` and ``odom_topic`` choose a bag's topics (the only LaserScan topic by
    default; an Odometry or a TFMessage topic). Without ``odom_topic`` there is no odometry
    unless ``odometry`` is True: then a bag's own (:func:`~pipeline.sources.logs.bags.
    find_odometry`: its only Odometry topic, else ``/tf``) and a CARMEN log's are used.
    ``odometry_from`` names what was used once :meth:`check` has run (None: no odometry).
    ``stamps`` is the stamp rule. ``skipped`` counts scans left out, by reason.
    """

    path: Path
    scan_topic: str | None = None
    odom_topic: str | None = None
    stamps: StampRule = field(default_factory=StampRule)
    odometry: bool = False
    skipped: dict[str, int] = field(default_factory=dict)
    odometry_from: str | None = field(default=None, init=False)
    live: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        self.kind = log_kind(self.path)
        if self.odom_topic is not None and self.kind != "bag":
            raise LogFormatError(f"{self.path}: --odom-topic applies to bags only")
        if self.scan_topic is not None and self.kind != "bag":
            raise LogFormatError(f"{self.path}: --scan-topic applies to bags only")
        self._checked: tuple[FloatArray, FloatArray | None] | None = None

    @property
    def name(self) -> str:
        """The log's file name (and topic)."""
        return f"{self.path.name}:{self.scan_topic}" if self.scan_topic else self.path.name

    def scans(self) -> Iterator[Scan]:
        """The log's scans as recorded (stamps unchecked)."""
        if self.kind == "bag":
            return read_bag(self.path, self.scan_topic)
        if self.kind == "carmen":
            return read_carmen(self.path)
        return read_breezyslam(self.path)

    def _poses(self, stamps_s: FloatArray) -> FloatArray | None:
        """Odometry poses at the recorded stamps, or None without odometry."""
        topic = self.odom_topic
        if self.kind == "bag" and topic is None and self.odometry:
            topic = find_odometry(self.path)
        if self.kind == "bag" and topic is not None:
            self.odometry_from = topic
            return poses_at(read_odometry(self.path, topic), stamps_s)
        if self.kind == "carmen" and self.odometry:
            self.odometry_from = "FLASER odometry"
            odom = read_carmen_odometry(self.path)
            return odom[:, 1:4]  # one row per scan, same order
        return None

    def check(self) -> tuple[FloatArray, FloatArray | None]:
        """Read the log once and apply the stamp rule and the odometry: the stamps to use and
        the poses at them (None without odometry). Raises :class:`LogFormatError` or
        :class:`~pipeline.sources.logs.stamps.LogStampError` before any frame is delivered."""
        if self._checked is None:
            raw = np.fromiter((s.stamp_s for s in self.scans()), dtype=np.float64)
            self._checked = (self.stamps.apply(raw, str(self.path)), self._poses(raw))
        return self._checked

    def frames(self) -> Iterator[Frame]:
        """One frame per usable scan: stamps by the rule, poses from the odometry."""
        stamps, poses = self.check()
        self.skipped.setdefault("outside the odometry", 0)
        for i, scan in enumerate(self.scans()):
            pose: Pose | None = None
            if poses is not None:
                if not np.all(np.isfinite(poses[i])):
                    self.skipped["outside the odometry"] += 1
                    continue
                pose = (float(poses[i, 0]), float(poses[i, 1]), float(poses[i, 2]))
            if stamps[i] != scan.stamp_s:
                scan = replace(scan, stamp_s=float(stamps[i]))
            sweep_s = scan.beam_period_s * max(scan.n_beams - 1, 0)
            yield Frame(scan, scan.stamp_s + sweep_s, pose=pose)
