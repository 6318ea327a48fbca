"""Device emulators on a real pseudo-terminal (requirement SR-DRV-3, SR-DRV-4).

:class:`Emulator` puts a device model (:mod:`pipeline.sources.serial.devices`) behind the master
side of an ``os.openpty`` pair and serves it from a background thread: host commands are read and
answered, and while the device is scanning, revolutions drawn from any ``Iterable[Scan]`` (the
simulator, a log, :func:`pipeline.sources.serial.synthetic.synthetic_scans`) are sent frame by
frame, at the device's real rate (``realtime=True``: one revolution per ``1 / rate_hz``, frames
spread over it) or as fast as the reader takes them. A :class:`FaultInjector` may corrupt frames,
stall the device or disconnect it; a disconnect closes the pty and opens a new one after the
configured time, and :attr:`Emulator.path` (a symlink) follows it, as a udev link follows a
re-plugged USB adapter.

The emulator never uses modem-control ioctls (DTR/RTS do not exist on a pty); the slave side
is put in raw mode with termios, which a pty does support.
"""

from __future__ import annotations

import contextlib
import os
import select
import tempfile
import threading
import time
import tty
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from pipeline.sources.serial.faults import FaultInjector, Injected
from pipeline.types import Scan

__all__ = ["DeviceModel", "Emulator", "EmulatorStats"]

_HIGH_WATER = 8192  # bytes queued ahead of the pty; small, so STOP takes effect at once
_READ_BYTES = 4096


class DeviceModel(Protocol):
    """What the emulator needs from a device model."""

    @property
    def scanning(self) -> bool: ...

    def receive(self, data: bytes) -> bytes: ...

    def frames(self, scan: Scan) -> list[bytes]: ...

    def finish(self) -> list[bytes]: ...

    def reset(self) -> None: ...


@dataclass(slots=True)
class EmulatorStats:
    """Totals since start: what was sent and what was done to it."""

    scans_sent: int = 0
    frames_sent: int = 0
    bytes_sent: int = 0
    disconnects: int = 0
    stalls: int = 0
    commands_bytes: int = 0


