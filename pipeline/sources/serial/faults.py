"""Fault injection for the device emulators (requirement SR-DRV-3).

A :class:`FaultInjector` corrupts a device's frames as a bad cable, a noisy line or a
browning-out scanner would: bit flips, dropped bytes, duplicated bytes, bursts of garbage,
partial (truncated) frames, stalls and disconnects. It is driven by a
``numpy.random.Generator`` (reproducible) and logs every fault it injects, with the byte
offset in the stream where it landed, so a test can count faults injected against faults the
driver detected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.compat import StrEnum

__all__ = ["FaultEvent", "FaultInjector", "FaultKind", "FaultPlan", "Injected"]


class FaultKind(StrEnum):
    """What can go wrong on the wire."""

    BIT_FLIP = "bit_flip"
    DROP_BYTE = "drop_byte"
    DUPLICATE_BYTE = "duplicate_byte"
    GARBAGE = "garbage"
    PARTIAL_FRAME = "partial_frame"
    STALL = "stall"
    DISCONNECT = "disconnect"


BYTE_FAULTS = (
    FaultKind.BIT_FLIP,
    FaultKind.DROP_BYTE,
    FaultKind.DUPLICATE_BYTE,
    FaultKind.GARBAGE,
    FaultKind.PARTIAL_FRAME,
)


@dataclass(frozen=True, slots=True)
class FaultPlan:
    """Probability per frame of each fault, and the fault sizes.

    ``garbage_bytes`` bounds a burst's length; ``stall_s`` and ``disconnect_s`` are how long
    the device goes quiet or away.
    """

    rates: dict[FaultKind, float] = field(default_factory=dict)
    garbage_bytes: int = 64
    stall_s: float = 1.0
    disconnect_s: float = 0.5

    def __post_init__(self) -> None:
        for kind, rate in self.rates.items():
            if not 0.0 <= rate <= 1.0:
                raise ValueError(f"FaultPlan: rate of {kind} is {rate}, expected 0..1")
        if sum(self.rates.values()) > 1.0:
            raise ValueError(f"FaultPlan: rates sum to {sum(self.rates.values())} > 1")
        if self.garbage_bytes < 1 or self.stall_s < 0 or self.disconnect_s < 0:
            raise ValueError("FaultPlan: garbage_bytes >= 1, stall_s and disconnect_s >= 0")


@dataclass(frozen=True, slots=True)
class FaultEvent:
    """One injected fault: its kind, the frame it hit and the stream offset where it lands."""

    kind: FaultKind
    frame: int
    offset: int


@dataclass(frozen=True, slots=True)
class Injected:
    """The (possibly corrupted) bytes of a frame and any timing fault to act out after it."""

    data: bytes
    events: tuple[FaultEvent, ...] = ()
    stall_s: float = 0.0
    disconnect_s: float = 0.0


class FaultInjector:
    """Applies at most one fault per frame, drawn from ``plan`` with ``rng``."""

    def __init__(self, plan: FaultPlan, rng: np.random.Generator) -> None:
        self.plan = plan
        self.rng = rng
        self.frame = 0
        self.offset = 0
        self.log: list[FaultEvent] = []
        kinds = list(plan.rates)
        self._kinds = kinds
        self._cumulative = np.cumsum([plan.rates[k] for k in kinds]) if kinds else np.zeros(0)

    def counts(self) -> dict[str, int]:
        """How many faults of each kind were injected so far."""
        out = {kind.value: 0 for kind in FaultKind}
        for event in self.log:
            out[event.kind.value] += 1
        return out

    def apply(self, frame: bytes) -> Injected:
        """Pass one frame through; maybe corrupt it (or act out a timing fault after it)."""
        kind: FaultKind | None = None
        if self._kinds:
            draw = float(self.rng.random())
            index = int(np.searchsorted(self._cumulative, draw, side="right"))
            if index < len(self._kinds):
                kind = self._kinds[index]
        result = inject(kind, frame, self.rng, self.plan) if kind else Injected(frame)
        if kind is not None:
            event = FaultEvent(kind, self.frame, self.offset + _where(kind, result, frame))
            self.log.append(event)
            result = Injected(result.data, (event,), result.stall_s, result.disconnect_s)
        self.frame += 1
        self.offset += len(result.data)
        return result


def _where(kind: FaultKind, result: Injected, frame: bytes) -> int:
    """Offset within the frame where the fault shows (first differing byte)."""
    for i, (a, b) in enumerate(zip(result.data, frame, strict=False)):
        if a != b:
            return i
    return min(len(result.data), len(frame))


def inject(kind: FaultKind, frame: bytes, rng: np.random.Generator, plan: FaultPlan) -> Injected:
    """``frame`` with one fault of ``kind`` (pure apart from ``rng``)."""
    data = bytearray(frame)
    n = len(data)
    if kind is FaultKind.BIT_FLIP and n:
        position = int(rng.integers(n))
        data[position] ^= 1 << int(rng.integers(8))
    elif kind is FaultKind.DROP_BYTE and n:
        del data[int(rng.integers(n))]
    elif kind is FaultKind.DUPLICATE_BYTE and n:
        position = int(rng.integers(n))
        data.insert(position, data[position])
    elif kind is FaultKind.GARBAGE:
        burst = rng.integers(0, 256, int(rng.integers(1, plan.garbage_bytes + 1)), dtype=np.uint8)
        data = bytearray(burst.tobytes()) + data
    elif kind is FaultKind.PARTIAL_FRAME and n > 1:
        data = data[: int(rng.integers(1, n))]
    elif kind is FaultKind.STALL:
        return Injected(bytes(data), stall_s=plan.stall_s)
    elif kind is FaultKind.DISCONNECT:
        return Injected(bytes(data), disconnect_s=plan.disconnect_s)
    return Injected(bytes(data))
