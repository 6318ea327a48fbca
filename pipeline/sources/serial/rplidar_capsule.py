"""RPLIDAR express-scan capsules (answer type 0x82) and ultra capsules (0x84): the codec.

Requirements SR-DRV-1 (symmetric express codec), SR-DRV-2 (checksummed frames) and SR-DRV-4
(the decoder reproduces a third-party driver's node values exactly).

Wire facts (Slamtec's protocol and SDK): a capsule starts with two bytes whose high nibbles
are the sync nibbles 0xA and 0x5 and whose low nibbles hold the checksum (low nibble first),
the XOR of every byte from offset 2 to the end. Bytes 2-3 hold ``start_angle_q6`` (15 bits)
and, in bit 15, the "new scan" flag. An express capsule then has 16 cabins of 5 bytes: two
little-endian u16 ``distance << 2 | dtheta[5:4]`` and one byte with the two low dtheta
nibbles; distances in mm, dtheta in 1/8 degree. The angles of a capsule's 32 nodes come from
its own start angle and the *next* capsule's: node k is at ``start + k * diff / 32 - dtheta``,
computed in the SDK's fixed-point steps, so a capsule is decoded only together with its
successor. An ultra capsule has 32 cabins of one little-endian u32 each: a 12-bit "major"
distance on a variable bit scale and two signed 10-bit predictions, 96 nodes per capsule.

The SDK reads dtheta as an unsigned 6-bit value while rplidar-roboticia reads bit 1 of the
distance word as a sign; the encoder keeps dtheta in 0..15 (1.875 degrees), where both
readings agree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.sources.serial.errors import ChecksumError, EncodeError, FrameError
from pipeline.sources.serial.rplidar import Q6_PER_TURN

__all__ = [
    "CAPSULE_BYTES",
    "NODES_PER_CAPSULE",
    "ULTRA_CAPSULE_BYTES",
    "CapsuleFields",
    "CapsuleNodes",
    "ExpressEncoder",
    "capsule_validity",
    "decode_capsule",
    "decode_express_pairs",
    "decode_ultra_pairs",
    "encode_capsule",
    "varbitscale_decode",
]

CAPSULE_BYTES = 84
ULTRA_CAPSULE_BYTES = 132
NODES_PER_CAPSULE = 32
ULTRA_NODES_PER_CAPSULE = 96
SYNC_NIBBLE1 = 0xA
SYNC_NIBBLE2 = 0x5
MAX_DISTANCE_MM = (1 << 14) - 1
_TURN_Q16 = 360 << 16
# The SDK's ultra-capsule angle correction, evaluated exactly as it does (its own pi digits).
_OFFSET_NEAR_Q16 = int(7.5 * 3.1415926535 * (1 << 16) / 180.0)
_OFFSET_FAR_Q16 = int(8 * 3.1415926535 * (1 << 16) / 180)
# Variable bit scale of ultra capsule distances: (scaled base, scale level, target base).
_VBS = ((3328, 4, 1 << 14), (1792, 3, 1 << 12), (1280, 2, 1 << 11), (512, 1, 1 << 9))

U8Array = npt.NDArray[np.uint8]
I64Array = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class CapsuleFields:
    """The raw fields of one express capsule (what the wire holds, before angle decoding)."""

    start_q6: int
    new_scan: bool
    distance_mm: I64Array  # 32 nodes
    dtheta_q3: I64Array  # 32 nodes, 0..63


@dataclass(frozen=True, slots=True)
class CapsuleNodes:
    """Decoded capsule nodes (flat, in time order): angle in 1/64 degree clockwise,
    distance in 1/4 mm (0: no return), and the SDK's sync bit (first node of a turn)."""

    angle_q6: I64Array
    distance_q2: I64Array
    sync: npt.NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.angle_q6.shape[0])


def capsule_validity(raw: U8Array) -> npt.NDArray[np.bool_]:
    """For ``(k, L)`` capsule bytes: sync nibbles right and XOR checksum matching."""
    sync_ok = ((raw[:, 0] >> 4) == SYNC_NIBBLE1) & ((raw[:, 1] >> 4) == SYNC_NIBBLE2)
    stated = (raw[:, 0] & 0x0F) | ((raw[:, 1] & 0x0F) << 4)
    valid: npt.NDArray[np.bool_] = sync_ok & (np.bitwise_xor.reduce(raw[:, 2:], axis=1) == stated)
    return valid


def _start(raw: U8Array) -> tuple[I64Array, npt.NDArray[np.bool_]]:
    start = raw[:, 2].astype(np.int64) | ((raw[:, 3].astype(np.int64) & 0x7F) << 8)
    return start, (raw[:, 3] & 0x80) != 0


