"""Serial link health, read by the runtime monitors (SR-DRV-3)."""

from __future__ import annotations

import enum
from dataclasses import dataclass


class DriverState(enum.Enum):
    """Health of a serial scanner link, as the runtime monitors read it (SR-DRV-3).

    ``OK``: valid frames arrive. ``DEGRADED``: valid frames arrive but some were rejected within
    the last silent timeout. ``STALE``: no valid frame for longer than the silent timeout.
    ``DISCONNECTED``: the port failed or is closed and a reconnect is pending. ``CONNECTING``:
    opening the port and handshaking. ``FAILED``: the reconnect budget is spent; the driver
    gives up. Only ``OK`` and ``DEGRADED`` mean the scans are fresh.
    """

    CONNECTING = "CONNECTING"
    OK = "OK"
    DEGRADED = "DEGRADED"
    STALE = "STALE"
    DISCONNECTED = "DISCONNECTED"
    FAILED = "FAILED"


@dataclass(frozen=True, slots=True)
class DriverHealth:
    """A snapshot of a driver's link health and counters at ``stamp_s`` (SR-DRV-2, SR-DRV-3).

    ``age_s`` is the time since the last valid frame (infinite before the first). Counters are
    totals since the driver was created: ``frames_rejected`` failed a checksum or check bit,
    ``bytes_discarded`` were skipped while re-synchronising, ``scans_incomplete`` were emitted
    with ``Scan.complete == False``, ``scans_dropped`` were withheld.
    """

    state: DriverState
    stamp_s: float
    age_s: float
    frames_ok: int = 0
    frames_rejected: int = 0
    bytes_discarded: int = 0
    scans_emitted: int = 0
    scans_incomplete: int = 0
    scans_dropped: int = 0
    reconnects: int = 0
    last_error: str = ""

    @property
    def fresh(self) -> bool:
        """True when the scans from this link may be used (state OK or DEGRADED)."""
        return self.state in (DriverState.OK, DriverState.DEGRADED)
