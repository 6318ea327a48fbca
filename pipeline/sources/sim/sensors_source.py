"""The simulated thermal camera and radar run beside the simulator, into the frames (SR-FUS-9).

:class:`SensorsSource` sits beside a closed-loop simulator
(:class:`~pipeline.sources.sim.source.SimSourceBeside`): for each frame it takes the robot's
pose at the scan's stamp (the frame's, exact in simulation) and its velocity there
(:func:`ego_twist`), and

* renders the LWIR frame the camera captures at that stamp
  (:class:`~pipeline.sources.sim.thermal_camera.ThermalRenderer`, in the run's weather) and runs
  the thermal detector on it (:class:`~pipeline.sensors.thermal.ThermalDetector`, SR-FUS-5): the
  frame's ``thermal`` are its detections, none from a contaminated frame;
* scans the radar at that stamp (:class:`~pipeline.sources.sim.radar.SimRadar`, SR-SIM-8): the
  frame's ``radar`` are its raw returns in the robot frame, for the perception chain's radar
  front-end to filter, compensate and gate;
* puts the robot's velocity into the frame (``twist``), which the front-end needs while the
  robot moves.

Each sensor draws from its own generator, seeded from the run's seed alone
(:func:`sensors_beside`), so the LiDAR's streams are the same bits with or without them. The
camera and the radar scan once per LiDAR revolution, at its stamp (10 Hz, not their own 30 and
20 Hz). What the sensors did in the newest frame is kept in :attr:`SensorsSource.last` (the
detector's and the radar's truth, for measurements); nothing grows with the run.
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
from pipeline.sources.sim.simulation import Simulation
from pipeline.sources.sim.source import SimSource, SimSourceBeside
from pipeline.sources.sim.thermal_camera import ThermalRenderer
from pipeline.sources.sim.weather import WEATHER_PRESETS, Weather
from pipeline.sources.sim.weather_scenarios import WEATHER_SCENARIOS
from pipeline.types import FloatArray, Frame, IntArray, RadarDetections
from pipeline.types.sensors import Twist

__all__ = ["SensorsReport", "SensorsSource", "ego_twist", "radar_spec", "sensors_beside"]

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
class SensorsReport:
    """What the sensors did for one frame: the detector's result (None without the camera),
    the radar's raw returns and each one's truth (object id, ghost or clutter; None without the
    radar), and the robot's twist."""

    stamp_s: float
    thermal: ThermalResult | None
    radar: RadarDetections | None
    radar_truth: IntArray | None
    twist: Twist


class SensorsSource(SimSourceBeside):
    """``upstream``'s frames with the thermal camera's detections, the radar's returns and the
    robot's twist added (module docstring). ``camera`` (a renderer and its detector) and
    ``radar`` may each be None (that sensor is absent); ``reflectors_m`` are the world's mapped
    radar reflectors ``(k, 4)``, world frame."""

    def __init__(
        self,
        upstream: SimSource | SimSourceBeside,
        camera: tuple[ThermalRenderer, ThermalDetector] | None,
        radar: SimRadar | None,
        *,
        reflectors_m: FloatArray | None = None,
    ) -> None:
        super().__init__(upstream)
        self.camera = camera
        self.radar = radar
        self.reflectors_m = reflectors_m
        self.last: SensorsReport | None = None

    def frames(self) -> Iterator[Frame]:
        """The upstream source's frames, each with what the sensors saw at its scan's stamp."""
        sim = self.inner.sim
        for frame in self.upstream.frames():
            if frame.scan is None or frame.pose is None:
                yield frame
                continue
            stamp, pose = frame.scan.stamp_s, frame.pose
            twist = ego_twist(sim.ego, stamp)
            found = None
            if self.camera is not None:
                renderer, detector = self.camera
                found = detector.detect(renderer.render(stamp, pose))
            returns = truth = None
            if self.radar is not None:
                returns, truth = self.radar.scan(sim.world, stamp, pose, twist, self.reflectors_m)
            self.last = SensorsReport(stamp, found, returns, truth, twist)
            yield dataclasses.replace(
                frame,
                thermal=None if found is None else found.detections,
                radar=returns,
                twist=twist,
            )


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
    calibration error) and its detector, the radar of :func:`radar_spec`. The camera sees
    ``weather`` (default: the weather scenario's preset when ``sim`` is one of
    :data:`~pipeline.sources.sim.weather_scenarios.WEATHER_SCENARIOS`, else clear air). Their
    noise is seeded by the run's seed and the sensor's stream key alone."""
    source = SimSource(sim) if upstream is None else upstream
    if (source if isinstance(source, SimSource) else source.inner).sim is not sim:
        raise ValueError("sensors_beside: upstream must run the same simulation")
    if weather is None:
        preset = WEATHER_SCENARIOS[sim.name][1] if sim.name in WEATHER_SCENARIOS else "clear"
        weather = WEATHER_PRESETS[preset]
    camera = None
    if "thermal" in sensors:
        t = config.thermal
        rng = np.random.default_rng([sim.seed, THERMAL_STREAM])
        renderer = ThermalRenderer(sim.world, weather, PinholeCamera.from_config(t), t.netd_c, rng)
        camera = (renderer, ThermalDetector(t))
    radar = None
    if "radar" in sensors:
        radar = SimRadar(radar_spec(config), np.random.default_rng([sim.seed, RADAR_STREAM]))
    return SensorsSource(source, camera, radar)