def _with_checksum(body: bytearray) -> bytes:
    checksum = 0
    for byte in body[2:]:
        checksum ^= byte
    body[0] = (SYNC_NIBBLE1 << 4) | (checksum & 0x0F)
    body[1] = (SYNC_NIBBLE2 << 4) | (checksum >> 4)
    return bytes(body)


def encode_capsule(fields: CapsuleFields) -> bytes:
    """The 84 bytes of an express capsule (checksum computed)."""
    dist, dtheta = fields.distance_mm, fields.dtheta_q3
    if dist.shape != (NODES_PER_CAPSULE,) or dtheta.shape != (NODES_PER_CAPSULE,):
        raise EncodeError(f"express capsule: need 32 nodes, got {dist.shape} / {dtheta.shape}")
    bad = (dist < 0) | (dist > MAX_DISTANCE_MM) | (dtheta < 0) | (dtheta > 63)
    if np.any(bad):
        index = int(np.argmax(bad))
        raise EncodeError(
            f"express capsule node {index}: distance {dist[index]} mm (0..16383) or "
            f"dtheta {dtheta[index]} (0..63) out of range",
            index,
        )
    if not 0 <= fields.start_q6 < 1 << 15:
        raise EncodeError(f"express capsule: start_q6 {fields.start_q6} needs 0..32767")
    words = (dist << 2) | (dtheta >> 4)
    cabins = np.empty((16, 5), dtype=np.uint8)
    cabins[:, 0] = words[0::2] & 0xFF
    cabins[:, 1] = words[0::2] >> 8
    cabins[:, 2] = words[1::2] & 0xFF
    cabins[:, 3] = words[1::2] >> 8
    cabins[:, 4] = (dtheta[0::2] & 0x0F) | ((dtheta[1::2] & 0x0F) << 4)
    start = fields.start_q6 | (0x8000 if fields.new_scan else 0)
    body = bytearray(4) + cabins.tobytes()
    body[2] = start & 0xFF
    body[3] = start >> 8
    return _with_checksum(body)


def decode_capsule(data: bytes, offset: int = 0) -> CapsuleFields:
    """The raw fields of one 84-byte express capsule; raises on bad sync or checksum."""
    if len(data) != CAPSULE_BYTES:
        raise FrameError(f"express capsule: {len(data)} bytes, expected 84", offset)
    raw = np.frombuffer(data, dtype=np.uint8).reshape(1, CAPSULE_BYTES)
    if not capsule_validity(raw)[0]:
        raise ChecksumError("express capsule: sync nibbles or XOR checksum wrong", offset)
    start, new_scan = _start(raw)
    dist, dtheta = _express_cabins(raw)
    return CapsuleFields(int(start[0]), bool(new_scan[0]), dist[0], dtheta[0])


def _express_cabins(raw: U8Array) -> tuple[I64Array, I64Array]:
    cab = raw[:, 4:CAPSULE_BYTES].reshape(-1, 16, 5).astype(np.int64)
    w1 = cab[..., 0] | (cab[..., 1] << 8)
    w2 = cab[..., 2] | (cab[..., 3] << 8)
    # Node 2c comes from the cabin's first word, node 2c + 1 from its second.
    dist = np.empty((cab.shape[0], 16, 2), dtype=np.int64)
    dist[..., 0] = w1 >> 2
    dist[..., 1] = w2 >> 2
    dtheta = np.empty_like(dist)
    dtheta[..., 0] = (cab[..., 4] & 0x0F) | ((w1 & 0x3) << 4)
    dtheta[..., 1] = (cab[..., 4] >> 4) | ((w2 & 0x3) << 4)
    return dist.reshape(-1, NODES_PER_CAPSULE), dtheta.reshape(-1, NODES_PER_CAPSULE)


def _wrap_q6(angle: I64Array) -> I64Array:
    angle = np.where(angle < 0, angle + Q6_PER_TURN, angle)
    return np.where(angle >= Q6_PER_TURN, angle - Q6_PER_TURN, angle)


def _angle_steps(start_q6: I64Array, per_capsule: int) -> tuple[I64Array, I64Array]:
    """Per decoded pair: the q16 angle of its first node and the q16 increment per node."""
    prev_q8 = start_q6[:-1] << 2
    cur_q8 = start_q6[1:] << 2
    diff_q8 = cur_q8 - prev_q8 + np.where(prev_q8 > cur_q8, 360 << 8, 0)
    inc_q16 = diff_q8 << 3 if per_capsule == NODES_PER_CAPSULE else (diff_q8 << 3) // 3
    return prev_q8 << 8, inc_q16