class Emulator:
    """A device model served on a pty from a background thread (use as a context manager)."""

    def __init__(
        self,
        device: DeviceModel,
        scans: Iterable[Scan],
        *,
        realtime: bool = False,
        rate_hz: float = 10.0,
        faults: FaultInjector | None = None,
        name: str = "lidar",
    ) -> None:
        if rate_hz <= 0:
            raise ValueError(f"Emulator: rate_hz must be > 0, got {rate_hz}")
        self.device = device
        self.realtime = realtime
        self.rate_hz = rate_hz
        self.faults = faults
        self.stats = EmulatorStats()
        self.exhausted = threading.Event()
        self._scans: Iterator[Scan] = iter(scans)
        self._dir = Path(tempfile.mkdtemp(prefix="safecase-emu-"))
        self._link = self._dir / name
        self._master = -1
        self._slave = -1
        self._stop = threading.Event()
        self._disconnect_request = 0.0
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=f"emulator-{name}", daemon=True)
        self.error: BaseException | None = None

    @property
    def path(self) -> str:
        """The device path to open (a symlink to the current pty slave)."""
        return str(self._link)

    def __enter__(self) -> Emulator:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        """Open the pty and start serving."""
        self._open_pty()
        self._thread.start()

    def stop(self) -> None:
        """Stop serving, close the pty and remove the link (idempotent)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self._close_pty()
        try:
            self._link.unlink(missing_ok=True)
            self._dir.rmdir()
        except OSError:
            pass

    def disconnect(self, duration_s: float) -> None:
        """Unplug the device now and plug it back in after ``duration_s``."""
        with self._lock:
            self._disconnect_request = max(duration_s, 1e-3)

    # -- pty ---------------------------------------------------------------------------
    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # termios on the slave: no echo, no line editing, 8 bits clean
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        tmp = self._dir / f".{self._link.name}.new"
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(slave))
        os.replace(tmp, self._link)

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    def _replug(self, duration_s: float) -> None:
        self._close_pty()
        self._link.unlink(missing_ok=True)
        self.stats.disconnects += 1
        self._stop.wait(duration_s)
        self.device.reset()
        if not self._stop.is_set():
            self._open_pty()

    # -- serving -----------------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._serve()
        except BaseException as exc:  # surfaced to the test through .error
            self.error = exc
            raise

    def _serve(self) -> None:
        out = bytearray()
        pending: deque[tuple[float, bytes]] = deque()
        quiet_until = 0.0
        unplug_after_flush = 0.0
        next_rev_s = time.monotonic()
        while not self._stop.is_set():
            with self._lock:
                request, self._disconnect_request = self._disconnect_request, 0.0
            if request or (unplug_after_flush and not out):
                self._replug(request or unplug_after_flush)
                out.clear()
                pending.clear()
                unplug_after_flush = 0.0
                continue
            now = time.monotonic()
            if (
                self.device.scanning
                and not pending
                and len(out) < _HIGH_WATER
                and not self.exhausted.is_set()
            ):
                next_rev_s = self._produce(pending, max(now, next_rev_s))
            while (
                pending
                and now >= quiet_until
                and not unplug_after_flush
                and (not self.realtime or pending[0][0] <= now)
                and len(out) < _HIGH_WATER
            ):
                injected = self._inject(pending.popleft()[1])
                out += injected.data
                self.stats.frames_sent += 1
                if injected.stall_s:
                    self.stats.stalls += 1
                    quiet_until = now + injected.stall_s
                    next_rev_s = max(next_rev_s, quiet_until)
                if injected.disconnect_s:
                    unplug_after_flush = injected.disconnect_s
            self._io(out, now, quiet_until, pending, next_rev_s)

    def _produce(self, pending: deque[tuple[float, bytes]], start_s: float) -> float:
        scan = next(self._scans, None)
        frames = self.device.finish() if scan is None else self.device.frames(scan)
        if scan is None:
            self.exhausted.set()
        else:
            self.stats.scans_sent += 1
        period = 1.0 / self.rate_hz
        for i, frame in enumerate(frames):
            pending.append((start_s + period * i / max(1, len(frames)), frame))
        return start_s + period if scan is not None else float("inf")

    def _inject(self, frame: bytes) -> Injected:
        return self.faults.apply(frame) if self.faults is not None else Injected(frame)

    def _io(
        self,
        out: bytearray,
        now: float,
        quiet_until: float,
        pending: deque[tuple[float, bytes]],
        next_rev_s: float,
    ) -> None:
        writing = bool(out) and now >= quiet_until
        # Sleep until the next thing to do (select also wakes when the pty can take more
        # bytes or a command arrives), never longer than 50 ms, and never spin.
        wake = now + 0.05
        room = len(out) < _HIGH_WATER
        if now < quiet_until:
            wake = min(wake, quiet_until)
        elif pending and room:
            wake = min(wake, pending[0][0]) if self.realtime else now
        elif self.device.scanning and room and not pending and not self.exhausted.is_set():
            wake = min(wake, next_rev_s) if self.realtime else now
        timeout = max(0.0, wake - now)
        master = self._master
        readable, writable, _ = select.select([master], [master] if writing else [], [], timeout)
        if readable:
            try:
                data = os.read(master, _READ_BYTES)
            except OSError:
                data = b""
            if data:
                self.stats.commands_bytes += len(data)
                was_scanning = self.device.scanning
                reply = self.device.receive(data)
                if was_scanning and not self.device.scanning:
                    out.clear()  # STOP: the device falls silent at once
                    pending.clear()
                elif reply and self.device.scanning:
                    pending.clear()  # a new scan request restarts the stream
                    out.clear()
                out += reply
        if writable and out:
            try:
                sent = os.write(master, bytes(out[:_READ_BYTES]))
            except BlockingIOError:
                sent = 0
            del out[:sent]
            self.stats.bytes_sent += sent
