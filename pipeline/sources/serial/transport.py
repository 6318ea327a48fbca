"""The serial scanner driver: link, handshake, decoding, silence detection, reconnection and
a typed health state (requirements SR-DRV-2, SR-DRV-3).

:class:`Driver` is single-threaded and poll-based: :meth:`Driver.poll` reads what arrived
within ``read_timeout_s`` (never waiting past the moment the device would become silent),
decodes it and returns the completed revolutions. :meth:`Driver.health` can be called at any
time and computes the state from the clock, so a silent device reads ``STALE`` as soon as
``silent_timeout_s`` has passed since its last valid frame, whether or not ``poll`` ran since.
On silence or a port failure the driver closes the port and reopens it after
``reconnect_backoff_s``, handshaking again. A device that has never delivered a valid frame
is given ``max_reconnects`` further attempts, then the driver gives up (``FAILED``: the port
cannot be opened or the device does not answer) and :meth:`Driver.scans` raises
:class:`LinkError`. A device that has delivered frames and then went away is retried for as
long as the driver runs, the wait doubling from ``reconnect_backoff_s`` up to
``reconnect_backoff_max_s`` (the runtime meanwhile commands STOP: the link is not fresh).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator

import serial

from pipeline.config import DriverSection
from pipeline.errors import ConfigError
from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip
from pipeline.sources.serial.assembly import LinkCounters
from pipeline.sources.serial.errors import DriverError, LinkError
from pipeline.sources.serial.rplidar_stream import RplidarStream
from pipeline.sources.serial.scip_stream import ScipStream
from pipeline.sources.serial.sessions import (
    Opener,
    RplidarSession,
    ScipSession,
    SerialLink,
    start_rplidar,
    start_scip,
)
from pipeline.types import DriverHealth, DriverState, Scan

__all__ = ["Driver", "link_state"]


class Driver:
    """Reads one scanner (``config.protocol``) on ``config.port_url`` (SR-DRV-*)."""

    def __init__(
        self,
        config: DriverSection,
        *,
        clock: Callable[[], float] = time.monotonic,
        opener: Opener = serial.serial_for_url,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if not config.port_url:
            raise ConfigError(
                ["driver.port_url = '': allowed: a pyserial URL or device path to read from"]
            )
        self.config = config
        self.clock = clock
        self.opener = opener
        self.sleep = sleep
        self.counters = LinkCounters()
        self.session: RplidarSession | ScipSession | None = None
        self._link: SerialLink | None = None
        self._stream: RplidarStream | ScipStream | None = None
        self._pending = b""
        now = clock()
        self._last_frame_s = now
        self._watch_s = now  # silence is measured from the last frame or (re)connection
        self._last_reject_s = -float("inf")
        self._retry_at = now
        self._attempts = 0  # consecutive failed (re)connection attempts
        self._reconnects = 0
        self._opened = False
        self._connecting = True
        self._failed = False
        self._ever_connected = False  # a valid frame has arrived at least once
        self._last_error = ""

    # -- lifecycle -----------------------------------------------------------------------
    def open(self) -> None:
        """Open the port and start the device streaming (failures schedule a retry)."""
        self._opened = True
        self._connect(self.clock())

    def close(self) -> None:
        """Stop the device (best effort) and close the port."""
        link = self._link
        if link is not None:
            stop = (
                rp.encode_request(rp.Cmd.STOP)
                if self.config.protocol == "rplidar"
                else scip.ScipCommand(scip.Name.QT).encode()
            )
            with contextlib.suppress(LinkError):
                link.write(stop)
            link.close()
        self._link = None
        self._stream = None

    def __enter__(self) -> Driver:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _connect(self, now: float) -> None:
        self._connecting = True
        link: SerialLink | None = None
        try:
            link = SerialLink(
                self.config.port_url,
                self.config.baudrate_bps,
                opener=self.opener,
                clock=self.clock,
            )
            start = start_rplidar if self.config.protocol == "rplidar" else start_scip
            session = start(link, self.config, self.counters)
        except DriverError as exc:
            if link is not None:
                link.close()
            self._last_error = f"{type(exc).__name__}: {exc}"
            self._attempts += 1
            if not self._ever_connected and self._attempts > self.config.max_reconnects:
                self._failed = True
            self._retry_at = self.clock() + self.backoff_s()
            return
        self.session = session
        self._watch_s = max(self._last_frame_s, self.clock())
        self._link = link
        self._stream = session.stream
        self._pending = session.leftover

    def _lose(self, now: float, reason: str) -> None:
        """Drop the link (port failure or silence); reconnect after the backoff."""
        if self._link is not None:
            self._link.close()
        if self._stream is not None:
            self._stream.reset()
        self._link = None
        self._stream = None
        self._last_error = reason
        self._retry_at = now + self.backoff_s()

    def backoff_s(self) -> float:
        """The wait before the next connection attempt [s]: ``reconnect_backoff_s`` while the
        device has never answered; after a loss it doubles with each failed attempt, up to
        ``reconnect_backoff_max_s``."""
        base = self.config.reconnect_backoff_s
        if not self._ever_connected:
            return base
        return float(
            min(base * 2.0 ** min(self._attempts, 30), self.config.reconnect_backoff_max_s)
        )

    def retrying_in_s(self, now_s: float) -> float | None:
        """Seconds from ``now_s`` to the next connection attempt while the link is down (the
        port is open or was asked to be), else None."""
        if self._link is not None or self._failed or not self._opened:
            return None
        return max(0.0, self._retry_at - now_s)

    # -- reading -------------------------------------------------------------------------
    def poll(self, max_wait_s: float | None = None) -> list[Scan]:
        """Read for at most ``read_timeout_s`` (or ``max_wait_s``); return new revolutions."""
        if not self._opened:
            self.open()
        now = self.clock()
        wait = self.config.read_timeout_s if max_wait_s is None else max_wait_s
        if self._failed:
            return []
        if self._link is None:
            if now < self._retry_at:
                self.sleep(max(0.0, min(self._retry_at - now, wait)))
                return []
            self._reconnects += 1
            self._connect(now)
            if self._link is None:
                return []
        link, stream = self._link, self._stream
        assert link is not None
        assert stream is not None
        silent_at = self._watch_s + self.config.silent_timeout_s
        wait = max(0.0, min(wait, silent_at - now + 1e-3))
        try:
            data = self._pending + link.read(wait)
        except LinkError as exc:
            self._lose(self.clock(), str(exc))
            return []
        self._pending = b""
        now = self.clock()
        ok, rejected = self.counters.frames_ok, self.counters.frames_rejected
        scans = stream.feed(data, now) if data else []
        if self.counters.frames_ok > ok:
            self._last_frame_s = self._watch_s = now
            self._attempts = 0
            self._connecting = False
            self._ever_connected = True
        if self.counters.frames_rejected > rejected:
            self._last_reject_s = now
        age = now - self._watch_s
        if age > self.config.silent_timeout_s:
            self._lose(
                now,
                f"LinkError: no valid frame for {age:.3f} s (driver.silent_timeout_s = "
                f"{self.config.silent_timeout_s} s)",
            )
        return scans

    def scans(self) -> Iterator[Scan]:
        """Revolutions as they arrive, forever; raises :class:`LinkError` once FAILED."""
        while True:
            yield from self.poll()
            if self._failed:
                raise LinkError(
                    f"driver gave up after {self.config.max_reconnects} reconnect attempts: "
                    f"{self._last_error}"
                )

    # -- health --------------------------------------------------------------------------
    def health(self, now_s: float | None = None) -> DriverHealth:
        """The link's state and counters now (SR-DRV-3); see :class:`DriverState`."""
        now = self.clock() if now_s is None else now_s
        state = link_state(
            now_s=now,
            last_frame_s=self._last_frame_s,
            last_reject_s=self._last_reject_s,
            silent_timeout_s=self.config.silent_timeout_s,
            failed=self._failed,
            link_up=self._link is not None or not self._opened,
            connecting=self._connecting,
        )
        c = self.counters
        error = self._last_error
        retry = self.retrying_in_s(now)
        if retry is not None:
            error = f"{error}; reconnecting in {retry:.1f} s (attempt {self._attempts + 1})"
        return DriverHealth(
            state=state,
            stamp_s=now,
            age_s=now - self._last_frame_s,
            frames_ok=c.frames_ok,
            frames_rejected=c.frames_rejected,
            bytes_discarded=c.bytes_discarded,
            scans_emitted=c.scans_emitted,
            scans_incomplete=c.scans_incomplete,
            scans_dropped=c.scans_dropped,
            reconnects=self._reconnects,
            last_error=error,
        )


def link_state(
    *,
    now_s: float,
    last_frame_s: float,
    last_reject_s: float,
    silent_timeout_s: float,
    failed: bool,
    link_up: bool,
    connecting: bool,
) -> DriverState:
    """The health state from the link's history (pure; SR-DRV-3).

    Precedence: FAILED, then STALE (no valid frame for more than ``silent_timeout_s``,
    whatever else holds), DISCONNECTED, CONNECTING, DEGRADED (a rejection within the
    timeout), OK. Only OK and DEGRADED are fresh, so a scan is never used more than
    ``silent_timeout_s`` after the last valid frame.
    """
    if failed:
        return DriverState.FAILED
    if now_s - last_frame_s > silent_timeout_s:
        return DriverState.STALE
    if not link_up:
        return DriverState.DISCONNECTED
    if connecting:
        return DriverState.CONNECTING
    if now_s - last_reject_s <= silent_timeout_s:
        return DriverState.DEGRADED
    return DriverState.OK
