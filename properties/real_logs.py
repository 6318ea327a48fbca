"""The real 2D LiDAR logs in ``../shared/data/real`` as log sources (SR-TRK-2, SR-TRK-5).

The folder sits beside the repository (GPL/LGPL data are not copied into it); tests that use
it skip with :data:`MISSING_REASON` when it is absent. Every log goes through the same stamp
rule as ``safecase run --log`` (:mod:`pipeline.sources.logs.stamps`); the two logs whose stamps
break it are re-stamped at their median scan interval, as a user would with ``--restamp``.
"""

from __future__ import annotations

from pathlib import Path

from pipeline.sources.logs.bags import laserscan_topics
from pipeline.sources.logs.source import LogSource
from pipeline.sources.logs.stamps import StampRule

__all__ = ["MISSING_REASON", "REAL_DATA", "RESTAMP_HZ", "streams"]

REAL_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
MISSING_REASON = (
    f"real LiDAR logs not found at {REAL_DATA} (the shared data folder beside the repository; "
    "a fresh clone does not have it)"
)
# The corrected CSAIL log prints its stamps with six significant digits (steps of 10^4 s): its
# scans come at the nominal 10 Hz. The corrected Intel log steps back 0.11 s at scan 295; its
# scans are 3.35 s apart (median). Every other log keeps its stamps.
RESTAMP_HZ = {"csail-corrected.log.gz": 10.0, "intel-corrected.log.gz": 1.0 / 3.35}


def streams(root: Path = REAL_DATA) -> list[LogSource]:
    """Every scan stream of the real logs: one per bag topic, one per text log (CARMEN logs with
    their odometry; the bags and the BreezySLAM log have none a pose can be read from)."""
    out: list[LogSource] = []
    for bag in sorted((root / "leg_tracker").glob("*.bag")):
        for topic in laserscan_topics(bag):
            out.append(LogSource(bag, scan_topic=topic))
    for dat in sorted((root / "breezyslam").glob("*.dat")):
        out.append(LogSource(dat))
    for log in sorted((root / "carmen").glob("*.log.gz")):
        rule = StampRule(restamp_hz=RESTAMP_HZ.get(log.name))
        out.append(LogSource(log, stamps=rule, odometry=True))
    return out
