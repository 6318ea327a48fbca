"""Incremental RPLIDAR stream decoding: bytes in, one :class:`Scan` per revolution out.

Requirement SR-DRV-2. :meth:`RplidarStream.feed` never raises on any input: a frame failing
its check (standard node: start-flag pair and check bit; capsule: sync nibbles and XOR
checksum; both: an implausible angle step) is rejected and counted, the decoder searches for
the next position where frames check again, and the revolution that lost beams is marked
incomplete (see :mod:`pipeline.sources.serial.assembly` for the policy).

Standard nodes carry only three check bits and no checksum over the distance, so two extra
guards apply: the angle must advance by at most ``max_step_deg`` per node (a misaligned or
corrupted node rarely does), and the last ``retract_nodes`` nodes before a rejected one are
withdrawn, since a dropped byte corrupts the node before the first one that fails. A bit flip
inside a distance field remains undetectable in this mode: the protocol has nothing to catch
it (express capsules do; see README "Serial drivers").
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt
from numpy.lib.stride_tricks import sliding_window_view

from pipeline.sources.serial.assembly import IncompletePolicy, LinkCounters, RevolutionBuilder
from pipeline.sources.serial.rplidar import NODE_BYTES, Q6_PER_TURN, fields_of, node_validity
from pipeline.sources.serial.rplidar_capsule import (
    CAPSULE_BYTES,
    ULTRA_CAPSULE_BYTES,
    capsule_validity,
    decode_express_pairs,
    decode_ultra_pairs,
)
from pipeline.types import Scan

__all__ = ["RplidarMode", "RplidarStream"]

RplidarMode = Literal["standard", "express", "ultra"]
U8Array = npt.NDArray[np.uint8]
I64Array = npt.NDArray[np.int64]

LOCK_NODES = 3  # consecutive valid nodes needed to (re)gain alignment
MAX_CAPSULE_SPAN_DEG = 90.0  # start angles of consecutive capsules differ by less


class RplidarStream:
    """Decodes an RPLIDAR scan stream in ``mode`` (standard nodes, express or ultra
    capsules) into revolutions. Bounded memory: at most two frames of unconsumed bytes plus
    one revolution of at most ``max_beams`` beams."""

    def __init__(
        self,
        mode: RplidarMode = "standard",
        *,
        counters: LinkCounters | None = None,
        policy: IncompletePolicy = "mark",
        max_beams: int = 8192,
        max_step_deg: float = 10.0,
        retract_nodes: int = 2,
        source: str = "rplidar",
    ) -> None:
        self.mode = mode
        self.counters = counters if counters is not None else LinkCounters()
        self.builder = RevolutionBuilder(
            self.counters,
            source=source,
            policy=policy,
            max_beams=max_beams,
            with_quality=mode == "standard",
        )
        self.max_step_q6 = round(max_step_deg * 64)
        self.retract = retract_nodes
        self.frame_bytes = {
            "standard": NODE_BYTES,
            "express": CAPSULE_BYTES,
            "ultra": ULTRA_CAPSULE_BYTES,
        }[mode]
        self.max_span_q6 = int(MAX_CAPSULE_SPAN_DEG * 64)
        self._buf = b""
        self._locked = False
        self._prev_angle = -1
        self._staged: list[tuple[U8Array, float]] = []
        self._held: U8Array | None = None

    def reset(self) -> None:
        """Start afresh (after a reconnect): drop buffered bytes and the open revolution."""
        self.counters.bytes_discarded += len(self._buf)
        self._buf = b""
        self._locked = False
        self._prev_angle = -1
        self._staged.clear()
        self._held = None
        self.builder.reset()

    def feed(self, data: bytes, now_s: float) -> list[Scan]:
        """Consume ``data`` read at host time ``now_s``; return the completed revolutions."""
        buf = np.frombuffer(self._buf + data, dtype=np.uint8)
        out: list[Scan] = []
        pos = 0
        while True:
            if self._locked:
                pos, more = (
                    self._aligned_nodes(buf, pos, now_s, out)
                    if self.mode == "standard"
                    else self._aligned_capsules(buf, pos, now_s, out)
                )
            else:
                pos, more = self._search(buf, pos)
            if not more:
                break
        self._buf = bytes(buf[pos:])
        return out

    # -- standard nodes ------------------------------------------------------------------
    def _aligned_nodes(
        self, buf: U8Array, pos: int, now_s: float, out: list[Scan]
    ) -> tuple[int, bool]:
        n = (buf.shape[0] - pos) // NODE_BYTES
        if n == 0:
            return pos, False
        raw = buf[pos : pos + n * NODE_BYTES].reshape(n, NODE_BYTES)
        good = node_validity(raw) & self._plausible(raw)
        j = n if bool(np.all(good)) else int(np.argmin(good))
        if j:
            self._commit(raw[:j], now_s, out)
            self.counters.frames_ok += j
        if j == n:
            return pos + n * NODE_BYTES, False
        self._reject()
        self.counters.bytes_discarded += 1
        return pos + j * NODE_BYTES + 1, True

    def _plausible(self, raw: U8Array) -> npt.NDArray[np.bool_]:
        """Angle steps of at most ``max_step_deg``, and a start flag only where the angle
        wraps (a device sets it on the first node of a turn, the one with the smallest angle;
        a byte slip can forge the flag elsewhere)."""
        angle = (raw[:, 1].astype(np.int64) >> 1) | (raw[:, 2].astype(np.int64) << 7)
        start = (raw[:, 0] & 1).astype(np.bool_)
        prev = np.empty_like(angle)
        prev[0] = self._prev_angle
        prev[1:] = angle[:-1]
        step = np.mod(angle - prev, Q6_PER_TURN)
        before = prev.copy()
        if before[0] < 0:
            before[0] = self.builder.last_angle
        ok: npt.NDArray[np.bool_] = ((step <= self.max_step_q6) | (prev < 0)) & (
            ~start | (before < 0) | (angle < before)
        )
        return ok

    def _commit(self, raw: U8Array, now_s: float, out: list[Scan]) -> None:
        """Stage the newest nodes; hand older ones to the revolution builder."""
        self._prev_angle = int(raw[-1, 1] >> 1) | (int(raw[-1, 2]) << 7)
        self._staged.append((raw, now_s))
        staged_n = sum(r.shape[0] for r, _ in self._staged)
        release = staged_n - self.retract
        keep: list[tuple[U8Array, float]] = []
        for chunk, stamp_s in self._staged:
            if release <= 0:
                keep.append((chunk, stamp_s))
                continue
            take = min(release, chunk.shape[0])
            nodes = fields_of(chunk[:take])
            out.extend(
                self.builder.add(
                    nodes.angle_q6, nodes.distance_q2, nodes.quality, nodes.start, stamp_s
                )
            )
            release -= take
            if take < chunk.shape[0]:
                keep.append((chunk[take:], stamp_s))
        self._staged = keep

    def _reject(self) -> None:
        self.counters.frames_rejected += 1
        self._staged.clear()
        self._held = None
        self._locked = False
        self._prev_angle = -1
        self.builder.mark_incomplete()

    # -- capsules ------------------------------------------------------------------------
    def _spans_ok(self, first_prev: U8Array | None, raw: U8Array) -> npt.NDArray[np.bool_]:
        start = raw[:, 2].astype(np.int64) | ((raw[:, 3].astype(np.int64) & 0x7F) << 8)
        prev = np.empty_like(start)
        prev[1:] = start[:-1]
        if first_prev is None:
            prev[0] = -1
        else:
            prev[0] = int(first_prev[2]) | ((int(first_prev[3]) & 0x7F) << 8)
        span = np.mod(start - prev, Q6_PER_TURN)
        ok: npt.NDArray[np.bool_] = ((span <= self.max_span_q6) | (prev < 0)) & (
            start < Q6_PER_TURN
        )
        return ok

    def _aligned_capsules(
        self, buf: U8Array, pos: int, now_s: float, out: list[Scan]
    ) -> tuple[int, bool]:
        size = self.frame_bytes
        k = (buf.shape[0] - pos) // size
        if k == 0:
            return pos, False
        raw = buf[pos : pos + k * size].reshape(k, size)
        good = capsule_validity(raw) & self._spans_ok(self._held, raw)
        j = k if bool(np.all(good)) else int(np.argmin(good))
        if j:
            run = raw[:j] if self._held is None else np.concatenate((self._held[None], raw[:j]))
            if run.shape[0] >= 2:
                decode = decode_express_pairs if self.mode == "express" else decode_ultra_pairs
                nodes = decode(run)
                out.extend(self.builder.add(nodes.angle_q6, nodes.distance_q2, None, None, now_s))
            self._held = raw[j - 1].copy()
            self.counters.frames_ok += j
        if j == k:
            return pos + k * size, False
        self._reject()
        self.counters.bytes_discarded += 1
        return pos + j * size + 1, True

    # -- re-synchronisation --------------------------------------------------------------
    def _search(self, buf: U8Array, pos: int) -> tuple[int, bool]:
        """Find the first offset where frames check again; discard the bytes before it."""
        size = self.frame_bytes
        need = size * (LOCK_NODES if self.mode == "standard" else 2)
        avail = buf.shape[0] - pos
        if avail < need:
            return pos, False
        view = buf[pos:]
        if self.mode == "standard":
            windows = sliding_window_view(view, NODE_BYTES)
            valid = node_validity(windows)
            angle = (windows[:, 1].astype(np.int64) >> 1) | (windows[:, 2].astype(np.int64) << 7)
            start = (windows[:, 0] & 1).astype(np.bool_)
            last = avail - need + 1
            ok = valid[:last].copy()
            before = self.builder.last_angle
            if before >= 0:
                ok &= ~start[:last] | (angle[:last] < before)
            for i in range(1, LOCK_NODES):
                here = slice(i * size, i * size + last)
                ok &= ~start[here] | (angle[here] < angle[(i - 1) * size :][:last])
                step = np.mod(
                    angle[i * size : i * size + last] - angle[(i - 1) * size :][:last], Q6_PER_TURN
                )
                ok &= valid[i * size : i * size + last] & (step <= self.max_step_q6)
        else:
            last = avail - need + 1
            ok = self._capsule_candidates(view, last)
        if not bool(np.any(ok)):
            self.counters.bytes_discarded += last
            return pos + last, False
        found = int(np.argmax(ok))
        self.counters.bytes_discarded += found
        self._locked = True
        self._prev_angle = -1
        self._held = None
        return pos + found, True

    def _capsule_candidates(self, view: U8Array, last: int) -> npt.NDArray[np.bool_]:
        """Offsets ``q < last`` where two adjacent capsules pass sync, checksum and span."""
        size = self.frame_bytes
        prefix = np.zeros(view.shape[0] + 1, dtype=np.uint8)
        np.bitwise_xor.accumulate(view, out=prefix[1:])
        limit = view.shape[0] - size + 1
        q = np.arange(limit)
        sync = ((view[:limit] >> 4) == 0xA) & ((view[1 : limit + 1] >> 4) == 0x5)
        stated = (view[:limit] & 0x0F) | ((view[1 : limit + 1] & 0x0F) << 4)
        xor = prefix[q + size] ^ prefix[q + 2]
        single = sync & (xor == stated)
        start = view[2 : limit + 2].astype(np.int64) | (
            (view[3 : limit + 3].astype(np.int64) & 0x7F) << 8
        )
        span = np.mod(start[size:limit] - start[: limit - size], Q6_PER_TURN)
        pair = single[: limit - size] & single[size:limit] & (span <= self.max_span_q6)
        ok: npt.NDArray[np.bool_] = pair[:last] & (start[:last] < Q6_PER_TURN)
        return ok
