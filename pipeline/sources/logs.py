"""Readers for recorded 2D LiDAR logs, each an iterator of :class:`pipeline.types.Scan`.

Formats (see ``../shared/data/real/README.md``):

* ROS1 bags with ``sensor_msgs/LaserScan`` messages (e.g. the leg_tracker bags), read with the
  ``rosbags`` package (a runtime dependency: ``safecase`` replays bags). One stream per topic;
  angles from ``angle_min + i * angle_increment``, ``beam_period_s`` from ``time_increment``.
* The BreezySLAM ``exp1.dat`` Hokuyo URG-04LX log: one scan a line, token 0 the timestamp in
  microseconds, tokens 24..705 the 682 ranges in millimetres over 240 degrees. Values below
  20 mm are the URG's error codes (no valid echo) and become NaN, so sanitation counts them as
  missing returns rather than as short ranges.
* CARMEN logs (optionally gzip-compressed): ``FLASER n r1..rn x y theta odom_x odom_y
  odom_theta timestamp host logger_timestamp`` lines, ranges in metres. FLASER carries no
  angles; the front laser is taken to span 180 degrees evenly, ``-pi/2 .. +pi/2`` (the SICK
  LMS convention of these data sets).

A malformed line or message raises :class:`LogFormatError` naming the file, the line (or
message) and what was expected.
"""

from __future__ import annotations

import gzip
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.errors import SafecaseError
from pipeline.types import Scan

__all__ = [
    "LogFormatError",
    "laserscan_topics",
    "read_breezyslam",
    "read_carmen",
    "read_ros1_bag",
    "restamped",
]

BREEZY_BEAMS = 682
BREEZY_FIRST_RANGE_TOKEN = 24
BREEZY_FOV_RAD = math.radians(240.0)
URG_ERROR_CODE_MAX_MM = 20.0
LASERSCAN = "sensor_msgs/msg/LaserScan"


class LogFormatError(SafecaseError, ValueError):
    """A log file that does not follow its format."""


def laserscan_topics(path: Path | str) -> list[str]:
    """The topics of a ROS1 bag that carry ``sensor_msgs/LaserScan`` messages."""
    from rosbags.rosbag1 import Reader

    with Reader(Path(path)) as reader:
        return sorted({c.topic for c in reader.connections if c.msgtype == LASERSCAN})


def read_ros1_bag(path: Path | str, topic: str | None = None) -> Iterator[Scan]:
    """Scans of one LaserScan topic of a ROS1 bag (the only one when ``topic`` is None)."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    file = Path(path)
    typestore = get_typestore(Stores.ROS1_NOETIC)
    with Reader(file) as reader:
        connections = [c for c in reader.connections if c.msgtype == LASERSCAN]
        topics = sorted({c.topic for c in connections})
        if topic is None:
            if len(topics) != 1:
                raise LogFormatError(
                    f"{file}: {len(topics)} LaserScan topics {topics}; expected exactly one, "
                    "or name one with topic="
                )
            topic = topics[0]
        chosen = [c for c in connections if c.topic == topic]
        if not chosen:
            raise LogFormatError(f"{file}: no LaserScan topic {topic!r}; found {topics}")
        for index, (connection, _, raw) in enumerate(reader.messages(connections=chosen)):
            msg: Any = typestore.deserialize_ros1(raw, connection.msgtype)
            ranges = np.asarray(msg.ranges, dtype=np.float64)
            n = ranges.shape[0]
            if not (math.isfinite(msg.angle_min) and math.isfinite(msg.angle_increment)):
                raise LogFormatError(f"{file}: message {index}: non-finite angle_min/increment")
            angles = msg.angle_min + msg.angle_increment * np.arange(n)
            intensities = np.asarray(msg.intensities, dtype=np.float64)
            yield Scan(
                stamp_s=msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec,
                angles_rad=angles,
                ranges_m=ranges,
                intensities=intensities if intensities.shape[0] == n else None,
                beam_period_s=max(float(msg.time_increment), 0.0),
                seq=int(msg.header.seq),
                source=f"{file.name}:{topic}",
            )


def _lines(file: Path) -> Iterator[str]:
    opener = gzip.open if file.suffix == ".gz" else open
    with opener(file, "rt", encoding="ascii", errors="replace") as handle:
        yield from handle


def read_breezyslam(path: Path | str) -> Iterator[Scan]:
    """Scans of a BreezySLAM ``.dat`` log (Hokuyo URG-04LX, 682 beams, 240 degrees)."""
    file = Path(path)
    angles = np.linspace(-BREEZY_FOV_RAD / 2.0, BREEZY_FOV_RAD / 2.0, BREEZY_BEAMS)
    seq = 0
    for number, line in enumerate(_lines(file), start=1):
        tokens = line.split()
        if not tokens:
            continue
        end = BREEZY_FIRST_RANGE_TOKEN + BREEZY_BEAMS
        if len(tokens) < end:
            raise LogFormatError(
                f"{file}:{number}: {len(tokens)} tokens; expected at least {end} "
                f"(timestamp, odometry, then {BREEZY_BEAMS} ranges in mm from token 24)"
            )
        try:
            stamp_us = int(tokens[0])
            mm = np.array(tokens[BREEZY_FIRST_RANGE_TOKEN:end], dtype=np.float64)
        except ValueError as exc:
            raise LogFormatError(f"{file}:{number}: not a number: {exc}") from None
        ranges = np.where(mm < URG_ERROR_CODE_MAX_MM, np.nan, mm * 1e-3)
        yield Scan(
            stamp_s=stamp_us * 1e-6,
            angles_rad=angles,
            ranges_m=ranges,
            seq=seq,
            source=file.name,
        )
        seq += 1


def read_carmen(path: Path | str) -> Iterator[Scan]:
    """Front-laser scans (``FLASER`` lines) of a CARMEN log, plain or gzip-compressed."""
    file = Path(path)
    seq = 0
    for number, line in enumerate(_lines(file), start=1):
        if not line.startswith("FLASER "):
            continue
        tokens = line.split()
        try:
            n = int(tokens[1])
            ranges = np.array(tokens[2 : 2 + n], dtype=np.float64)
            stamp = float(tokens[2 + n + 6])
        except (IndexError, ValueError) as exc:
            raise LogFormatError(
                f"{file}:{number}: bad FLASER line ({exc}); expected 'FLASER n r1..rn x y "
                "theta odom_x odom_y odom_theta timestamp host logger_timestamp'"
            ) from None
        if ranges.shape[0] != n or n < 2:
            raise LogFormatError(f"{file}:{number}: FLASER announces {n} ranges, has {len(ranges)}")
        yield Scan(
            stamp_s=stamp,
            angles_rad=np.linspace(-math.pi / 2.0, math.pi / 2.0, n),
            ranges_m=ranges,
            seq=seq,
            source=file.name,
        )
        seq += 1


def restamped(scans: Iterator[Scan], period_s: float) -> Iterator[Scan]:
    """The same scans stamped ``seq * period_s`` from the first stamp.

    For logs whose timestamps lost their resolution (the corrected CSAIL CARMEN log prints
    them with six significant digits, i.e. in steps of 10^4 s): a tracker needs a clock.
    """
    first: float | None = None
    for index, scan in enumerate(scans):
        if first is None:
            first = scan.stamp_s
        yield Scan(
            stamp_s=first + index * period_s,
            angles_rad=scan.angles_rad,
            ranges_m=scan.ranges_m,
            intensities=scan.intensities,
            beam_period_s=scan.beam_period_s,
            seq=scan.seq,
            source=scan.source,
        )
