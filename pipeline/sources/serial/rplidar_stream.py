"""Incremental RPLIDAR stream decoding: bytes in, one :class:`Scan` per revolution out.

Requirements SR-DRV-2, SR-DRV-6. :meth:`RplidarStream.feed` never raises on any input: a
frame failing its check (standard node: start-flag pair and check bit; capsule: sync nibbles
and XOR checksum; both: an implausible angle step) is rejected and counted, the decoder
searches for the next position where frames check again, and the revolution that lost beams
is marked incomplete (see :mod:`pipeline.sources.serial.assembly` for the policy).

Standard nodes carry only three check bits and no checksum over the distance, so two extra
guards apply: the angle must advance by at least 1/64 degree and at most ``max_step_deg`` per
node (a repeated, misaligned or corrupted node rarely does), and the last ``retract_nodes``
nodes before a rejected one are withdrawn, since a dropped byte corrupts the node before the
first one that fails. A bit flip inside a distance field, or in the low angle bits, remains
undetectable in this mode: the protocol has nothing to catch it (express capsules do).

An express or ultra capsule's beams are interpolated between its own start angle and the
next capsule's, so a missing, repeated or swapped capsule would put a whole capsule of beams
at angles they were not measured at while every checksum passes. The rotation speed cannot
change by much within one capsule, so the span between consecutive start angles must agree
with the last accepted span (within ``SPAN_TOLERANCE``); a pair whose span does not is
rejected. Until a span is known (after a start or reconnect), a span is trusted only once
``LEARN_SPANS`` consecutive spans agree: an isolated fault never makes that many.

Work is linear in the bytes fed: each step examines a bounded, doubling window of the
buffer, so a rejected frame never makes the decoder re-examine the rest of a large feed.
"""

from __future__ import annotations

import itertools
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
# A capsule lasts milliseconds: the motor cannot change speed by a quarter in that time, while
# a missing capsule doubles the span and a repeated one makes it zero.
SPAN_TOLERANCE = 0.25
SPAN_SLACK_Q6 = 4  # start angles are whole 1/64 degrees: room for their rounding
LEARN_SPANS = 3  # consecutive agreeing spans that establish the rotation speed
# This many rejected spans in a row: the learnt speed itself may be wrong, learn afresh. An
# isolated fault rejects at most three (a swap: two long spans around a backward one).
SPAN_MISSES_TO_RELEARN = 8
FIRST_CHUNK_FRAMES = 8  # frames examined by the first step after a rejection (then doubling)
MAX_CHUNK_FRAMES = 8192  # the doubling stops here (bounds the arrays of one step)
FIRST_SEARCH_BYTES = 512  # offsets examined by the first re-synchronisation step (doubling)


