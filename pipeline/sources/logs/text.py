"""Text logs of 2D LiDAR scans: CARMEN and BreezySLAM, each an iterator of scans.

Formats:

* The BreezySLAM ``exp1.dat`` Hokuyo URG-04LX log: one scan a line, token 0 the timestamp in
  microseconds, tokens 24..705 the 682 ranges in millimetres over 240 degrees. Values below
  20 mm are the URG's error codes (no valid echo) and become NaN, so sanitation counts them as
  missing returns rather than as short ranges.
* CARMEN logs (optionally gzip-compressed): ``FLASER n r1..rn x y theta odom_x odom_y
  odom_theta timestamp host logger_timestamp`` lines, ranges in metres. FLASER carries no
  angles; the front laser is taken to span 180 degrees evenly, ``-pi/2 .. +pi/2`` (the SICK
  LMS convention of these data sets). ``odom_x odom_y odom_theta`` is the robot's odometry at
  the scan (:func:`read_carmen_odometry`).

A malformed line or message raises :class:`LogFormatError` naming the file, the line (or
message) and what was expected.
"""

from __future__ import annotations

import gzip
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from pipeline.errors import SafecaseError
from pipeline.types import FloatArray, Scan

__all__ = ["LogFormatError", "read_breezyslam", "read_carmen", "read_carmen_odometry"]

BREEZY_BEAMS = 682
BREEZY_FIRST_RANGE_TOKEN = 24
BREEZY_FOV_RAD = math.radians(240.0)
URG_ERROR_CODE_MAX_MM = 20.0


class LogFormatError(SafecaseError, ValueError):
    """A log file that does not follow its format."""


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


def _flaser(file: Path) -> Iterator[tuple[int, FloatArray, float, tuple[float, float, float]]]:
    """(line number, ranges, stamp, odometry pose) of every FLASER line."""
    for number, line in enumerate(_lines(file), start=1):
        if not line.startswith("FLASER "):
            continue
        tokens = line.split()
        try:
            n = int(tokens[1])
            ranges = np.array(tokens[2 : 2 + n], dtype=np.float64)
            odom = (float(tokens[n + 5]), float(tokens[n + 6]), float(tokens[n + 7]))
            stamp = float(tokens[2 + n + 6])
        except (IndexError, ValueError) as exc:
            raise LogFormatError(
                f"{file}:{number}: bad FLASER line ({exc}); expected 'FLASER n r1..rn x y "
                "theta odom_x odom_y odom_theta timestamp host logger_timestamp'"
            ) from None
        if ranges.shape[0] != n or n < 2:
            raise LogFormatError(f"{file}:{number}: FLASER announces {n} ranges, has {len(ranges)}")
        yield number, ranges, stamp, odom


def read_carmen(path: Path | str) -> Iterator[Scan]:
    """Front-laser scans (``FLASER`` lines) of a CARMEN log, plain or gzip-compressed."""
    file = Path(path)
    for seq, (_, ranges, stamp, _) in enumerate(_flaser(file)):
        n = ranges.shape[0]
        yield Scan(
            stamp_s=stamp,
            angles_rad=np.linspace(-math.pi / 2.0, math.pi / 2.0, n),
            ranges_m=ranges,
            seq=seq,
            source=file.name,
        )


def read_carmen_odometry(path: Path | str) -> FloatArray:
    """The odometry of every FLASER line as an (n, 4) array ``[stamp_s, x_m, y_m, yaw_rad]``:
    one row per scan of :func:`read_carmen`, in the same order."""
    file = Path(path)
    rows = [(stamp, *odom) for _, _, stamp, odom in _flaser(file)]
    out: FloatArray = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return out
