"""Turning a stream of decoded beams into one :class:`Scan` per revolution (SR-DRV-2).

Shared by the RPLIDAR stream decoders. Policy on rejected frames (the issue leaves the
choice to us): a revolution that lost beams to a rejected frame, or whose start was lost, is
emitted with ``complete=False`` and *only* the beams that came from frames which passed their
checks (policy ``"mark"``, the default: downstream sees every trustworthy beam and knows a
sector is missing), or withheld and counted (policy ``"drop"``). A beam from a rejected frame
is never emitted and never patched. The partial revolution before the first start of a turn
(after connecting or re-synchronising) is withheld and counted as dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from pipeline.sources.serial.rplidar import q6_to_angles
from pipeline.types import Scan

__all__ = ["IncompletePolicy", "LinkCounters", "RevolutionBuilder"]

IncompletePolicy = Literal["mark", "drop"]
# A device sweeps one way: within a revolution the angle never falls by more than an express
# node's compensation (dtheta below 8 degrees). A larger fall starts a new revolution, also
# after a gap that swallowed the wrap, so one scan never holds a sector twice.
BACKWARD_CUT_Q6 = 16 * 64
I64Array = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(slots=True)
class LinkCounters:
    """Running totals of one link (mutable; :class:`~pipeline.types.DriverHealth` snapshots
    them). ``frames_rejected`` counts frames that failed a checksum, check bit or plausibility
    check; ``bytes_discarded`` bytes skipped while searching for the next frame."""

    frames_ok: int = 0
    frames_rejected: int = 0
    bytes_discarded: int = 0
    scans_emitted: int = 0
    scans_incomplete: int = 0
    scans_dropped: int = 0


class RevolutionBuilder:
    """Accumulates committed beams and cuts them into revolutions.

    A revolution ends where a beam carries the start flag or the angle falls back by more
    than :data:`BACKWARD_CUT_Q6` (the wrap past 360 degrees, or a gap that swallowed it).
    ``max_beams`` bounds the work per revolution: a revolution that grows
    beyond it (a device that never wraps) is cut and emitted incomplete.
    """

    def __init__(
        self,
        counters: LinkCounters,
        *,
        source: str,
        policy: IncompletePolicy = "mark",
        max_beams: int = 8192,
        with_quality: bool = True,
    ) -> None:
        self.counters = counters
        self.source = source
        self.policy = policy
        self.max_beams = max_beams
        self.with_quality = with_quality
        self._chunks: list[tuple[I64Array, I64Array, I64Array | None]] = []
        self._n = 0
        self._stamp_s = 0.0
        self._started = False  # the current revolution began at a start of turn
        self._incomplete = False
        self._last_angle = -1
        self._gap = False
        self._seq = 0

    @property
    def last_angle(self) -> int:
        """Angle (1/64 degree) of the last committed beam; -1 when none since a reset."""
        return self._last_angle

    def reset(self) -> None:
        """Forget the revolution in progress (after a reconnect): it will be dropped."""
        if self._n:
            self.counters.scans_dropped += 1
        self._chunks.clear()
        self._n = 0
        self._started = False
        self._incomplete = False
        self._gap = False
        self._last_angle = -1

    def mark_incomplete(self) -> None:
        """Beams were lost to a rejected frame: the revolution in progress is incomplete, and
        so is the next one if it begins right after the gap at an angle wrap (its first
        beams may be among the lost ones; a start flag proves they are not)."""
        self._incomplete = True
        self._gap = True

    def add(
        self,
        angle_q6: I64Array,
        distance_q2: I64Array,
        quality: I64Array | None,
        start: BoolArray | None,
        stamp_s: float,
    ) -> list[Scan]:
        """Append committed beams (all from frames that passed their checks); return the
        revolutions they complete. ``stamp_s`` is the host time these beams were read."""
        n = int(angle_q6.shape[0])
        if n == 0:
            return []
        prev = np.empty(n, dtype=np.int64)
        prev[0] = self._last_angle
        prev[1:] = angle_q6[:-1]
        wrap = (angle_q6 < prev - BACKWARD_CUT_Q6) & (prev >= 0)
        cut = wrap | start if start is not None else wrap
        gap_wrap = self._gap and bool(wrap[0]) and not (start is not None and bool(start[0]))
        self._gap = False
        self._last_angle = int(angle_q6[-1])
        out: list[Scan] = []
        begin = 0
        for index in np.flatnonzero(cut).tolist():
            self._append(angle_q6, distance_q2, quality, begin, index, stamp_s)
            out.extend(self._emit(stamp_s))
            self._started = True
            self._incomplete = gap_wrap and index == 0
            begin = index
        self._append(angle_q6, distance_q2, quality, begin, n, stamp_s)
        while self._n > self.max_beams:
            self._incomplete = True
            out.extend(self._emit(stamp_s, limit=self.max_beams))
        return out

    def _append(
        self,
        angle: I64Array,
        dist: I64Array,
        quality: I64Array | None,
        begin: int,
        end: int,
        stamp_s: float,
    ) -> None:
        if end <= begin:
            return
        if self._n == 0:
            self._stamp_s = stamp_s
        q = quality[begin:end] if (quality is not None and self.with_quality) else None
        self._chunks.append((angle[begin:end], dist[begin:end], q))
        self._n += end - begin

    def _emit(self, next_stamp_s: float, limit: int | None = None) -> list[Scan]:
        if self._n == 0:
            self._incomplete = False
            return []
        angle = np.concatenate([c[0] for c in self._chunks])
        dist = np.concatenate([c[1] for c in self._chunks])
        quality = (
            np.concatenate([c[2] for c in self._chunks if c[2] is not None])
            if self.with_quality and all(c[2] is not None for c in self._chunks)
            else None
        )
        stamp_s, started, incomplete = self._stamp_s, self._started, self._incomplete
        rest: tuple[I64Array, I64Array, I64Array | None] | None = None
        if limit is not None:
            rest = (angle[limit:], dist[limit:], None if quality is None else quality[limit:])
            angle, dist = angle[:limit], dist[:limit]
            quality = None if quality is None else quality[:limit]
        self._chunks.clear()
        self._n = 0
        self._incomplete = False
        self._started = False
        if rest is not None and rest[0].shape[0]:
            self._chunks.append(rest)
            self._n = int(rest[0].shape[0])
            self._stamp_s = next_stamp_s
        if not started or (incomplete and self.policy == "drop"):
            self.counters.scans_dropped += 1
            return []
        ranges = dist.astype(np.float64) / 4000.0
        ranges[dist == 0] = np.nan
        n = int(angle.shape[0])
        period = max(0.0, (next_stamp_s - stamp_s) / n) if limit is None else 0.0
        scan = Scan(
            stamp_s=stamp_s,
            angles_rad=q6_to_angles(angle),
            ranges_m=ranges,
            intensities=None if quality is None else quality.astype(np.float64),
            beam_period_s=period,
            seq=self._seq,
            source=self.source,
            complete=not incomplete,
        )
        self._seq += 1
        self.counters.scans_emitted += 1
        self.counters.scans_incomplete += int(incomplete)
        return [scan]