class RplidarStream:
    """Decodes an RPLIDAR scan stream in ``mode`` (standard nodes, express or ultra
    capsules) into revolutions (SR-DRV-2, SR-DRV-6). Bounded memory: at most two frames of
    unconsumed bytes plus one revolution of at most ``max_beams`` beams."""

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
        self._held: U8Array | None = None  # the last capsule, waiting for its successor
        self._held_start = -1  # its start angle (1/64 degree)
        self._ref_span = -1  # last accepted capsule span (1/64 degree); -1: not known
        self._prev_span = -1  # span of the last capsule pair since the last rejected frame
        self._run = 0  # consecutive agreeing spans while learning
        self._misses = 0  # rejected spans in a row
        self._chunk = FIRST_CHUNK_FRAMES  # frames the next aligned step examines

    def reset(self) -> None:
        """Start afresh (after a reconnect): drop buffered bytes and the open revolution."""
        self.counters.bytes_discarded += len(self._buf)
        self._buf = b""
        self._locked = False
        self._prev_angle = -1
        self._staged.clear()
        self._held = None
        self._ref_span = self._prev_span = -1
        self._run = self._misses = 0
        self._chunk = FIRST_CHUNK_FRAMES
        self.builder.reset()

    def feed(self, data: bytes, now_s: float) -> list[Scan]:
        """Consume ``data`` read at host time ``now_s``; return the completed revolutions.

        Never raises; the work is linear in ``len(data)``."""
        buf = np.frombuffer(self._buf + data, dtype=np.uint8)
        out: list[Scan] = []
        pos = 0
        while True:
            if self._locked:
                aligned = self._aligned_nodes if self.mode == "standard" else self._aligned_capsules
                pos, more, clean = aligned(buf, pos, self._chunk, now_s, out)
                # Doubling after clean steps (across feeds too) keeps a clean stream
                # vectorised; starting small after a rejection bounds the work wasted on
                # frames after the next bad one to twice the clean frames before it.
                self._chunk = (
                    min(self._chunk * 2, MAX_CHUNK_FRAMES) if clean else FIRST_CHUNK_FRAMES
                )
            else:
                pos, more = self._search(buf, pos)
            if not more:
                break
        self._buf = bytes(buf[pos:])
        return out

    # -- standard nodes ------------------------------------------------------------------
    def _aligned_nodes(
        self, buf: U8Array, pos: int, limit: int, now_s: float, out: list[Scan]
    ) -> tuple[int, bool, bool]:
        """Decode up to ``limit`` aligned nodes at ``pos``: (new pos, more to do, all good)."""
        n = min((buf.shape[0] - pos) // NODE_BYTES, limit)
        if n == 0:
            return pos, False, True
        raw = buf[pos : pos + n * NODE_BYTES].reshape(n, NODE_BYTES)
        good = node_validity(raw) & self._plausible(raw)
        j = n if bool(np.all(good)) else int(np.argmin(good))
        if j:
            self._commit(raw[:j], now_s, out)
            self.counters.frames_ok += j
        if j == n:
            end = pos + n * NODE_BYTES
            return end, buf.shape[0] - end >= NODE_BYTES, True
        self._reject()
        self.counters.bytes_discarded += 1
        return pos + j * NODE_BYTES + 1, True, False

    def _plausible(self, raw: U8Array) -> npt.NDArray[np.bool_]:
        """Angle steps of 1/64 degree to ``max_step_deg`` (a repeated node does not advance),
        and a start flag only where the angle wraps (a device sets it on the first node of a
        turn, the one with the smallest angle; a byte slip can forge the flag elsewhere)."""
        angle = (raw[:, 1].astype(np.int64) >> 1) | (raw[:, 2].astype(np.int64) << 7)
        start = (raw[:, 0] & 1).astype(np.bool_)
        prev = np.empty_like(angle)
        prev[0] = self._prev_angle
        prev[1:] = angle[:-1]
        step = np.mod(angle - prev, Q6_PER_TURN)
        before = prev.copy()
        if before[0] < 0:
            before[0] = self.builder.last_angle
        ok: npt.NDArray[np.bool_] = (((step >= 1) & (step <= self.max_step_q6)) | (prev < 0)) & (
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
        self._prev_span = -1
        self._run = 0
        self._locked = False
        self._prev_angle = -1
        self.builder.mark_incomplete()

    # -- capsules ------------------------------------------------------------------------
    def _aligned_capsules(
        self, buf: U8Array, pos: int, limit: int, now_s: float, out: list[Scan]
    ) -> tuple[int, bool, bool]:
        """Decode up to ``limit`` aligned capsules at ``pos``: (new pos, more, all good)."""
        size = self.frame_bytes
        k = min((buf.shape[0] - pos) // size, limit)
        if k == 0:
            return pos, False, True
        raw = buf[pos : pos + k * size].reshape(k, size)
        start = _start_q6(raw)
        good = capsule_validity(raw) & (start < Q6_PER_TURN)
        j = k if bool(np.all(good)) else int(np.argmin(good))
        if j:
            self._decode_run(raw[:j], start[:j], now_s, out)
            self.counters.frames_ok += j
        if j == k:
            end = pos + k * size
            return end, buf.shape[0] - end >= size, True
        self._reject()
        self.counters.bytes_discarded += 1
        return pos + j * size + 1, True, False

    def _decode_run(self, raw: U8Array, start: I64Array, now_s: float, out: list[Scan]) -> None:
        """Decode consecutive valid capsules (after the held one); a pair whose span is
        rejected gives no beams and leaves the revolution incomplete."""
        starts = start.tolist()
        if self._held is not None:
            raw = np.concatenate((self._held[None], raw))
            starts.insert(0, self._held_start)
        self._held = raw[-1].copy()
        self._held_start = starts[-1]
        if raw.shape[0] < 2:
            return
        accept = self._accept_spans([(b - a) % Q6_PER_TURN for a, b in itertools.pairwise(starts)])
        decode = decode_express_pairs if self.mode == "express" else decode_ultra_pairs
        nodes = decode(raw)
        if all(accept):
            out.extend(self.builder.add(nodes.angle_q6, nodes.distance_q2, None, None, now_s))
            return
        per = len(nodes) // len(accept)
        # Runs of equal acceptance, in wire order: beams of accepted runs go to the builder,
        # a rejected run marks the revolution incomplete where its beams would have been.
        lo = 0
        for hi in range(1, len(accept) + 1):
            if hi < len(accept) and accept[hi] == accept[lo]:
                continue
            if accept[lo]:
                angle = nodes.angle_q6[lo * per : hi * per]
                dist = nodes.distance_q2[lo * per : hi * per]
                out.extend(self.builder.add(angle, dist, None, None, now_s))
            else:
                self.builder.mark_incomplete()
            lo = hi

    def _agrees(self, span: int, ref: int) -> bool:
        return abs(span - ref) <= ref * SPAN_TOLERANCE + SPAN_SLACK_Q6

    def _accept_spans(self, spans: list[int]) -> list[bool]:
        """Which capsule pairs have a span (1/64 degree between start angles) that agrees with
        the last accepted one or, while none is known, ends a run of ``LEARN_SPANS``
        consecutive agreeing spans (SR-DRV-2). A few dozen spans per call: plain ints."""
        accept = []
        for span in spans:
            if not 0 < span <= self.max_span_q6:
                agree = False
            elif self._ref_span >= 0:
                agree = self._agrees(span, self._ref_span)
            else:
                follows = self._prev_span >= 0 and self._agrees(span, self._prev_span)
                self._run = self._run + 1 if follows else 1
                agree = self._run >= LEARN_SPANS
            accept.append(agree)
            if agree:
                self._ref_span = span
                self._misses = 0
            elif self._ref_span >= 0:
                # A capsule missing, repeated or swapped before this one: a frame lost.
                self.counters.frames_rejected += 1
                self._misses += 1
                if self._misses >= SPAN_MISSES_TO_RELEARN:
                    self._ref_span = -1
                    self._run = 1
                    self._misses = 0
            self._prev_span = span
        return accept

    # -- re-synchronisation --------------------------------------------------------------
    def _search(self, buf: U8Array, pos: int) -> tuple[int, bool]:
        """Find the first offset where frames check again; discard the bytes before it.

        Examines a window of offsets that doubles while nothing is found, so the work is
        linear in the bytes it moves past."""
        size = self.frame_bytes
        need = size * (LOCK_NODES if self.mode == "standard" else 2)
        window = FIRST_SEARCH_BYTES
        while True:
            avail = buf.shape[0] - pos
            if avail < need:
                return pos, False
            last = min(avail - need + 1, window)
            view = buf[pos : pos + last + need - 1]
            ok = (
                self._node_candidates(view, last)
                if self.mode == "standard"
                else self._capsule_candidates(view, last)
            )
            if bool(np.any(ok)):
                found = int(np.argmax(ok))
                self.counters.bytes_discarded += found
                self._locked = True
                self._prev_angle = -1
                self._held = None
                return pos + found, True
            self.counters.bytes_discarded += last
            pos += last
            window *= 2

    def _node_candidates(self, view: U8Array, last: int) -> npt.NDArray[np.bool_]:
        """Offsets ``q < last`` where ``LOCK_NODES`` nodes in a row pass their checks."""
        size = NODE_BYTES
        windows = sliding_window_view(view, NODE_BYTES)
        valid = node_validity(windows)
        angle = (windows[:, 1].astype(np.int64) >> 1) | (windows[:, 2].astype(np.int64) << 7)
        start = (windows[:, 0] & 1).astype(np.bool_)
        ok: npt.NDArray[np.bool_] = valid[:last].copy()
        before = self.builder.last_angle
        if before >= 0:
            ok &= ~start[:last] | (angle[:last] < before)
        for i in range(1, LOCK_NODES):
            here = slice(i * size, i * size + last)
            previous = angle[(i - 1) * size :][:last]
            ok &= ~start[here] | (angle[here] < previous)
            step = np.mod(angle[here] - previous, Q6_PER_TURN)
            ok &= valid[here] & (step >= 1) & (step <= self.max_step_q6)
        return ok

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


def _start_q6(raw: U8Array) -> I64Array:
    """Start angles (1/64 degree, 15 bits) of ``(k, L)`` capsule bytes."""
    start: I64Array = raw[:, 2].astype(np.int64) | ((raw[:, 3].astype(np.int64) & 0x7F) << 8)
    return start
