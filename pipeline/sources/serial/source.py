"""A serial scanner as a source of frames, and the same behind a device emulator (SR-DRV-3).

:class:`SerialSource` reads a scanner at any pyserial URL (a device, a pty, ``socket://``)
through :class:`~pipeline.sources.serial.transport.Driver`: one frame per received revolution
(the newest, when several arrived at once) and, while none arrives, one frame without a scan
every ``period_s``, which the monitors turn into STOP with the driver's state as the reason.
A device that never answers (a port that cannot be opened, no handshake) is an error naming
it once the driver has given up (:class:`~pipeline.sources.serial.errors.LinkError` after
``driver.max_reconnects`` attempts); one that answered and went away is retried, with back-off,
for as long as the frames are read (each frame without a scan is a STOP). :class:`EmulatedSource`
serves a scan source from a device emulator on a real pty and reads it back through the same
driver.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

from pipeline.config import DriverSection
from pipeline.sources.serial.devices import RplidarDevice, ScipDevice
from pipeline.sources.serial.emulator import Emulator
from pipeline.sources.serial.errors import LinkError
from pipeline.sources.serial.transport import Driver
from pipeline.types import DriverState, Frame, Scan

__all__ = ["EmulatedSource", "SerialSource"]


@dataclass
class SerialSource:
    """Frames from the scanner at ``config.port_url`` (module docstring); ``clock`` is the
    decision clock [s]."""

    config: DriverSection
    period_s: float
    clock: Callable[[], float] = time.monotonic
    live: bool = field(default=True, init=False)

    @property
    def name(self) -> str:
        """The port's URL."""
        return self.config.port_url

    def frames(self) -> Iterator[Frame]:
        """Frames until the driver gives up (the port is closed when the iteration ends)."""
        now, period = self.clock, self.period_s
        with Driver(self.config, clock=now) as driver:
            last = now()
            while True:
                scans = driver.poll(period)
                t = now()
                if not scans and t - last < period:
                    time.sleep(min(period - (t - last), 0.01))
                    continue
                last = t
                health = driver.health(t)
                yield Frame(scans[-1] if scans else None, t, health=health)
                if health.state is DriverState.FAILED:
                    raise LinkError(
                        f"{self.name}: no scanner after {health.reconnects + 1} attempts "
                        f"({self.config.max_reconnects} reconnects, "
                        f"{self.config.reconnect_backoff_s} s apart): {health.last_error}"
                    )


@dataclass
class EmulatedSource:
    """``scans`` served by an emulated ``protocol`` device on a pty at ``rate_hz`` and read
    back through the serial driver configured by ``config`` (its port is the pty)."""

    config: DriverSection
    period_s: float
    scans: Iterable[Scan]
    rate_hz: float
    clock: Callable[[], float] = time.monotonic
    live: bool = field(default=True, init=False)

    @property
    def name(self) -> str:
        """The emulated protocol."""
        return f"emulated {self.config.protocol}"

    def frames(self) -> Iterator[Frame]:
        """Frames of the emulated device (the emulator stops when the iteration ends)."""
        device = RplidarDevice() if self.config.protocol == "rplidar" else ScipDevice()
        with Emulator(device, iter(self.scans), realtime=True, rate_hz=self.rate_hz) as emu:
            port = self.config.model_copy(update={"port_url": str(emu.path)})
            yield from SerialSource(port, self.period_s, self.clock).frames()
