"""Opening a serial link and starting a device streaming (requirements SR-DRV-3, SR-DRV-4).

:class:`SerialLink` wraps a pyserial port opened with ``serial.serial_for_url`` (a device
path, a pty, ``loop://`` or ``socket://`` all work) and turns every port failure into a
:class:`~pipeline.sources.serial.errors.LinkError`. It never touches the modem lines.
:func:`start_rplidar` and :func:`start_scip` perform each protocol's handshake (stop any
stream, drain, query the device, start scanning) and return the stream decoder together with
the bytes that arrived after the handshake.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import serial

from pipeline.config import DriverSection
from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip, scip_answers
from pipeline.sources.serial.assembly import LinkCounters
from pipeline.sources.serial.errors import DeviceError, LinkError, ProtocolError
from pipeline.sources.serial.rplidar_stream import RplidarStream
from pipeline.sources.serial.scip_stream import ScipStream

__all__ = ["RplidarSession", "ScipSession", "SerialLink", "start_rplidar", "start_scip"]

Opener = Callable[..., Any]
_DRAIN_QUIET_S = 0.02
_DRAIN_MAX_S = 0.5


class SerialLink:
    """A pyserial port with typed errors and a read that returns what has arrived."""

    def __init__(
        self,
        url: str,
        baudrate_bps: int,
        *,
        opener: Opener = serial.serial_for_url,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.url = url
        self.clock = clock
        try:
            self._port = opener(url, baudrate=baudrate_bps, timeout=0.05, write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkError(f"cannot open serial port {url!r}: {exc}") from None
        self._timeout = 0.05

    def read(self, timeout_s: float) -> bytes:
        """Bytes that arrive within ``timeout_s`` (returns as soon as any have arrived)."""
        try:
            if abs(timeout_s - self._timeout) > 1e-6:
                self._port.timeout = max(0.0, timeout_s)
                self._timeout = timeout_s
            first = bytes(self._port.read(1))
            if not first:
                return b""
            waiting = int(self._port.in_waiting)
            return first + (bytes(self._port.read(waiting)) if waiting else b"")
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"serial port {self.url!r} failed while reading: {exc}") from None

    def write(self, data: bytes) -> None:
        """Send ``data``; raises :class:`LinkError` when the port fails."""
        try:
            self._port.write(data)
            self._port.flush()
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"serial port {self.url!r} failed while writing: {exc}") from None

    def drain(self) -> int:
        """Read and drop input until the line is quiet; return how many bytes were dropped."""
        dropped = 0
        deadline = self.clock() + _DRAIN_MAX_S
        while self.clock() < deadline:
            data = self.read(_DRAIN_QUIET_S)
            if not data:
                break
            dropped += len(data)
        return dropped

    def close(self) -> None:
        """Close the port (never raises)."""
        with contextlib.suppress(serial.SerialException, OSError):
            self._port.close()


def _read_until(
    link: SerialLink, done: Callable[[bytes], Any], timeout_s: float, what: str
) -> tuple[Any, bytes]:
    buf = b""
    deadline = link.clock() + timeout_s
    while True:
        result = done(buf)
        if result is not None:
            return result, buf
        remaining = deadline - link.clock()
        if remaining <= 0:
            raise LinkError(f"no {what} within {timeout_s:.3f} s ({len(buf)} bytes received)")
        buf += link.read(min(remaining, 0.05))


# ------------------------------------------------------------------------------ RPLIDAR
@dataclass(frozen=True, slots=True)
class RplidarSession:
    """A started RPLIDAR: its decoder, identity, health and the bytes left to decode."""

    stream: RplidarStream
    info: rp.DeviceInfo
    health: rp.Health
    leftover: bytes


def _rplidar_answer(
    link: SerialLink, request: bytes, expected: rp.Descriptor, timeout_s: float
) -> tuple[bytes, bytes]:
    link.write(request)

    def done(buf: bytes) -> tuple[bytes, int] | None:
        at = buf.find(bytes((rp.SYNC_BYTE, rp.SYNC_BYTE2)))
        if at < 0 or len(buf) < at + rp.DESCRIPTOR_BYTES:
            return None
        descriptor = rp.decode_descriptor(buf, at)
        if descriptor != expected:
            raise ProtocolError(
                f"rplidar: answer descriptor {descriptor} to request {request.hex()}, "
                f"expected {expected}",
                at,
            )
        end = at + rp.DESCRIPTOR_BYTES + (0 if expected.send_mode else expected.length)
        return (buf[at + rp.DESCRIPTOR_BYTES : end], end) if len(buf) >= end else None

    (data, end), buf = _read_until(link, done, timeout_s, f"answer to {request.hex()}")
    return data, buf[end:]


def start_rplidar(
    link: SerialLink, config: DriverSection, counters: LinkCounters
) -> RplidarSession:
    """Stop, drain, GET_HEALTH, GET_INFO, then SCAN or EXPRESS_SCAN (``config.rplidar_mode``).

    Raises :class:`DeviceError` when the device reports health Error (it needs a reset),
    :class:`ProtocolError` / :class:`LinkError` when it does not answer as the protocol says.
    """
    timeout_s = config.silent_timeout_s
    link.write(rp.encode_request(rp.Cmd.STOP))
    link.drain()
    data, _ = _rplidar_answer(
        link, rp.encode_request(rp.Cmd.GET_HEALTH), rp.HEALTH_DESCRIPTOR, timeout_s
    )
    health = rp.Health.decode(data)
    if health.status is rp.HealthStatus.ERROR:
        raise DeviceError(f"rplidar reports health ERROR, error code {health.error_code}")
    data, _ = _rplidar_answer(
        link, rp.encode_request(rp.Cmd.GET_INFO), rp.INFO_DESCRIPTOR, timeout_s
    )
    info = rp.DeviceInfo.decode(data)
    if config.rplidar_mode == "express":
        request = rp.encode_request(rp.Cmd.EXPRESS_SCAN, bytes(5))
        descriptor = rp.EXPRESS_DESCRIPTOR
    else:
        request, descriptor = rp.encode_request(rp.Cmd.SCAN), rp.SCAN_DESCRIPTOR
    _, leftover = _rplidar_answer(link, request, descriptor, timeout_s)
    stream = RplidarStream(
        config.rplidar_mode,
        counters=counters,
        policy=config.incomplete_policy,
        max_beams=config.max_beams_per_revolution,
        max_step_deg=config.max_step_deg,
        source=f"rplidar:{config.port_url}",
    )
    return RplidarSession(stream, info, health, leftover)


# --------------------------------------------------------------------------------- SCIP
@dataclass(frozen=True, slots=True)
class ScipSession:
    """A started SCIP 2.0 device: its decoder, parameters, command and leftover bytes."""

    stream: ScipStream
    params: scip.ScipParams
    command: scip.ScipCommand
    leftover: bytes


def _scip_answer(
    link: SerialLink,
    command: scip.ScipCommand,
    timeout_s: float,
    accept: tuple[bytes, ...] | None,
) -> tuple[tuple[bytes, ...], bytes]:
    """Send ``command``; return the data lines of its first whole valid answer and the bytes
    after it. Garbage, garbled answers and answers to other commands before it are skipped
    (SR-DRV-2); a status outside ``accept`` is a :class:`DeviceError`."""
    link.write(command.encode())
    line = command.line()

    def done(buf: bytes) -> tuple[scip_answers.ScipAnswer, int] | None:
        answer, end = scip_answers.answer_to(buf, command)
        if answer is None:
            return None
        if accept is not None and answer.status not in accept:
            raise DeviceError(f"scip {line!r}: device status {answer.status!r}", answer.offset)
        return answer, end

    (answer, end), buf = _read_until(link, done, timeout_s, f"answer to {line!r}")
    return answer.lines, buf[end:]


def start_scip(link: SerialLink, config: DriverSection, counters: LinkCounters) -> ScipSession:
    """QT, drain, SCIP2.0, PP, then MD/MS (``config.scip_command``) over AMIN..AMAX."""
    timeout_s = config.silent_timeout_s
    link.write(scip.ScipCommand(scip.Name.QT).encode())
    link.drain()
    _scip_answer(link, scip.ScipCommand(scip.Name.SCIP20), timeout_s, None)
    lines, _ = _scip_answer(link, scip.ScipCommand(scip.Name.PP), timeout_s, (b"00",))
    params = scip.ScipParams.from_items(scip.decode_info_lines(list(lines)))
    command = scip.ScipCommand(scip.Name(config.scip_command), params.amin, params.amax, 1, 0, 0)
    _, leftover = _scip_answer(link, command, timeout_s, (b"00",))
    stream = ScipStream(
        params,
        command,
        counters=counters,
        policy=config.incomplete_policy,
        source=f"scip:{config.port_url}",
    )
    return ScipSession(stream, params, command, leftover)
