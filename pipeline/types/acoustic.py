"""Microphone-array audio and the acoustic alert it yields (SR-ACU-1, SR-ACU-3).

An alert is a bearing, never a position: the array hears the direction a reversing beeper or
a horn comes from, not how far away it is, so an alert never becomes an obstacle; the governor
reads it as a reason for caution (:mod:`safety.model.caution`).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from pipeline.types.core import FloatArray, frozen_array

__all__ = ["AcousticAlert", "AlertKind", "AudioClip"]


class AlertKind(enum.Enum):
    """What was heard: a pulsed reversing beeper or a sustained horn."""

    BEEPER = "beeper"
    HORN = "horn"


@dataclass(frozen=True, slots=True)
class AudioClip:
    """``samples`` (n_mics, n) [Pa] of a microphone array, starting at ``stamp_s`` [s].

    ``mic_xy_m`` (n_mics, 2) places each microphone in the robot frame (x forward, y left);
    ``sample_rate_hz`` is the common sample rate. The clip's last sample was taken at
    ``end_s``.
    """

    samples: FloatArray
    sample_rate_hz: float
    stamp_s: float
    mic_xy_m: FloatArray

    def __post_init__(self) -> None:
        samples = frozen_array(np.asarray(self.samples, dtype=np.float64))
        mics = frozen_array(np.asarray(self.mic_xy_m, dtype=np.float64))
        if samples.ndim != 2 or mics.shape != (samples.shape[0], 2) or samples.shape[0] < 2:
            raise ValueError(
                f"AudioClip: samples must be (n_mics >= 2, n) and mic_xy_m (n_mics, 2), got "
                f"{samples.shape} and {mics.shape}"
            )
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0.0):
            raise ValueError(f"AudioClip: sample_rate_hz must be > 0, got {self.sample_rate_hz}")
        if not math.isfinite(self.stamp_s):
            raise ValueError(f"AudioClip: stamp_s must be finite, got {self.stamp_s!r}")
        object.__setattr__(self, "samples", samples)
        object.__setattr__(self, "mic_xy_m", mics)

    @property
    def n_mics(self) -> int:
        """Number of microphones."""
        return int(self.samples.shape[0])

    @property
    def end_s(self) -> float:
        """Time of the last sample [s]."""
        return float(self.stamp_s + (self.samples.shape[1] - 1) / self.sample_rate_hz)


@dataclass(frozen=True, slots=True)
class AcousticAlert:
    """A warning sound heard by the array (SR-ACU-1): ``kind``, the direction it came from,
    ``bearing_rad`` in the robot frame (counter-clockwise from x, in (-pi, pi]), the detector's
    ``confidence`` in [0, 1] (a score, not a calibrated probability) and ``stamp_s``, the time of
    the newest audio it rests on [s]; ``ambiguous`` when another direction fitted as well (the
    bearing may be that one instead). No range: it never places an obstacle."""

    kind: AlertKind
    bearing_rad: float
    confidence: float
    stamp_s: float
    ambiguous: bool = False

    def __post_init__(self) -> None:
        if not math.isfinite(self.bearing_rad):
            raise ValueError(f"AcousticAlert: bearing_rad must be finite, got {self.bearing_rad}")
        if not 0.0 <= self.confidence <= 1.0:
            raise ValueError(f"AcousticAlert: confidence must be in [0, 1], got {self.confidence}")
        if not isinstance(self.kind, AlertKind):
            raise TypeError(f"AcousticAlert: kind must be an AlertKind, got {self.kind!r}")
