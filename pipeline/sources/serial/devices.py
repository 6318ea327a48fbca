"""The device side of each protocol, as pure state machines (requirement SR-DRV-3).

A device model takes the bytes the host sent (:meth:`receive`, returning the immediate
answers) and, while it is scanning, turns each :class:`Scan` it is given into the frames a
real device would send for that revolution (:meth:`frames`). The emulator
(:mod:`pipeline.sources.serial.emulator`) moves these bytes over a pseudo-terminal and injects
faults frame by frame; tests can also drive the models directly.

The RPLIDAR model sweeps clockwise as the device does: it sends a revolution's beams sorted
by their clockwise angle, starting at the smallest. The SCIP model puts each beam on its
nearest step (see :func:`pipeline.sources.serial.scip.scan_to_values`).
"""

from __future__ import annotations

import numpy as np

from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip
from pipeline.sources.serial.errors import DriverError
from pipeline.sources.serial.rplidar_capsule import ExpressEncoder
from pipeline.types import Scan

__all__ = ["RplidarDevice", "ScipDevice"]


class RplidarDevice:
    """An RPLIDAR (A-series like) answering STOP, RESET, SCAN, FORCE_SCAN, EXPRESS_SCAN
    (legacy capsules), GET_INFO, GET_HEALTH, GET_SAMPLERATE and GET_ACC_BOARD_FLAG;
    SET_MOTOR_PWM is accepted silently; requests failing their checksum are ignored, as the
    device ignores them."""

    def __init__(
        self,
        info: rp.DeviceInfo | None = None,
        health: rp.Health | None = None,
        sample_rate: rp.SampleRate | None = None,
    ) -> None:
        self.info = info or rp.DeviceInfo(0x18, 1, 29, 7, bytes(range(16)))
        self.health = health or rp.Health(rp.HealthStatus.GOOD, 0)
        self.sample_rate = sample_rate or rp.SampleRate(500, 250)
        self.mode: str | None = None  # None (idle), "standard" or "express"
        self._rx = b""
        self._encoder = ExpressEncoder()
        self.requests: list[rp.Request] = []

    @property
    def scanning(self) -> bool:
        """True while the device streams scan frames."""
        return self.mode is not None

    def reset(self) -> None:
        """Power-on state (after a disconnect)."""
        self.mode = None
        self._rx = b""
        self._encoder = ExpressEncoder()

    def receive(self, data: bytes) -> bytes:
        """Consume host bytes; return the answers to every complete request."""
        buf = self._rx + data
        out = bytearray()
        pos = 0
        while pos < len(buf):
            if buf[pos] != rp.SYNC_BYTE:
                pos += 1  # the device skips anything that is not a request
                continue
            try:
                request, used = rp.parse_request(buf, pos)
            except DriverError:
                pos += 1
                continue
            if request is None:
                break
            pos += used
            self.requests.append(request)
            out += self._answer(request)
        self._rx = buf[pos:]
        return bytes(out)

    def _answer(self, request: rp.Request) -> bytes:
        cmd = request.cmd
        if cmd in (rp.Cmd.STOP, rp.Cmd.RESET):
            self.mode = None
            return b""
        if cmd in (rp.Cmd.SCAN, rp.Cmd.FORCE_SCAN):
            self.mode = "standard"
            return rp.encode_descriptor(rp.SCAN_DESCRIPTOR)
        if cmd == rp.Cmd.EXPRESS_SCAN:
            self.mode = "express"
            self._encoder = ExpressEncoder()
            return rp.encode_descriptor(rp.EXPRESS_DESCRIPTOR)
        if cmd == rp.Cmd.GET_INFO:
            return rp.encode_descriptor(rp.INFO_DESCRIPTOR) + self.info.encode()
        if cmd == rp.Cmd.GET_HEALTH:
            return rp.encode_descriptor(rp.HEALTH_DESCRIPTOR) + self.health.encode()
        if cmd == rp.Cmd.GET_SAMPLERATE:
            return rp.encode_descriptor(rp.SAMPLERATE_DESCRIPTOR) + self.sample_rate.encode()
        if cmd == rp.Cmd.GET_ACC_BOARD_FLAG:
            return rp.encode_descriptor(rp.Descriptor(4, rp.SEND_SINGLE, 0xFF)) + bytes(4)
        return b""  # SET_MOTOR_PWM and anything unknown: no answer

    def frames(self, scan: Scan) -> list[bytes]:
        """The frames of one revolution in the current mode (one node or one capsule each)."""
        nodes = rp.scan_to_nodes(scan)
        order = np.argsort(nodes.angle_q6, kind="stable")
        start = np.zeros(order.shape[0], dtype=np.bool_)
        if start.shape[0]:
            start[0] = True
        if self.mode == "standard":
            data = rp.encode_nodes(
                rp.StandardNodes(
                    start, nodes.quality[order], nodes.angle_q6[order], nodes.distance_q2[order]
                )
            )
            return [data[i : i + rp.NODE_BYTES] for i in range(0, len(data), rp.NODE_BYTES)]
        if self.mode == "express":
            # Express distances are whole millimetres (1/4 mm steps are lost).
            dist_mm = np.minimum((nodes.distance_q2[order] + 2) // 4, (1 << 14) - 1)
            data = self._encoder.push(nodes.angle_q6[order].astype(np.float64), dist_mm)
            return [data[i : i + 84] for i in range(0, len(data), 84)]
        return []

    def finish(self) -> list[bytes]:
        """Frames that close the stream (express: the capsules still held back)."""
        if self.mode != "express":
            return []
        data = self._encoder.flush()
        return [data[i : i + 84] for i in range(0, len(data), 84)]


class ScipDevice:
    """A Hokuyo URG/UTM answering SCIP2.0, VV, PP, II, BM, QT, RS, MD/MS and GD/GS.

    Status codes: ``00`` accepted, ``99`` a scan follows, ``02`` laser already on, ``04``
    end step out of range, ``05`` end step before start step, ``0E`` unknown command.
    """

    def __init__(self, params: scip.ScipParams | None = None, serial: str = "H0000001") -> None:
        self.params = params or scip.ScipParams()
        self.version = {
            "VEND": "Hokuyo Automatic Co.,Ltd.",
            "PROD": "SOKUIKI Sensor UTM-30LX",
            "FIRM": "1.20.00(17/Jul./2012)",
            "PROT": "SCIP 2.0",
            "SERI": serial,
        }
        self.laser_on = False
        self.command: scip.ScipCommand | None = None
        self.remaining = 0
        self._skipped = 0
        self._rx = b""
        self.time_ms = 0
        self.lines: list[bytes] = []

    @property
    def scanning(self) -> bool:
        """True while an MD/MS or GD/GS request waits for scans."""
        return self.command is not None

    def reset(self) -> None:
        """Power-on state (after a disconnect)."""
        self.laser_on = False
        self.command = None
        self._rx = b""

    def receive(self, data: bytes) -> bytes:
        """Consume host bytes; return the answers to every complete command line."""
        buf = self._rx + data.replace(b"\r", b"\n")
        *lines, self._rx = buf.split(b"\n")
        out = bytearray()
        for line in lines:
            if line:
                self.lines.append(line)
                out += self._answer(line)
        return bytes(out)

    def _answer(self, line: bytes) -> bytes:
        try:
            command = scip.ScipCommand.parse(line)
        except DriverError:
            return scip.encode_response(line[:64], "0E")
        name = command.name
        if name is scip.Name.VV:
            return scip.info_response(line, self.version)
        if name is scip.Name.PP:
            return scip.info_response(line, self.params.items())
        if name is scip.Name.II:
            items = {
                "MODL": self.params.model.split("(")[0],
                "LASR": "ON" if self.laser_on else "OFF",
                "SCSP": f"Standard motor speed ({self.params.scan_rpm} rpm)",
                "MESM": "Measuring by Normal Mode",
                "SBPS": "USB only",
                "TIME": f"{self.time_ms:06X}",
                "STAT": "Sensor works well.",
            }
            return scip.info_response(line, items)
        if name is scip.Name.BM:
            status = "02" if self.laser_on else "00"
            self.laser_on = True
            return scip.encode_response(line, status)
        if name in (scip.Name.QT, scip.Name.RS):
            self.laser_on = False
            self.command = None
            return scip.encode_response(line, "00")
        if name is scip.Name.SCIP20:
            return scip.encode_response(line, "00")
        if command.end > self.params.amax:
            return scip.encode_response(line, "04")
        if command.end < command.start:
            return scip.encode_response(line, "05")
        self.laser_on = True
        self.command = command
        self.remaining = command.scans
        self._skipped = 0
        if name in (scip.Name.MD, scip.Name.MS):
            return scip.encode_response(line, "00")
        return b""  # GD/GS: the answer carries the next scan

    def frames(self, scan: Scan) -> list[bytes]:
        """The answer for one revolution (one frame per line), or nothing while skipping."""
        command = self.command
        if command is None:
            return []
        self.time_ms = (self.time_ms + round(1000 * self.params.scan_period_s)) % (1 << 24)
        streaming = command.name in (scip.Name.MD, scip.Name.MS)
        if streaming and self._skipped < command.interval:
            self._skipped += 1
            return []
        self._skipped = 0
        values = scip.scan_to_values(scan, self.params, command)
        lines = scip.encode_data_lines(values, command.width, self.time_ms)
        if streaming:
            if command.scans:
                self.remaining -= 1
            echo = scip.ScipCommand(
                command.name,
                command.start,
                command.end,
                command.cluster,
                command.interval,
                max(self.remaining, 0),
            ).line()
            status = "99"
            if command.scans and self.remaining <= 0:
                self.command = None
        else:
            echo, status = command.line(), "00"
            self.command = None
        answer = scip.encode_response(echo, status, lines)
        return [line + b"\n" for line in answer.split(b"\n")[:-1]]

    def finish(self) -> list[bytes]:
        """Nothing is held back in SCIP."""
        return []
