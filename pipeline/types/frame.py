"""What a source delivers per cycle: a stamped frame of scan, pose and detections."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.types.acoustic import AcousticAlert
from pipeline.types.core import FloatArray, Scan, frozen_array
from pipeline.types.drivers import DriverHealth
from pipeline.types.fusion import RadarDetections, ThermalDetections
from pipeline.types.sensors import Twist

Pose = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class SecondScan:
    """The second scanner's newest revolution (SR-LID-1): ``scan`` in that scanner's own
    frame (its mount is configured, ``scan2.mount_*``) and ``pose``, the robot's odometry pose
    ``(x_m, y_m, yaw_rad)`` at that scan's stamp, None when the source has no odometry."""

    scan: Scan
    pose: Pose | None = None


@dataclass(frozen=True, slots=True)
class Frame:
    """One cycle's input from a source (:mod:`pipeline.sources`), in the robot frame.

    ``scan`` is the newest revolution, or None when nothing arrived in time (a live source's
    tick, which the monitors turn into STOP). ``received_s`` is when the frame became available
    on the decision clock [s]. ``pose`` places the robot frame in the tracking (odometry) frame
    at the scan's stamp, ``(x_m, y_m, yaw_rad)``; None when the source has no odometry (tracking
    then happens in the robot frame). ``thermal`` and ``radar`` are detections in the robot
    frame; ``health`` is a serial link's state. ``route_m`` (k, 2), when the source knows it, is
    the robot's planned route in the tracking frame and ``route_arc_m`` how far along it the
    robot is at ``received_s``; without it the path ahead is straight along the robot's heading.
    ``acoustic`` is the newest alert of the microphone array (a bearing, never a position), which
    the runtime reads as a reason for caution (SR-ACU-3), or None. ``second`` is a second
    scanner's newest revolution, merged with ``scan`` while it is fresh (SR-LID-1), or None.
    ``twist`` is the robot's velocity from odometry at the scan's stamp (robot frame), which
    the radar's front-end needs to take the robot's own motion out of the Doppler (SR-FUS-9);
    None when the source has no odometry velocity.
    """

    scan: Scan | None
    received_s: float
    pose: Pose | None = None
    thermal: ThermalDetections | None = None
    radar: RadarDetections | None = None
    health: DriverHealth | None = None
    route_m: FloatArray | None = None
    route_arc_m: float = 0.0
    acoustic: AcousticAlert | None = None
    second: SecondScan | None = None
    twist: Twist | None = None

    def __post_init__(self) -> None:
        if not np.isfinite(self.received_s):
            raise ValueError(f"Frame: received_s must be finite, got {self.received_s!r}")
        if self.route_m is not None:
            route = frozen_array(self.route_m)
            if route.ndim != 2 or route.shape[1] != 2 or route.shape[0] < 2:
                raise ValueError(f"Frame: route_m must be (k >= 2, 2), got {route.shape}")
            object.__setattr__(self, "route_m", route)

    @property
    def stamp_s(self) -> float:
        """The scan's stamp, or the time received when there is no scan [s]."""
        return self.received_s if self.scan is None else self.scan.stamp_s
