"""Typed errors of the serial drivers, all under :class:`pipeline.errors.SafecaseError`.

Every driver error carries ``offset`` (the byte offset into the buffer or stream being
examined, or the beam index for an encoding error; -1 when no position applies) and
``reason`` (one sentence naming the bad value and what was expected). The runtime catches
:class:`DriverError` as "anything the link can do to us"; anything else escaping a driver is a
bug (requirement SR-DRV-2).
"""

from __future__ import annotations

from pipeline.errors import SafecaseError

__all__ = [
    "ChecksumError",
    "DeviceError",
    "DriverError",
    "EncodeError",
    "FrameError",
    "LinkError",
    "ProtocolError",
]


class DriverError(SafecaseError):
    """Base of every serial-driver error: where in the bytes it happened and why."""

    def __init__(self, reason: str, offset: int = -1) -> None:
        self.reason = reason
        self.offset = int(offset)
        where = f" (at byte offset {self.offset})" if self.offset >= 0 else ""
        super().__init__(f"{reason}{where}")


class FrameError(DriverError):
    """A frame is malformed: bad sync bytes, bad length, a character outside the alphabet."""


class ChecksumError(FrameError):
    """A frame fails its checksum or check bit (SR-DRV-2): it is rejected and counted."""


class ProtocolError(DriverError):
    """The device answered, but not what the protocol allows here (wrong descriptor, echo)."""


class DeviceError(DriverError):
    """The device reports a fault of its own (RPLIDAR health Error, SCIP error status)."""


class EncodeError(DriverError, ValueError):
    """A value cannot be represented in the protocol (``offset`` is the beam index)."""


class LinkError(DriverError):
    """The serial link failed: the port cannot be opened, went away or stayed silent."""
