"""Arrays, scans and commands: the two ends of the data path."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


def frozen_array(
    values: npt.ArrayLike, dtype: type[np.generic] = np.float64
) -> npt.NDArray[np.generic]:
    """A read-only, C-contiguous copy of ``values`` with the given dtype."""
    array = np.array(values, dtype=dtype, copy=True, order="C")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, slots=True)
class Scan:
    """One revolution of a 2D range scanner, whatever produced it (SR-DRV-*, SR-SIM-*).

    ``angles_rad`` and ``ranges_m`` have one entry per beam, in the scanner frame
    (counter-clockwise, 0 rad straight ahead). A beam with no return has range NaN; the
    sanitation stage drops and counts such beams, it never guesses. ``stamp_s`` is the time of
    the first beam; beam ``i`` was taken at ``stamp_s + i * beam_period_s``. ``complete`` is
    False when the driver had to drop rejected frames from this revolution (the beams that
    came from them are absent, never patched).
    """

    stamp_s: float
    angles_rad: FloatArray
    ranges_m: FloatArray
    intensities: FloatArray | None = None
    beam_period_s: float = 0.0
    seq: int = 0
    source: str = ""
    complete: bool = True

    def __post_init__(self) -> None:
        angles = frozen_array(self.angles_rad)
        ranges = frozen_array(self.ranges_m)
        if angles.ndim != 1 or ranges.shape != angles.shape:
            raise ValueError(
                f"Scan: angles_rad shape {angles.shape} and ranges_m shape {ranges.shape} "
                "must be equal and one-dimensional"
            )
        if not np.all(np.isfinite(angles)):
            raise ValueError("Scan: angles_rad must be finite")
        object.__setattr__(self, "angles_rad", angles)
        object.__setattr__(self, "ranges_m", ranges)
        if self.intensities is not None:
            intensities = frozen_array(self.intensities)
            if intensities.shape != angles.shape:
                raise ValueError(
                    f"Scan: intensities shape {intensities.shape} must equal "
                    f"angles_rad shape {angles.shape}"
                )
            object.__setattr__(self, "intensities", intensities)
        if not np.isfinite(self.stamp_s):
            raise ValueError(f"Scan: stamp_s must be finite, got {self.stamp_s!r}")
        if not (np.isfinite(self.beam_period_s) and self.beam_period_s >= 0.0):
            raise ValueError(f"Scan: beam_period_s must be >= 0, got {self.beam_period_s!r}")

    @property
    def n_beams(self) -> int:
        """Number of beams in this revolution."""
        return int(self.angles_rad.shape[0])


class Action(enum.Enum):
    """The governor's decision (SR-STOP-*)."""

    PROCEED = "PROCEED"
    SLOW = "SLOW"
    STOP = "STOP"


@dataclass(frozen=True, slots=True)
class Command:
    """What the safety layer tells the drive, with every reason that shaped it.

    ``speed_mps`` is the commanded speed limit (0 for STOP). ``reasons`` is never empty for
    SLOW or STOP: fail-safe stops record why (stale input, missed deadline, bad config, ...).
    """

    action: Action
    speed_mps: float
    stamp_s: float
    reasons: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.speed_mps) and self.speed_mps >= 0.0):
            raise ValueError(f"Command: speed_mps must be finite and >= 0, got {self.speed_mps}")
        if self.action is Action.STOP and self.speed_mps != 0.0:
            raise ValueError(f"Command: STOP must have speed_mps 0, got {self.speed_mps}")
        if self.action is not Action.PROCEED and not self.reasons:
            raise ValueError(f"Command: {self.action.value} needs at least one reason")


def freeze_fields(obj: object, names: tuple[str, ...], dtype: type[np.generic]) -> None:
    """Replace each named field of a frozen dataclass by a read-only array of ``dtype``."""
    for name in names:
        object.__setattr__(obj, name, frozen_array(getattr(obj, name), dtype))
