"""Fuzz cases for the serial stream decoders: clean device streams with a known truth, and
their mutations (requirements SR-DRV-2, SR-DRV-3).

A *batch* is a clean device stream of a few revolutions (RPLIDAR standard nodes, RPLIDAR
express capsules, or SCIP 2.0 MD/GD answers) whose every returned beam carries a distance
used nowhere else in the batch, so a decoded beam names the beam it came from (distances are
multiples of 3: one flipped bit never turns one into another). The truth is what the codec
put on the wire: the nodes, the capsule pairs or the step values. :func:`mutate` applies one
mutation per window of frames (a frame: one standard node, one capsule, one SCIP line): bit
flip, truncation, dropped frame, duplicated frame, swapped adjacent frames, or garbage
inserted before a frame. :func:`decode_stream` runs the driver's own stream decoder over the
bytes in reads of random size. Everything is driven by the ``numpy.random.Generator`` given,
so a seed reproduces a case. The campaign and its judge: :mod:`properties.fuzz_campaign`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from pipeline.compat import StrEnum
from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip
from pipeline.sources.serial.assembly import LinkCounters
from pipeline.sources.serial.devices import ScipDevice
from pipeline.sources.serial.rplidar_capsule import CAPSULE_BYTES, decode_express_pairs
from pipeline.sources.serial.rplidar_stream import RplidarStream
from pipeline.sources.serial.scip_stream import ScipStream
from pipeline.types import Scan
from properties.driver_streams import UTM_30LX, device_frames

__all__ = [
    "MUTATIONS",
    "MUTATIONS_PER_REVOLUTION",
    "PROTOCOLS",
    "Batch",
    "Mutation",
    "Protocol",
    "Truth",
    "decode_stream",
    "make_batch",
    "mutate",
]

Protocol = Literal["rplidar-standard", "rplidar-express", "scip"]
PROTOCOLS: tuple[Protocol, ...] = ("rplidar-standard", "rplidar-express", "scip")
I64Array = npt.NDArray[np.int64]

GARBAGE_BYTES = 64  # longest garbage burst
# Reads fed to a decoder at once: log-uniform from a small serial read to a replayed capture.
READ_BYTES = (256, 65536)
NO_RETURN_SHARE = 0.05
# Mutations per revolution: a standard revolution has 360 nodes, enough room for four
# mutations whose effects stay apart (a rejection costs a handful of nodes).
MUTATIONS_PER_REVOLUTION: dict[str, int] = {
    "rplidar-standard": 4,
    "rplidar-express": 1,
    "scip": 1,
}


class Mutation(StrEnum):
    """One change to one frame of a device stream (a swap changes two adjacent frames)."""

    BIT_FLIP = "bit flip"
    TRUNCATION = "truncation"
    DROP = "dropped frame"
    DUPLICATE = "duplicated frame"
    SWAP = "swapped frames"
    GARBAGE = "garbage"


MUTATIONS: tuple[Mutation, ...] = tuple(Mutation)


@dataclass(frozen=True, slots=True)
class Truth:
    """The beams a batch sent. Angle keys are whole protocol units (1/64 degree for RPLIDAR,
    steps for SCIP); a beam's identity is its distance key, unique per batch for a return
    and 0 for no return; revolutions are numbered in wire order from 0."""

    pairs: I64Array  # sorted (angle key << 32 | value key) of every beam sent
    angles: I64Array  # sorted angle keys at which anything was sent
    idents: I64Array  # sorted identities of the returns
    ident_angles: I64Array  # angle key of each identity, in the order of ``idents``
    ident_revolutions: I64Array  # revolution of each identity, in the order of ``idents``
    unit_deg: float  # degrees per angle key
    turn: int  # angle keys per turn


@dataclass(frozen=True, slots=True)
class Batch:
    """A clean stream: the bytes before the first frame, the frames, how many frames one
    revolution takes, beams per revolution, the truth, and the SCIP model and command."""

    protocol: Protocol
    prefix: bytes
    frames: tuple[bytes, ...]
    frames_per_revolution: int
    beams_per_revolution: int
    truth: Truth
    params: scip.ScipParams | None = None
    command: scip.ScipCommand | None = None


def _truth(angle: I64Array, value: I64Array, ident: I64Array, unit_deg: float, turn: int) -> Truth:
    """The truth of beams given in wire order (a new revolution where the angle falls)."""
    returns = ident > 0
    order = np.argsort(ident[returns], kind="stable")
    revolution = np.concatenate(([0], np.cumsum(np.diff(angle) < -turn // 2)))
    return Truth(
        pairs=np.unique((angle << 32) | value),
        angles=np.unique(angle),
        idents=ident[returns][order],
        ident_angles=angle[returns][order],
        ident_revolutions=revolution[returns][order],
        unit_deg=unit_deg,
        turn=turn,
    )


def _rplidar_batch(protocol: Protocol, rng: np.random.Generator, revolutions: int) -> Batch:
    express = protocol == "rplidar-express"
    # RPLIDAR A1 standard scans: about 360 samples a turn; express (A2/A3): 360 to 800.
    n = int(rng.choice([360, 720])) if express else 360
    step = 2 * np.pi / n
    # Unique distances: 1/4 mm for standard nodes, whole mm for express capsules.
    pool = np.arange(102, 1 << 14, 3) if express else np.arange(402, 1 << 16, 3)
    revolutions = min(revolutions, pool.shape[0] // n)
    drawn = rng.choice(pool, size=revolutions * n, replace=False).reshape(revolutions, n)
    scans = []
    for r in range(revolutions):
        angles = -(np.arange(n) + rng.uniform(-0.05, 0.05, n)) * step
        angles[0] = 0.0
        ranges = drawn[r] / (1000.0 if express else 4000.0)
        ranges[rng.random(n) < NO_RETURN_SHARE] = np.nan
        quality = np.where(np.isnan(ranges), 0.0, rng.integers(1, 64, n).astype(np.float64))
        scans.append(Scan(0.0, angles, ranges, None if express else quality))
    frames = device_frames("rplidar-express" if express else "rplidar-standard", scans)
    raw = np.frombuffer(b"".join(frames.frames), dtype=np.uint8)
    if express:
        nodes = decode_express_pairs(raw.reshape(-1, CAPSULE_BYTES))
        angle, value = nodes.angle_q6, nodes.distance_q2
        ident, per_rev = value, max(1, n // 32)
    else:
        standard = rp.decode_nodes(raw)
        angle = standard.angle_q6
        ident = standard.distance_q2
        value, per_rev = (ident << 6) | standard.quality, n
    truth = _truth(angle, value, ident, 1 / 64, rp.Q6_PER_TURN)
    return Batch(protocol, frames.prefix, tuple(frames.frames), per_rev, n, truth)


def _scip_batch(rng: np.random.Generator, revolutions: int) -> Batch:
    streaming = bool(rng.integers(0, 2))
    params = UTM_30LX
    name = scip.Name.MD if streaming else scip.Name.GD
    command = scip.ScipCommand(name, params.amin, params.amax, 1, 0, 0)
    n = command.n_values
    pool = np.arange(-(-params.dmin_mm // 3) * 3, params.dmax_mm + 1, 3)
    # Both low characters of every value at least 15: a 3-character group read one or two
    # characters off (lines swapped) then starts with a character >= 15, which is above
    # 61439 mm, beyond DMAX: it reads as no return, never as another value that was sent.
    pool = pool[((pool >> 6) & 0x3F >= 15) & (pool & 0x3F >= 15)]
    revolutions = min(revolutions, pool.shape[0] // n)
    drawn = rng.choice(pool, size=revolutions * n, replace=False).reshape(revolutions, n)
    steps = np.arange(params.amin, params.amax + 1, dtype=np.float64)
    angles = (steps - params.afrt) * params.step_rad
    device = ScipDevice(params)
    prefix = device.receive(command.encode())
    frames: list[bytes] = []
    angle_keys, values = [], []
    for r in range(revolutions):
        ranges = drawn[r] / 1000.0
        ranges[rng.random(n) < NO_RETURN_SHARE] = np.nan
        scan = Scan(0.0, angles, ranges)
        if not streaming:
            device.receive(command.encode())  # GD answers one scan per request
        frames += device.frames(scan)
        sent = scip.scan_to_values(scan, params, command)
        values.append(np.where((sent >= params.dmin_mm) & (sent <= params.dmax_mm), sent, 0))
        angle_keys.append(np.arange(params.amin, params.amax + 1, dtype=np.int64))
    value = np.concatenate(values).astype(np.int64)
    truth = _truth(np.concatenate(angle_keys), value, value, 360 / params.ares, params.ares)
    per_rev = len(frames) // revolutions
    return Batch("scip", prefix, tuple(frames), per_rev, n, truth, params, command)


def make_batch(protocol: Protocol, rng: np.random.Generator, revolutions: int = 8) -> Batch:
    """A clean stream of ``revolutions`` turns (RPLIDAR: plus a closing turn) for ``protocol``."""
    if protocol == "scip":
        return _scip_batch(rng, revolutions)
    return _rplidar_batch(protocol, rng, revolutions)


def mutate(
    frames: Sequence[bytes], mutation: Mutation, rng: np.random.Generator, window: int
) -> tuple[list[bytes], int]:
    """``frames`` with one ``mutation`` at a random frame of every ``window`` frames; returns
    the mutated frames and the number of mutations."""
    out = list(frames)
    n = len(out)
    starts = np.arange(0, n - 1, max(1, window))
    widths = np.minimum(window, n - 1 - starts)
    positions = starts + (rng.random(starts.shape[0]) * widths).astype(np.int64)
    for pos in positions[::-1].tolist():
        frame = out[pos]
        if mutation is Mutation.BIT_FLIP:
            flipped = bytearray(frame)
            flipped[int(rng.integers(len(frame)))] ^= 1 << int(rng.integers(8))
            out[pos] = bytes(flipped)
        elif mutation is Mutation.TRUNCATION:
            # At least one byte stays (a frame cut to nothing is a dropped frame).
            out[pos] = frame[: int(rng.integers(1, len(frame))) if len(frame) > 1 else 0]
        elif mutation is Mutation.DROP:
            del out[pos]
        elif mutation is Mutation.DUPLICATE:
            out.insert(pos, frame)
        elif mutation is Mutation.SWAP:
            out[pos], out[pos + 1] = out[pos + 1], frame
        else:
            size = int(rng.integers(1, GARBAGE_BYTES + 1))
            out.insert(pos, rng.integers(0, 256, size, dtype=np.uint8).tobytes())
    return out, int(positions.shape[0])


def decode_stream(
    batch: Batch, data: bytes, rng: np.random.Generator
) -> tuple[list[Scan], LinkCounters, float]:
    """Decode ``data`` with a fresh stream decoder in reads of one random size within
    :data:`READ_BYTES`; returns the scans, the counters and the decoder's seconds."""
    counters = LinkCounters()
    decoder: RplidarStream | ScipStream
    if batch.protocol == "scip":
        assert batch.params is not None
        assert batch.command is not None
        decoder = ScipStream(batch.params, batch.command, counters=counters)
    else:
        decoder = RplidarStream(
            "standard" if batch.protocol == "rplidar-standard" else "express", counters=counters
        )
    low, high = np.log(READ_BYTES[0]), np.log(READ_BYTES[1])
    read = int(np.exp(rng.uniform(low, high)))
    out: list[Scan] = []
    started = time.perf_counter()
    for at in range(0, len(data), read):
        out += decoder.feed(data[at : at + read], float(at))
    return out, counters, time.perf_counter() - started
