"""Serial LiDAR drivers and device emulators: Slamtec RPLIDAR and Hokuyo SCIP 2.0.

Codecs (pure, symmetric): :mod:`.rplidar`, :mod:`.rplidar_capsule`, :mod:`.scip`. Stream
decoding into one :class:`~pipeline.types.Scan` per revolution: :mod:`.rplidar_stream`,
:mod:`.scip_stream`, :mod:`.assembly`. The pyserial transport with health and reconnection:
:mod:`.sessions`, :mod:`.transport`. The device side on a pty with fault injection:
:mod:`.devices`, :mod:`.faults`, :mod:`.emulator`; a deterministic scan source for them:
:mod:`.synthetic`. Errors: :mod:`.errors`. Requirements SR-DRV-1 .. SR-DRV-5.
"""

from __future__ import annotations

from pipeline.sources.serial.errors import (
    ChecksumError,
    DeviceError,
    DriverError,
    EncodeError,
    FrameError,
    LinkError,
    ProtocolError,
)
from pipeline.sources.serial.transport import Driver

__all__ = [
    "ChecksumError",
    "DeviceError",
    "Driver",
    "DriverError",
    "EncodeError",
    "FrameError",
    "LinkError",
    "ProtocolError",
]
