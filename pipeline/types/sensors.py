"""What the sensor front-ends read besides detections (SR-FUS-5..7, SR-SIM-7).

A :class:`ThermalImage` is what the simulated camera (:mod:`pipeline.sources.sim.
thermal_camera`) renders and the thermal front-end (:mod:`pipeline.sensors.thermal`) reads; a
:class:`Twist`, the robot's velocity from odometry, is what the radar front-end
(:mod:`pipeline.sensors.radar`) needs to take the robot's own motion out of the Doppler.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["ThermalImage", "Twist"]

Float32Array = npt.NDArray[np.float32]


@dataclass(frozen=True, slots=True)
class ThermalImage:
    """One LWIR frame: apparent temperature [deg C] of each pixel, ``(height, width)``, row 0
    at the top; ``stamp_s`` its capture time on the sensor clock. A NaN pixel is a dead one."""

    stamp_s: float
    pixels_c: Float32Array

    def __post_init__(self) -> None:
        pixels = np.array(self.pixels_c, dtype=np.float32, copy=True, order="C")
        if pixels.ndim != 2 or min(pixels.shape) < 3:
            raise ValueError(
                f"ThermalImage: pixels_c must be 2-D and at least 3 x 3, got {pixels.shape}"
            )
        pixels.setflags(write=False)
        object.__setattr__(self, "pixels_c", pixels)

    @property
    def shape(self) -> tuple[int, int]:
        """``(height_px, width_px)``."""
        return int(self.pixels_c.shape[0]), int(self.pixels_c.shape[1])


@dataclass(frozen=True, slots=True)
class Twist:
    """The robot's velocity from odometry at the scan's stamp, in the robot frame: forward and
    leftward speed [m/s] and yaw rate [rad/s] (counter-clockwise)."""

    vx_mps: float
    vy_mps: float
    yaw_rate_rps: float

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.vx_mps, self.vy_mps, self.yaw_rate_rps)):
            raise ValueError(f"Twist: every component must be finite, got {self}")
