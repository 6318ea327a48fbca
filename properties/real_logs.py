"""The real 2D LiDAR logs in ``../shared/data/real`` as named scan streams (SR-TRK-2, SR-TRK-5).

The folder sits beside the repository (GPL/LGPL data are not copied into it); tests that use
it skip with :data:`MISSING_REASON` when it is absent.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

from pipeline.sources.logs import (
    laserscan_topics,
    read_breezyslam,
    read_carmen,
    read_ros1_bag,
    restamped,
)
from pipeline.types import Scan

__all__ = ["MISSING_REASON", "REAL_DATA", "streams"]

REAL_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
MISSING_REASON = (
    f"real LiDAR logs not found at {REAL_DATA} (the shared data folder beside the repository; "
    "a fresh clone does not have it)"
)
# The corrected CSAIL log prints timestamps with six significant digits (steps of 10^4 s), so
# its scans are restamped at the nominal 10 Hz of the other logs; the others keep their stamps.
RESTAMP_PERIOD_S = {"csail-corrected.log.gz": 0.1}

Stream = tuple[str, Callable[[], Iterator[Scan]]]


def _restamped_carmen(path: Path, period_s: float) -> Iterator[Scan]:
    return restamped(read_carmen(path), period_s)


def streams(root: Path = REAL_DATA) -> list[Stream]:
    """Every scan stream of the real logs: one per bag topic, one per text log."""
    out: list[Stream] = []
    for bag in sorted((root / "leg_tracker").glob("*.bag")):
        for topic in laserscan_topics(bag):
            out.append((f"{bag.name}:{topic}", partial(read_ros1_bag, bag, topic)))
    for dat in sorted((root / "breezyslam").glob("*.dat")):
        out.append((dat.name, partial(read_breezyslam, dat)))
    for log in sorted((root / "carmen").glob("*.log.gz")):
        period = RESTAMP_PERIOD_S.get(log.name)
        if period is None:
            out.append((log.name, partial(read_carmen, log)))
        else:
            out.append((log.name, partial(_restamped_carmen, log, period)))
    return out
