"""The stamp rule for recorded logs: a tracker needs a clock that moves forward (SR-TRK-3).

A log is usable only when its scan stamps are finite, non-zero, strictly increasing and never
step by more than ``max_step_s`` (default 60 s: a pause in recording longer than that is a new
run, not a gap to coast over). Constant stamps, zero stamps, stamps going backwards and jumps by
hours are refused at the source with :class:`LogStampError`, which names the file, the scan and
the first bad stamp; the user may ask for re-stamping at a given rate instead
(:func:`restamp`), which keeps the first stamp and spaces the others evenly. The runtime and
the real-log checks use this same rule.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from pipeline.errors import SafecaseError
from pipeline.types import FloatArray

__all__ = ["DEFAULT_MAX_STEP_S", "LogStampError", "StampRule", "check_stamps", "restamp"]

DEFAULT_MAX_STEP_S = 60.0


class LogStampError(SafecaseError, ValueError):
    """A log whose scan stamps a tracker cannot use (constant, zero, backwards, jumping)."""


@dataclass(frozen=True)
class StampRule:
    """How a log's stamps are taken: checked as recorded (``restamp_hz`` None) or replaced by
    ``first + i / restamp_hz``; ``max_step_s`` is the largest step allowed between scans [s]."""

    restamp_hz: float | None = None
    max_step_s: float = DEFAULT_MAX_STEP_S

    def __post_init__(self) -> None:
        if self.restamp_hz is not None and not (
            math.isfinite(self.restamp_hz) and 0.0 < self.restamp_hz <= 1000.0
        ):
            raise ValueError(f"restamp rate {self.restamp_hz!r} Hz: allowed: 0 < rate <= 1000")
        if not (math.isfinite(self.max_step_s) and self.max_step_s > 0.0):
            raise ValueError(f"max_step_s {self.max_step_s!r}: allowed: a finite number > 0")

    def apply(self, stamps_s: Iterable[float], file: str) -> FloatArray:
        """The stamps to use for the log's scans, in order (checked or re-stamped)."""
        raw = np.fromiter(stamps_s, dtype=np.float64)
        if self.restamp_hz is not None:
            return restamp(raw, self.restamp_hz, file)
        check_stamps(raw, file, self.max_step_s)
        return raw


def check_stamps(stamps_s: FloatArray, file: str, max_step_s: float = DEFAULT_MAX_STEP_S) -> None:
    """Refuse stamps a tracker cannot use, naming ``file``, the scan and the first bad stamp."""
    hint = "; re-stamp the log at its scan rate (safecase run --log FILE --restamp HZ)"
    for i, stamp in enumerate(stamps_s.tolist()):
        if not math.isfinite(stamp) or stamp == 0.0:
            raise LogStampError(f"{file}: scan {i} is stamped {stamp!r}: not a usable time{hint}")
        if i == 0:
            continue
        step = stamp - float(stamps_s[i - 1])
        if step <= 0.0:
            what = "the same as" if step == 0.0 else f"{-step:.6g} s before"
            raise LogStampError(
                f"{file}: scan {i} is stamped {stamp!r}, {what} scan {i - 1}: stamps must "
                f"increase{hint}"
            )
        if step > max_step_s:
            raise LogStampError(
                f"{file}: scan {i} is stamped {stamp!r}, {step:.6g} s after scan {i - 1}: "
                f"more than {max_step_s:g} s between scans{hint}"
            )


def restamp(stamps_s: FloatArray, rate_hz: float, file: str) -> FloatArray:
    """``first + i / rate_hz`` for every scan; the first stamp must itself be finite."""
    if stamps_s.shape[0] == 0:
        return stamps_s
    first = float(stamps_s[0])
    if not math.isfinite(first):
        raise LogStampError(f"{file}: scan 0 is stamped {first!r}: cannot re-stamp from it")
    out: FloatArray = first + np.arange(stamps_s.shape[0]) / rate_hz
    return out