def decode_express_pairs(raw: U8Array) -> CapsuleNodes:
    """Nodes of ``k - 1`` consecutive express capsules given ``(k, 84)`` bytes (vectorised).

    Capsule ``i`` is decoded with the start angle of capsule ``i + 1``; the caller must pass
    only capsules that passed :func:`capsule_validity` and follow each other on the wire.
    """
    start, _ = _start(raw)
    dist, dtheta = _express_cabins(raw)
    base_q16, inc_q16 = _angle_steps(start, NODES_PER_CAPSULE)
    nominal = base_q16[:, None] + np.arange(NODES_PER_CAPSULE)[None, :] * inc_q16[:, None]
    angle = _wrap_q6((nominal - (dtheta[:-1] << 13)) >> 10)
    sync = ((nominal + inc_q16[:, None]) % _TURN_Q16) < inc_q16[:, None]
    return CapsuleNodes(angle.ravel(), (dist[:-1] << 2).ravel(), sync.ravel())


def varbitscale_decode(scaled: I64Array) -> tuple[I64Array, I64Array]:
    """Ultra-capsule major distances from their variable bit scale: (value, scale level)."""
    value = scaled.copy()
    level = np.zeros_like(scaled)
    done = np.zeros(scaled.shape, dtype=np.bool_)
    for scaled_base, lvl, target_base in _VBS:
        hit = ~done & (scaled >= scaled_base)
        value[hit] = target_base + ((scaled[hit] - scaled_base) << lvl)
        level[hit] = lvl
        done |= hit
    return value, level


def decode_ultra_pairs(raw: U8Array) -> CapsuleNodes:
    """Nodes of ``k - 1`` consecutive ultra capsules given ``(k, 132)`` bytes (vectorised)."""
    start, _ = _start(raw)
    cab = raw[:, 4:ULTRA_CAPSULE_BYTES].reshape(-1, 32, 4).astype(np.int64)
    word = cab[..., 0] | (cab[..., 1] << 8) | (cab[..., 2] << 16) | (cab[..., 3] << 24)
    major = word & 0xFFF
    predict = np.stack(((word >> 12) & 0x3FF, (word >> 22) & 0x3FF), axis=-1)
    predict = np.where(predict & 0x200, predict - 0x400, predict)  # signed 10-bit
    major_next = np.concatenate((major[:-1, 1:], major[1:, :1]), axis=1)
    m1, lvl1 = varbitscale_decode(major[:-1])
    m2, lvl2 = varbitscale_decode(major_next)
    borrow = (m1 == 0) & (m2 != 0)
    base1 = np.where(borrow, m2, m1)
    lvl1 = np.where(borrow, lvl2, lvl1)
    p1, p2 = predict[:-1, :, 0], predict[:-1, :, 1]
    # The SDK works in u32: a negative prediction wraps; -512 and 511 mean "no return".
    d1 = np.where((p1 == -512) | (p1 == 511), 0, (((p1 << lvl1) + base1) << 2) % (1 << 32))
    d2 = np.where((p2 == -512) | (p2 == 511), 0, (((p2 << lvl2) + m2) << 2) % (1 << 32))
    dist = np.stack((m1 << 2, d1, d2), axis=-1).reshape(-1, ULTRA_NODES_PER_CAPSULE)
    base_q16, inc_q16 = _angle_steps(start, ULTRA_NODES_PER_CAPSULE)
    nominal = base_q16[:, None] + np.arange(ULTRA_NODES_PER_CAPSULE)[None, :] * inc_q16[:, None]
    sync = ((nominal + inc_q16[:, None]) % _TURN_Q16) < inc_q16[:, None]
    far = dist >= 50 * 4
    k2 = np.trunc(98361.0 / np.where(far, dist, 1)).astype(np.int64)
    offset_q16 = np.where(
        far,
        _OFFSET_FAR_Q16 - (k2 << 6) - np.trunc(k2**3 / 98304.0).astype(np.int64),
        _OFFSET_NEAR_Q16,
    )
    correction = np.trunc((offset_q16 * 180) / 3.14159265).astype(np.int64)
    angle = _wrap_q6((nominal - correction) >> 10)
    return CapsuleNodes(angle.ravel(), dist.ravel(), sync.ravel())


