"""When the simulated thermal camera and radar capture, and a capture re-expressed at a LiDAR
scan's stamp (SR-FUS-9, SR-SIM-7, SR-SIM-8).

**Clocks.** Each sensor runs on its own clock (:class:`SensorClock`): it captures at
``phase_s + k / rate_hz`` (k = 0, 1, ...) on the simulated clock, the camera at
``thermal.rate_hz`` (30 Hz), the radar at ``radar.rate_hz`` (20 Hz). The phase is not
configured: it is drawn uniformly in ``[0, 1 / rate_hz)`` as the first draw of the sensor's own
seeded generator (:meth:`SensorClock.drawn`), since a real sensor's shutter or chirp is not
aligned with the LiDAR's revolution; the seed reproduces it and the seeds vary it. A sensor
captures nothing before its phase (it has not published yet). For a scan stamped ``t`` a sensor
gives its newest capture at or before ``t`` (:meth:`SensorClock.newest`), as a real integration
consumes the latest message: its age at ``t`` lies in ``[0, 1 / rate_hz)``.

**Re-expression.** The chain expects thermal and radar in the robot frame at the scan's stamp
(:meth:`pipeline.perception.Perception.perceive` moves them into the tracking frame with the
frame's pose), and the radar's front-end takes the robot's own motion out of the Doppler with
the frame's twist, the robot's velocity at that stamp
(:meth:`pipeline.sensors.radar.RadarFrontEnd.in_tracking_frame`). A capture taken at another
instant is re-expressed the way a ROS integration does with tf2 and odometry, from the simulated
odometry's poses and twists at both instants:

* thermal detections (:func:`thermal_at_scan`): each position moved by the rigid transform from
  the robot frame at the capture to the robot frame at the scan's stamp;
* radar returns (:func:`radar_at_scan`): each range unchanged, the mount moved to where the radar
  stood at the capture (in the frame at the scan's stamp), the bearings turned by the robot's
  change of heading, so each return lies where it was seen; the Doppler is re-referenced from the
  radar's own velocity at the capture to the one the front-end takes out (the scan's twist at
  the moved mount), so the front-end's compensation gives the target's own velocity along the
  ray at the capture, exactly.

The stamps stay the capture's (``stamp_s`` of each detection): fusion's freshness guard judges
their true age (SR-FUS-1), its gates take each track to the detection's stamp at the track's
velocity (:mod:`pipeline.fusion`), and the governor grows a thermal-only pedestrian's disc by the
walking speed over its age (:func:`safety.obstacles.pedestrian_regions`). In the closed loop a
capture is at most ``1 / rate_hz`` + one LiDAR revolution + ``runtime.sim_cycle_s`` old at
fusion (camera 0.183 s, radar just below 0.2 s with the defaults: within the default maximum
ages of 0.2 s); a rate whose period exceeds the maximum age less the clock skew is refused when
the configuration loads (:class:`pipeline.config.SafecaseConfig`).

**Not compensated: the objects' own motion during the age** (below ``1 / rate_hz``). A radar
return's position, which updates its track only on a degraded LiDAR, is compared with the track
at the scan's stamp: off by the object's speed times the age, at most ``predict.
max_object_speed_mps`` x 50 ms = 3.5 m/s x 50 ms = 0.18 m (a person at 1.6 m/s: 8 cm, 5 cm in
a 33 ms camera frame). A radar return's Doppler is the target's radial speed at the capture: off
by its acceleration times the age (a tug braking at 4 m/s^2: 0.2 m/s, two Doppler noise
sigmas). Both are well inside the tracker's gates (``track.gate_euclidean_m`` 2 m; the
Mahalanobis gate adds the body's half extent, 0.25 m for a person, to the covariance), so no
match is lost to them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from pipeline.frames import to_child, to_parent
from pipeline.types import FloatArray, Pose, RadarDetections, ThermalDetections
from pipeline.types.sensors import Twist

__all__ = ["SensorClock", "radar_at_scan", "thermal_at_scan"]


@dataclass(frozen=True, slots=True)
class SensorClock:
    """A sensor's capture instants ``phase_s + k / rate_hz`` [s], k = 0, 1, ... (module
    docstring), with ``0 <= phase_s < 1 / rate_hz``."""

    rate_hz: float
    phase_s: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ValueError(f"SensorClock: rate_hz must be finite and > 0, got {self.rate_hz}")
        if not 0.0 <= self.phase_s < 1.0 / self.rate_hz:
            raise ValueError(
                f"SensorClock: phase_s must lie in [0, {1.0 / self.rate_hz}), got {self.phase_s}"
            )

    @staticmethod
    def drawn(rate_hz: float, rng: np.random.Generator) -> SensorClock:
        """The clock at ``rate_hz`` with a phase drawn uniformly in ``[0, 1 / rate_hz)`` from
        ``rng`` (one draw: the sensor's own generator, so the seed reproduces it)."""
        period_s = 1.0 / rate_hz
        phase_s = float(rng.uniform(0.0, period_s))
        return SensorClock(rate_hz, min(phase_s, math.nextafter(period_s, 0.0)))

    def instant_s(self, k: int) -> float:
        """The ``k``-th capture instant [s]."""
        return self.phase_s + k / self.rate_hz

    def newest(self, t_s: float) -> int | None:
        """The index of the newest capture at or before ``t_s`` [s] (never one after it); None
        before the first."""
        k = math.floor((t_s - self.phase_s) * self.rate_hz)
        if self.instant_s(k) > t_s:  # the product rounded up across an instant
            k -= 1
        elif self.instant_s(k + 1) <= t_s:  # or down
            k += 1
        return None if k < 0 else k


def thermal_at_scan(
    thermal: ThermalDetections, capture_pose: Pose, scan_pose: Pose
) -> ThermalDetections:
    """Detections given in the robot frame at ``capture_pose`` expressed in the robot frame at
    ``scan_pose`` (both world poses); stamps and confidences unchanged (module docstring)."""
    if capture_pose == scan_pose:
        return thermal
    x_m, y_m = to_child(scan_pose, *to_parent(capture_pose, thermal.x_m, thermal.y_m))
    return ThermalDetections(thermal.stamp_s, x_m, y_m, thermal.confidence)


def _mount_along(
    bearing_rad: FloatArray, mount_x_m: float, mount_y_m: float, twist: Twist
) -> FloatArray:
    """The velocity along each ray of a mount at ``(mount_x_m, mount_y_m)`` on a robot moving at
    ``twist`` [m/s], the robot frame's (the front-end's compensation term, SR-FUS-7)."""
    w = twist.yaw_rate_rps
    along: FloatArray = np.cos(bearing_rad) * (twist.vx_mps - w * mount_y_m) + np.sin(
        bearing_rad
    ) * (twist.vy_mps + w * mount_x_m)
    return along


def radar_at_scan(
    radar: RadarDetections,
    capture_pose: Pose,
    capture_twist: Twist,
    scan_pose: Pose,
    scan_twist: Twist,
) -> RadarDetections:
    """Returns given in the robot frame at ``capture_pose`` (the robot moving at
    ``capture_twist``) expressed in the robot frame at ``scan_pose``, their Doppler re-referenced
    for the front-end's compensation with ``scan_twist`` (module docstring); ranges, stamps,
    elevations, RCS and SNR unchanged."""
    if capture_pose == scan_pose and capture_twist == scan_twist:
        return radar
    mount = to_parent(capture_pose, np.array([radar.mount_x_m]), np.array([radar.mount_y_m]))
    mx, my = to_child(scan_pose, *mount)
    mount_x_m, mount_y_m = float(mx[0]), float(my[0])
    bearing = radar.bearing_rad + (capture_pose[2] - scan_pose[2])
    # The target's velocity along the ray relative to the radar, plus the radar's own at the
    # capture, is the target's own; less what the front-end will add back at the scan's stamp.
    own = radar.radial_velocity_mps + _mount_along(
        radar.bearing_rad, radar.mount_x_m, radar.mount_y_m, capture_twist
    )
    rate = own - _mount_along(bearing, mount_x_m, mount_y_m, scan_twist)
    return dataclasses.replace(
        radar,
        bearing_rad=bearing,
        radial_velocity_mps=rate,
        mount_x_m=mount_x_m,
        mount_y_m=mount_y_m,
    )
