"""The simulated thermal camera and radar run beside the simulator, into the frames (SR-FUS-9).

:class:`SensorsSource` sits beside a closed-loop simulator
(:class:`~pipeline.sources.sim.source.SimSourceBeside`). Each sensor runs on its own clock
(:mod:`pipeline.sources.sim.sensor_timing`: the camera at ``thermal.rate_hz``, 30 Hz, the radar
at ``radar.rate_hz``, 20 Hz, each from a phase drawn from its own seeded generator). For each
LiDAR frame, stamped ``t``, each sensor contributes its newest capture at or before ``t``, taken
with the robot's pose and velocity (:func:`ego_twist`) at the capture's instant:

* the camera's LWIR frame rendered then (:class:`~pipeline.sources.sim.thermal_camera.
  ThermalRenderer`, in the run's weather) through the thermal detector
  (:class:`~pipeline.sensors.thermal.ThermalDetector`, SR-FUS-5, SR-SIM-7): the frame's
  ``thermal`` are its detections, none from a contaminated frame;
* the radar's scan then (:class:`~pipeline.sources.sim.radar.SimRadar`, SR-SIM-8): the frame's
  ``radar`` are its raw returns, for the perception chain's radar front-end to filter,
  compensate and gate;

each re-expressed in the robot frame at ``t`` with the odometry's poses at both instants, the
radar's Doppler re-referenced for the front-end's compensation with the frame's twist
(:func:`~pipeline.sources.sim.sensor_timing.thermal_at_scan`,
:func:`~pipeline.sources.sim.sensor_timing.radar_at_scan`: what is and is not compensated),
each detection stamped with its capture's instant; and the frame's ``twist`` is the robot's
velocity at ``t``, which the front-end needs while the robot moves. A frame before a sensor's
first capture gets nothing from it (None). Only a capture that a frame uses is rendered or
scanned, once: a capture serving two frames (a sensor slower than the LiDAR) is kept, so a frame
costs at most one render and one radar scan.

Each sensor draws from its own generator, seeded from the run's seed alone
(:func:`sensors_beside`), so the LiDAR's streams are the same bits with or without them. What the
sensors gave the newest frame is kept in :attr:`SensorsSource.last` (the detector's result and
the radar's truth, for measurements); nothing grows with the run.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.sensors.camera import PinholeCamera
from pipeline.sensors.thermal import ThermalDetector, ThermalResult
from pipeline.sources.sim.ego import Ego
from pipeline.sources.sim.radar import RadarSpec, SimRadar
from pipeline.sources.sim.sensor_timing import SensorClock, radar_at_scan, thermal_at_scan
from pipeline.sources.sim.simulation import Simulation
from pipeline.sources.sim.source import SimSource, SimSourceBeside
from pipeline.sources.sim.thermal_camera import ThermalRenderer
from pipeline.sources.sim.weather import WEATHER_PRESETS, Weather
from pipeline.sources.sim.weather_scenarios import WEATHER_SCENARIOS
from pipeline.types import FloatArray, Frame, IntArray, Pose, RadarDetections
from pipeline.types.sensors import Twist

__all__ = [
    "Capture",
    "SensorsReport",
    "SensorsSource",
    "ego_twist",
    "radar_spec",
    "sensors_beside",
]

Sensor = Literal["thermal", "radar"]

THERMAL_STREAM = 22
"""Spawn key of the camera's noise (airside recommendation #22)."""
RADAR_STREAM = 24
"""Spawn key of the radar's noise (airside recommendation #24)."""


def ego_twist(ego: Ego, stamp_s: float) -> Twist:
    """The simulated robot's velocity at ``stamp_s`` (its odometry, robot frame): forward speed
    from the ego's speed log, no sideways slip, and the yaw rate over the step before ``stamp_s``
    (a route's heading changes only at its vertices; at a run's first instant it is 0)."""
    dt = ego.dt_s
    t = np.array([max(stamp_s - dt, 0.0), stamp_s])
    poses = ego.poses_at(t)
    turn = math.remainder(float(poses[1, 2] - poses[0, 2]), 2.0 * math.pi)
    span = float(t[1] - t[0])
    speed = float(ego.speeds_at(np.array([stamp_s]))[0])
    return Twist(speed, 0.0, turn / span if span > 0.0 else 0.0)


