"""Slamtec RPLIDAR serial protocol codec: requests, response descriptors, standard scan nodes,
GET_INFO, GET_HEALTH and GET_SAMPLERATE answers (requirements SR-DRV-1, SR-DRV-2).

Pure, symmetric functions over bytes and numpy arrays; no I/O. Express and ultra capsules
live in :mod:`pipeline.sources.serial.rplidar_capsule`.

Protocol facts (Slamtec's public RPLIDAR interface protocol): a request is ``0xA5 cmd`` or,
for commands with bit 7 set, ``0xA5 cmd size payload checksum`` where the checksum is the XOR
of every byte before it. An answer starts with a 7-byte descriptor ``0xA5 0x5A`` + a
little-endian u32 holding the data length (30 bits) and the send mode (2 bits) + a data-type
byte. A standard scan node is 5 bytes: ``quality<<2 | !S<<1 | S``, ``angle_q6[6:0]<<1 | C``
(check bit C = 1), ``angle_q6[14:7]``, then ``distance_q2`` as little-endian u16. Angles are
in 1/64 degree, clockwise seen from above; distances in 1/4 mm, 0 meaning no return.

The device measures clockwise; :class:`~pipeline.types.Scan` is counter-clockwise, so a
device angle ``a`` degrees becomes ``-a`` in radians, in ``(-2 pi, 0]`` in sweep order.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.sources.serial.errors import ChecksumError, EncodeError, FrameError
from pipeline.types import Scan

__all__ = [
    "DEFAULT_QUALITY",
    "DESCRIPTOR_BYTES",
    "NODE_BYTES",
    "Q6_PER_TURN",
    "AnsType",
    "Cmd",
    "Descriptor",
    "DeviceInfo",
    "Health",
    "HealthStatus",
    "Request",
    "SampleRate",
    "StandardNodes",
    "decode_descriptor",
    "decode_nodes",
    "encode_descriptor",
    "encode_nodes",
    "encode_request",
    "node_validity",
    "nodes_to_scan",
    "parse_request",
    "scan_to_nodes",
]

SYNC_BYTE = 0xA5
SYNC_BYTE2 = 0x5A
HAS_PAYLOAD = 0x80
NODE_BYTES = 5
DESCRIPTOR_BYTES = 7
Q6_PER_TURN = 360 * 64
MAX_DISTANCE_Q2 = 0xFFFF
# The quality Slamtec's SDK reports for capsule nodes that have a return (0x2f); we use it for
# scans that carry no intensities of their own.
DEFAULT_QUALITY = 0x2F
_RAD_PER_Q6 = np.pi / (180.0 * 64.0)

U8Array = npt.NDArray[np.uint8]
I64Array = npt.NDArray[np.int64]


class Cmd(enum.IntEnum):
    """Request command bytes (bit 7 set: the request carries a payload)."""

    STOP = 0x25
    RESET = 0x40
    SCAN = 0x20
    FORCE_SCAN = 0x21
    EXPRESS_SCAN = 0x82
    GET_INFO = 0x50
    GET_HEALTH = 0x52
    GET_SAMPLERATE = 0x59
    GET_LIDAR_CONF = 0x84
    SET_MOTOR_PWM = 0xF0
    GET_ACC_BOARD_FLAG = 0xFF


class AnsType(enum.IntEnum):
    """Data-type byte of a response descriptor."""

    DEVINFO = 0x04
    DEVHEALTH = 0x06
    SAMPLERATE = 0x15
    MEASUREMENT = 0x81
    CAPSULED = 0x82
    HQ = 0x83
    ULTRA_CAPSULED = 0x84
    DENSE_CAPSULED = 0x85


SEND_SINGLE = 0
SEND_MULTI = 1


# ------------------------------------------------------------------------------- requests
@dataclass(frozen=True, slots=True)
class Request:
    """One host-to-device request."""

    cmd: int
    payload: bytes = b""


def encode_request(cmd: int, payload: bytes = b"") -> bytes:
    """The bytes of a request; a payload is only allowed (and required) when cmd bit 7 is set."""
    if not 0 <= cmd <= 0xFF:
        raise EncodeError(f"rplidar request: cmd {cmd!r} is not a byte")
    if not cmd & HAS_PAYLOAD:
        if payload:
            raise EncodeError(f"rplidar request: cmd 0x{cmd:02X} takes no payload")
        return bytes((SYNC_BYTE, cmd))
    if len(payload) > 0xFF:
        raise EncodeError(f"rplidar request: payload of {len(payload)} bytes exceeds 255")
    body = bytes((SYNC_BYTE, cmd, len(payload))) + payload
    checksum = 0
    for byte in body:
        checksum ^= byte
    return body + bytes((checksum,))


def parse_request(buf: bytes, offset: int = 0) -> tuple[Request | None, int]:
    """Parse one request at ``buf[offset:]`` (device side).

    Returns ``(request, bytes consumed)``, or ``(None, 0)`` when the request is not complete
    yet. Raises :class:`FrameError` (bad sync byte) or :class:`ChecksumError` with the offset.
    """
    if len(buf) - offset < 2:
        return None, 0
    if buf[offset] != SYNC_BYTE:
        raise FrameError(f"rplidar request: sync byte 0x{buf[offset]:02X}, expected 0xA5", offset)
    cmd = buf[offset + 1]
    if not cmd & HAS_PAYLOAD:
        return Request(cmd), 2
    if len(buf) - offset < 3:
        return None, 0
    size = buf[offset + 2]
    total = 3 + size + 1
    if len(buf) - offset < total:
        return None, 0
    checksum = 0
    for byte in buf[offset : offset + total - 1]:
        checksum ^= byte
    if checksum != buf[offset + total - 1]:
        raise ChecksumError(
            f"rplidar request 0x{cmd:02X}: checksum 0x{buf[offset + total - 1]:02X}, "
            f"expected 0x{checksum:02X}",
            offset + total - 1,
        )
    return Request(cmd, bytes(buf[offset + 3 : offset + 3 + size])), total


# ---------------------------------------------------------------------------- descriptors
@dataclass(frozen=True, slots=True)
class Descriptor:
    """A response descriptor: data length per answer, send mode, data type."""

    length: int
    send_mode: int
    data_type: int


SCAN_DESCRIPTOR = Descriptor(NODE_BYTES, SEND_MULTI, AnsType.MEASUREMENT)
EXPRESS_DESCRIPTOR = Descriptor(84, SEND_MULTI, AnsType.CAPSULED)
ULTRA_DESCRIPTOR = Descriptor(132, SEND_MULTI, AnsType.ULTRA_CAPSULED)
INFO_DESCRIPTOR = Descriptor(20, SEND_SINGLE, AnsType.DEVINFO)
HEALTH_DESCRIPTOR = Descriptor(3, SEND_SINGLE, AnsType.DEVHEALTH)
SAMPLERATE_DESCRIPTOR = Descriptor(4, SEND_SINGLE, AnsType.SAMPLERATE)


def encode_descriptor(descriptor: Descriptor) -> bytes:
    """The 7 bytes of a response descriptor."""
    if not 0 <= descriptor.length < 1 << 30:
        raise EncodeError(f"rplidar descriptor: length {descriptor.length} needs 0..2^30-1")
    if not 0 <= descriptor.send_mode <= 3 or not 0 <= descriptor.data_type <= 0xFF:
        raise EncodeError(f"rplidar descriptor: bad send mode or type in {descriptor}")
    word = descriptor.length | (descriptor.send_mode << 30)
    return struct.pack("<BBIB", SYNC_BYTE, SYNC_BYTE2, word, descriptor.data_type)


def decode_descriptor(buf: bytes, offset: int = 0) -> Descriptor:
    """Decode the 7-byte descriptor at ``buf[offset:]``; raises :class:`FrameError`."""
    if len(buf) - offset < DESCRIPTOR_BYTES:
        raise FrameError(
            f"rplidar descriptor: {len(buf) - offset} bytes, expected {DESCRIPTOR_BYTES}", offset
        )
    sync1, sync2, word, data_type = struct.unpack_from("<BBIB", buf, offset)
    if (sync1, sync2) != (SYNC_BYTE, SYNC_BYTE2):
        raise FrameError(
            f"rplidar descriptor: sync 0x{sync1:02X} 0x{sync2:02X}, expected 0xA5 0x5A", offset
        )
    return Descriptor(word & 0x3FFFFFFF, word >> 30, data_type)


# ------------------------------------------------------------------- info, health, rates
@dataclass(frozen=True, slots=True)
class DeviceInfo:
    """GET_INFO answer: model, firmware major.minor, hardware revision, 16-byte serial."""

    model: int
    firmware_major: int
    firmware_minor: int
    hardware: int
    serial: bytes

    def encode(self) -> bytes:
        """The 20 data bytes of the answer."""
        if len(self.serial) != 16:
            raise EncodeError(f"rplidar info: serial has {len(self.serial)} bytes, expected 16")
        fields = (self.model, self.firmware_minor, self.firmware_major, self.hardware)
        if not all(0 <= f <= 0xFF for f in fields):
            raise EncodeError(f"rplidar info: a field is not a byte in {self}")
        return bytes(fields) + self.serial

    @classmethod
    def decode(cls, data: bytes) -> DeviceInfo:
        """Decode the 20 data bytes; raises :class:`FrameError` on a wrong length."""
        if len(data) != INFO_DESCRIPTOR.length:
            raise FrameError(f"rplidar info: {len(data)} bytes, expected 20", 0)
        return cls(data[0], data[2], data[1], data[3], bytes(data[4:20]))


class HealthStatus(enum.IntEnum):
    """GET_HEALTH status byte."""

    GOOD = 0
    WARNING = 1
    ERROR = 2


@dataclass(frozen=True, slots=True)
class Health:
    """GET_HEALTH answer: status and a little-endian u16 error code (as in Slamtec's SDK)."""

    status: HealthStatus
    error_code: int = 0

    def encode(self) -> bytes:
        """The 3 data bytes of the answer."""
        if not 0 <= self.error_code <= 0xFFFF:
            raise EncodeError(f"rplidar health: error_code {self.error_code} is not a u16")
        return struct.pack("<BH", int(self.status), self.error_code)

    @classmethod
    def decode(cls, data: bytes) -> Health:
        """Decode the 3 data bytes; raises :class:`FrameError` on a bad length or status."""
        if len(data) != HEALTH_DESCRIPTOR.length:
            raise FrameError(f"rplidar health: {len(data)} bytes, expected 3", 0)
        status, code = struct.unpack("<BH", data)
        if status not in (0, 1, 2):
            raise FrameError(f"rplidar health: status {status}, expected 0, 1 or 2", 0)
        return cls(HealthStatus(status), code)


@dataclass(frozen=True, slots=True)
class SampleRate:
    """GET_SAMPLERATE answer: microseconds per sample in standard and express scans."""

    standard_us: int
    express_us: int

    def encode(self) -> bytes:
        """The 4 data bytes of the answer."""
        if not (0 <= self.standard_us <= 0xFFFF and 0 <= self.express_us <= 0xFFFF):
            raise EncodeError(f"rplidar sample rate: fields must be u16 in {self}")
        return struct.pack("<HH", self.standard_us, self.express_us)

    @classmethod
    def decode(cls, data: bytes) -> SampleRate:
        """Decode the 4 data bytes."""
        if len(data) != SAMPLERATE_DESCRIPTOR.length:
            raise FrameError(f"rplidar sample rate: {len(data)} bytes, expected 4", 0)
        standard, express = struct.unpack("<HH", data)
        return cls(standard, express)


# ---------------------------------------------------------------------- standard nodes
@dataclass(frozen=True, slots=True)
class StandardNodes:
    """Standard scan nodes as arrays (struct of arrays, one entry per node)."""

    start: npt.NDArray[np.bool_]
    quality: I64Array
    angle_q6: I64Array
    distance_q2: I64Array

    def __len__(self) -> int:
        return int(self.angle_q6.shape[0])


def encode_nodes(nodes: StandardNodes) -> bytes:
    """The 5-byte wire form of each node, concatenated (vectorised)."""
    quality, angle, dist = nodes.quality, nodes.angle_q6, nodes.distance_q2
    bad = (quality < 0) | (quality > 63) | (angle < 0) | (angle > 0x7FFF)
    bad |= (dist < 0) | (dist > MAX_DISTANCE_Q2)
    if np.any(bad):
        index = int(np.argmax(bad))
        raise EncodeError(
            f"rplidar node {index}: quality {quality[index]} (0..63), angle_q6 {angle[index]} "
            f"(0..32767) or distance_q2 {dist[index]} (0..65535) out of range",
            index,
        )
    start = nodes.start.astype(np.int64)
    out = np.empty((len(nodes), NODE_BYTES), dtype=np.uint8)
    out[:, 0] = (quality << 2) | ((1 - start) << 1) | start
    out[:, 1] = ((angle & 0x7F) << 1) | 1
    out[:, 2] = angle >> 7
    out[:, 3] = dist & 0xFF
    out[:, 4] = dist >> 8
    return out.tobytes()


def node_validity(raw: U8Array) -> npt.NDArray[np.bool_]:
    """For an ``(n, 5)`` array of node bytes: which pass the start-flag pair and check bit.

    A node is valid when S and !S differ, the check bit C is 1 and the angle is below 360
    degrees (a device never sends more).
    """
    b0 = raw[:, 0]
    pair_ok = ((b0 ^ (b0 >> 1)) & 1) == 1
    check_ok = (raw[:, 1] & 1) == 1
    angle = (raw[:, 1].astype(np.int64) >> 1) | (raw[:, 2].astype(np.int64) << 7)
    valid: npt.NDArray[np.bool_] = pair_ok & check_ok & (angle < Q6_PER_TURN)
    return valid


def _fields(raw: U8Array) -> StandardNodes:
    b0 = raw[:, 0].astype(np.int64)
    return StandardNodes(
        start=(b0 & 1).astype(np.bool_),
        quality=b0 >> 2,
        angle_q6=(raw[:, 1].astype(np.int64) >> 1) | (raw[:, 2].astype(np.int64) << 7),
        distance_q2=raw[:, 3].astype(np.int64) | (raw[:, 4].astype(np.int64) << 8),
    )


def decode_nodes(data: bytes | U8Array, offset: int = 0) -> StandardNodes:
    """Decode whole nodes from ``data``; raises :class:`ChecksumError` at the first bad node.

    ``offset`` is added to the reported byte position (the caller's stream offset).
    """
    raw = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes | bytearray) else data
    if raw.shape[0] % NODE_BYTES:
        raise FrameError(
            f"rplidar nodes: {raw.shape[0]} bytes is not a multiple of {NODE_BYTES}", offset
        )
    raw = raw.reshape(-1, NODE_BYTES)
    valid = node_validity(raw)
    if not np.all(valid):
        index = int(np.argmin(valid))
        raise ChecksumError(
            f"rplidar node {index}: start-flag pair, check bit or angle invalid "
            f"(bytes {bytes(raw[index]).hex()})",
            offset + index * NODE_BYTES,
        )
    return _fields(raw)