class ExpressEncoder:
    """Turns a stream of nodes into express capsules, as a device would (SR-DRV-1).

    :meth:`push` takes target angles (clockwise, 1/64 degree, floats) and distances (mm) and
    returns the capsules it can finish: a capsule is finished once the start angle of the
    next one is known, because the decoder interpolates towards it. The start angle of each
    capsule is its first target plus :attr:`margin_q6`, and each node's ``dtheta`` takes up
    the difference; :class:`EncodeError` is raised when a node cannot get within
    ``tolerance_q6`` of its target (beams too irregular for express mode). :meth:`flush`
    pads with no-return nodes continuing the last angular step and finishes everything.
    """

    margin_q6 = 8
    max_dtheta_q3 = 15

    def __init__(self, tolerance_q6: float = 8.0) -> None:
        self.tolerance_q6 = tolerance_q6
        self._angles: list[float] = []
        self._dist: list[int] = []
        self._held: tuple[int, npt.NDArray[np.float64], I64Array] | None = None
        self._first = True
        self._step_q6 = 0.0

    def push(self, angle_q6: npt.ArrayLike, distance_mm: npt.ArrayLike) -> bytes:
        """Queue nodes; return the bytes of every capsule that is now final."""
        angles = np.asarray(angle_q6, dtype=np.float64)
        dist = np.asarray(distance_mm, dtype=np.int64)
        if angles.shape != dist.shape or angles.ndim != 1:
            raise EncodeError("express encoder: angles and distances must be equal 1-D arrays")
        bad = ~np.isfinite(angles) | (dist < 0) | (dist > MAX_DISTANCE_MM)
        if np.any(bad):
            index = int(np.argmax(bad))
            raise EncodeError(
                f"express encoder: node {index} angle {angles[index]!r} or distance "
                f"{dist[index]} mm (0..16383) not representable",
                index,
            )
        if angles.shape[0] >= 2:
            self._step_q6 = float(np.median(np.diff(np.unwrap(angles, period=Q6_PER_TURN))))
        self._angles.extend(np.mod(angles, Q6_PER_TURN).tolist())
        self._dist.extend(dist.tolist())
        out = bytearray()
        while len(self._angles) >= NODES_PER_CAPSULE:
            targets = np.array(self._angles[:NODES_PER_CAPSULE])
            dists = np.array(self._dist[:NODES_PER_CAPSULE], dtype=np.int64)
            del self._angles[:NODES_PER_CAPSULE], self._dist[:NODES_PER_CAPSULE]
            start = int(np.rint(targets[0]) + self.margin_q6) % Q6_PER_TURN
            if self._held is not None:
                out += self._finish(start)
            self._held = (start, targets, dists)
        return bytes(out)

    def flush(self) -> bytes:
        """Pad with no-return nodes and finish every capsule (the stream ends here)."""
        if self._held is None and not self._angles:
            return b""
        last = self._angles[-1] if self._angles else float(self._held[1][-1])  # type: ignore[index]
        step = self._step_q6 if self._step_q6 > 0 else 64.0
        need = (-len(self._angles)) % NODES_PER_CAPSULE + 2 * NODES_PER_CAPSULE
        # Padding nodes carry no return, so their angles are exempt from the tolerance.
        out = self.push(last + step * np.arange(1, need + 1), np.zeros(need, dtype=np.int64))
        self._held = None
        self._angles.clear()
        self._dist.clear()
        return out

    def _finish(self, next_start: int) -> bytes:
        assert self._held is not None
        start, targets, dists = self._held
        inc_q16 = ((next_start - start) % Q6_PER_TURN) * 32
        nominal_q6 = (start * 1024 + np.arange(NODES_PER_CAPSULE) * inc_q16) >> 10
        ahead = np.mod(nominal_q6 - targets + Q6_PER_TURN / 2, Q6_PER_TURN) - Q6_PER_TURN / 2
        step = np.rint(ahead / 8.0)
        # Keep each node in its target's turn: a node just past 0 deg must not decode to just
        # below 360 (nor the reverse), or it would land in the neighbouring revolution.
        step = np.where(targets + ahead - 8 * step < 0, np.floor((ahead + targets) / 8), step)
        limit = Q6_PER_TURN - 1 - targets
        step = np.where(ahead - 8 * step > limit, np.ceil((ahead - limit) / 8), step)
        dtheta = np.clip(step, 0, self.max_dtheta_q3).astype(np.int64)
        error = ahead - 8 * dtheta
        error = np.where((targets + error < 0) | (error > limit), np.inf, error)
        real = dists > 0
        if np.any(real & (np.abs(error) > self.tolerance_q6)):
            index = int(np.argmax(real & (np.abs(error) > self.tolerance_q6)))
            raise EncodeError(
                f"express encoder: node {index} of a capsule lands {error[index] / 64:.3f} deg "
                f"from its target (tolerance {self.tolerance_q6 / 64:.3f} deg): beams too "
                "irregular for express capsules",
                index,
            )
        capsule = encode_capsule(CapsuleFields(start, self._first, dists, dtheta))
        self._first = False
        return capsule