def radar_spec(config: SafecaseConfig) -> RadarSpec:
    """The simulated radar as the configuration describes it: the ``radar`` section's mount
    height and noise, the ``fusion`` section's Doppler noise (mount position, field of view,
    range and clutter: :class:`RadarSpec`'s defaults)."""
    r = config.radar
    return RadarSpec(
        mount_z_m=r.mount_z_m,
        range_std_m=r.range_std_m,
        azimuth_std_rad=math.radians(r.azimuth_std_deg),
        doppler_std_mps=config.fusion.radar_doppler_std_mps,
    )


@dataclass(frozen=True, slots=True)
class Capture:
    """One capture of a sensor: its index ``k`` on the sensor's clock, its instant [s], and the
    robot's pose (world frame) and twist then."""

    k: int
    stamp_s: float
    pose: Pose
    twist: Twist


@dataclass(frozen=True, slots=True)
class SensorsReport:
    """What the sensors gave one frame stamped ``stamp_s``: the capture each sensor's
    contribution came from (None: that sensor absent or not yet captured), the detector's
    result and the radar's raw returns as captured (robot frame at the capture) with each
    return's truth (object id, ghost or clutter), and the robot's twist at ``stamp_s``."""

    stamp_s: float
    thermal_capture: Capture | None
    thermal: ThermalResult | None
    radar_capture: Capture | None
    radar: RadarDetections | None
    radar_truth: IntArray | None
    twist: Twist


class SensorsSource(SimSourceBeside):
    """``upstream``'s frames with the thermal camera's detections, the radar's returns and the
    robot's twist added (module docstring). ``camera`` (a renderer, its detector and the
    camera's clock) and ``radar`` (the radar and its clock) may each be None (that sensor is
    absent); ``reflectors_m`` are the world's mapped radar reflectors ``(k, 4)``, world frame."""

    def __init__(
        self,
        upstream: SimSource | SimSourceBeside,
        camera: tuple[ThermalRenderer, ThermalDetector, SensorClock] | None,
        radar: tuple[SimRadar, SensorClock] | None,
        *,
        reflectors_m: FloatArray | None = None,
    ) -> None:
        super().__init__(upstream)
        self.camera = camera
        self.radar = radar
        self.reflectors_m = reflectors_m
        self.last: SensorsReport | None = None
        self._thermal: tuple[Capture, ThermalResult] | None = None
        self._radar: tuple[Capture, RadarDetections, IntArray] | None = None

    def _capture(self, clock: SensorClock, k: int) -> Capture:
        """Capture ``k`` of ``clock``: its instant and the robot's pose and twist then."""
        ego = self.inner.sim.ego
        t = clock.instant_s(k)
        at = ego.poses_at(np.array([t]))[0]
        return Capture(k, t, (float(at[0]), float(at[1]), float(at[2])), ego_twist(ego, t))

    def _thermal_at(self, stamp_s: float) -> tuple[Capture, ThermalResult] | None:
        """The camera's newest frame at or before ``stamp_s`` through the detector, rendered
        once (None: no camera, or no frame yet)."""
        if self.camera is None:
            return None
        renderer, detector, clock = self.camera
        k = clock.newest(stamp_s)
        if k is None:
            return None
        if self._thermal is None or self._thermal[0].k != k:
            shot = self._capture(clock, k)
            self._thermal = (shot, detector.detect(renderer.render(shot.stamp_s, shot.pose)))
        return self._thermal

    def _radar_at(self, stamp_s: float) -> tuple[Capture, RadarDetections, IntArray] | None:
        """The radar's newest scan at or before ``stamp_s`` and its truth, scanned once (None:
        no radar, or no scan yet)."""
        if self.radar is None:
            return None
        radar, clock = self.radar
        k = clock.newest(stamp_s)
        if k is None:
            return None
        if self._radar is None or self._radar[0].k != k:
            shot = self._capture(clock, k)
            world = self.inner.sim.world
            returns, truth = radar.scan(
                world, shot.stamp_s, shot.pose, shot.twist, self.reflectors_m
            )
            self._radar = (shot, returns, truth)
        return self._radar

    def frames(self) -> Iterator[Frame]:
        """The upstream source's frames, each with the sensors' newest captures at or before
        its scan's stamp, re-expressed at that stamp (module docstring)."""
        sim = self.inner.sim
        for frame in self.upstream.frames():
            if frame.scan is None or frame.pose is None:
                yield frame
                continue
            stamp, pose = frame.scan.stamp_s, frame.pose
            twist = ego_twist(sim.ego, stamp)
            camera = self._thermal_at(stamp)
            thermal = None
            if camera is not None:
                thermal = thermal_at_scan(camera[1].detections, camera[0].pose, pose)
            scanned = self._radar_at(stamp)
            returns = None
            if scanned is not None:
                shot = scanned[0]
                returns = radar_at_scan(scanned[1], shot.pose, shot.twist, pose, twist)
            self.last = SensorsReport(
                stamp,
                None if camera is None else camera[0],
                None if camera is None else camera[1],
                None if scanned is None else scanned[0],
                None if scanned is None else scanned[1],
                None if scanned is None else scanned[2],
                twist,
            )
            yield dataclasses.replace(frame, thermal=thermal, radar=returns, twist=twist)