def fields_of(raw: U8Array) -> StandardNodes:
    """Fields of ``(n, 5)`` node bytes already known to be valid (no checks)."""
    return _fields(raw)


# ------------------------------------------------------------------ scan <-> node units
def angles_to_q6(angles_rad: npt.NDArray[np.float64]) -> I64Array:
    """Counter-clockwise radians to the device's clockwise 1/64 degree, in 0..23039."""
    clockwise_deg = np.mod(-np.asarray(angles_rad, dtype=np.float64), 2 * np.pi) * (180 / np.pi)
    return np.mod(np.rint(clockwise_deg * 64.0).astype(np.int64), Q6_PER_TURN)


def q6_to_angles(angle_q6: I64Array) -> npt.NDArray[np.float64]:
    """The device's clockwise 1/64 degree to counter-clockwise radians in (-2 pi, 0]."""
    return -(angle_q6.astype(np.float64) * _RAD_PER_Q6)


def scan_to_nodes(scan: Scan) -> StandardNodes:
    """Quantise a scan to standard nodes in the scan's beam order (SR-DRV-1).

    Ranges become 1/4 mm (NaN: 0, no return); angles 1/64 degree clockwise. The first beam
    carries the start flag. Intensities, when present, must be qualities 0..63; without them
    a return gets :data:`DEFAULT_QUALITY`. Raises :class:`EncodeError` naming the first beam
    that cannot be represented (negative range, or beyond 16.38 m).
    """
    ranges = scan.ranges_m
    finite = np.isfinite(ranges)
    q2 = np.zeros(ranges.shape, dtype=np.int64)
    q2[finite] = np.rint(ranges[finite] * 4000.0).astype(np.int64)
    bad = (np.isinf(ranges)) | (q2 < 0) | (q2 > MAX_DISTANCE_Q2)
    if np.any(bad):
        index = int(np.argmax(bad))
        raise EncodeError(
            f"rplidar: range {float(ranges[index])!r} m of beam {index} is outside 0..16.38375 m",
            index,
        )
    if scan.intensities is None:
        quality = np.where(q2 > 0, DEFAULT_QUALITY, 0).astype(np.int64)
    else:
        quality = np.rint(np.nan_to_num(scan.intensities, nan=0.0)).astype(np.int64)
        if np.any((quality < 0) | (quality > 63)):
            index = int(np.argmax((quality < 0) | (quality > 63)))
            raise EncodeError(
                f"rplidar: intensity {float(quality[index])!r} of beam {index} "
                "is not a quality 0..63",
                index,
            )
    start = np.arange(ranges.shape[0]) == 0
    return StandardNodes(start, quality, angles_to_q6(scan.angles_rad), q2)


def nodes_to_scan(
    nodes: StandardNodes,
    *,
    stamp_s: float,
    beam_period_s: float = 0.0,
    seq: int = 0,
    source: str = "rplidar",
    complete: bool = True,
) -> Scan:
    """A :class:`Scan` from decoded nodes: metres (0 becomes NaN), radians, qualities."""
    ranges = nodes.distance_q2.astype(np.float64) / 4000.0
    ranges[nodes.distance_q2 == 0] = np.nan
    return Scan(
        stamp_s=stamp_s,
        angles_rad=q6_to_angles(nodes.angle_q6),
        ranges_m=ranges,
        intensities=nodes.quality.astype(np.float64),
        beam_period_s=beam_period_s,
        seq=seq,
        source=source,
        complete=complete,
    )