def sensors_beside(
    config: SafecaseConfig,
    sim: Simulation,
    sensors: Sequence[Sensor],
    *,
    upstream: SimSource | SimSourceBeside | None = None,
    weather: Weather | None = None,
) -> SensorsSource:
    """``sim`` in closed loop (``upstream``, default a plain :class:`SimSource` of ``sim``) with
    the named ``sensors`` beside it: the camera at the ``thermal`` section's extrinsic (no
    calibration error) and its detector, at ``thermal.rate_hz``; the radar of
    :func:`radar_spec`, at ``radar.rate_hz``. The camera sees ``weather`` (default: the preset
    ``sim`` is set in, ``sim.weather``; when that is not stated, the weather scenario's own
    preset when ``sim`` is one of
    :data:`~pipeline.sources.sim.weather_scenarios.WEATHER_SCENARIOS`, else clear air). Each
    sensor's generator is seeded by the run's seed and the sensor's stream key alone; its first
    draw is the sensor's phase (:meth:`SensorClock.drawn`), the rest its noise."""
    source = SimSource(sim) if upstream is None else upstream
    if (source if isinstance(source, SimSource) else source.inner).sim is not sim:
        raise ValueError("sensors_beside: upstream must run the same simulation")
    if weather is None:
        preset = sim.weather
        if preset is None:
            preset = WEATHER_SCENARIOS[sim.name][1] if sim.name in WEATHER_SCENARIOS else "clear"
        weather = WEATHER_PRESETS[preset]
    camera = None
    if "thermal" in sensors:
        t = config.thermal
        rng = np.random.default_rng([sim.seed, THERMAL_STREAM])
        clock = SensorClock.drawn(t.rate_hz, rng)
        renderer = ThermalRenderer(sim.world, weather, PinholeCamera.from_config(t), t.netd_c, rng)
        camera = (renderer, ThermalDetector(t), clock)
    radar = None
    if "radar" in sensors:
        rng = np.random.default_rng([sim.seed, RADAR_STREAM])
        clock = SensorClock.drawn(config.radar.rate_hz, rng)
        radar = (SimRadar(radar_spec(config), rng), clock)
    return SensorsSource(source, camera, radar)
