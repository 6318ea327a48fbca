"""Pedestrian recall by range in fog and at night: the LiDAR alone against LiDAR + thermal
(SR-FUS-5, a measurement; open loop, one frame per placement).

A person stands at a range of 5-40 m ahead of the robot (lateral offset and facing drawn per
seed) on an empty apron. The LiDAR (the configured scanner, degraded by the weather) counts as
seeing them when at least ``cluster.min_points`` of its returns lie on the person (true returns,
not backscatter); the thermal camera when its detector reports a detection within the ground
bound of the calibration plus 0.5 m of the person. Recall is the share of placements seen.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from evidence.profiles import certifying
from pipeline.config import SafecaseConfig
from pipeline.sensors.camera import PinholeCamera
from pipeline.sensors.thermal import ThermalDetector
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.lidar import Lidar, ScannerPoses
from pipeline.sources.sim.objects import person
from pipeline.sources.sim.scenarios import lidar_spec_from_config
from pipeline.sources.sim.shapes import rectangle
from pipeline.sources.sim.thermal_camera import ThermalRenderer
from pipeline.sources.sim.weather import WEATHER_PRESETS, weather_lidar
from pipeline.sources.sim.world import SimObject, Structure, World
from pipeline.types import FloatArray

CODE = ["pipeline/sensors/thermal.py", "pipeline/sources/sim/weather.py"]
RANGES_M = (5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0)
WEATHERS = ("night", "fog", "night_fog", "rain")


def _still(pose: tuple[float, float, float]) -> ScannerPoses:
    def poses(t: FloatArray) -> FloatArray:
        return np.tile(np.array(pose), (np.atleast_1d(t).shape[0], 1))

    return poses


def _world(x_m: float, y_m: float, heading_rad: float) -> World:
    # One cone far behind the robot: the apron is otherwise empty.
    structure = Structure.from_parts([("cone", rectangle(-60.2, -59.8, -0.2, 0.2))])
    walker = SimObject(
        1, "walker", person(), mo.integrate(mo.stationary(), x_m, y_m, heading_rad, 1.0)
    )
    return World("recall", structure, (walker,), (-61.0, 45.0, -10.0, 10.0), "apron")


@pytest.mark.requirement("SR-FUS-5", kind="measurement", code=CODE)
def test_pedestrian_recall_lidar_against_thermal(
    safecase_config: SafecaseConfig, evidence: Any
) -> None:
    t = safecase_config.thermal
    seeds = 20 if certifying() else 5
    cam = PinholeCamera.from_config(t)
    detector = ThermalDetector(t)
    dt, da = t.calibration_translation_m, math.radians(t.calibration_angle_deg)
    base = lidar_spec_from_config(safecase_config)
    need = safecase_config.cluster.min_points
    rows = []
    recall: dict[tuple[str, float], tuple[float, float]] = {}
    for name in WEATHERS:
        weather = WEATHER_PRESETS[name]
        spec = weather_lidar(base, weather)
        for r in RANGES_M:
            seen_lidar = seen_both = 0
            for seed in range(seeds):
                rng = np.random.default_rng([seed, int(r), WEATHERS.index(name)])
                y = float(rng.uniform(-2.0, 2.0))
                world = _world(r, y, float(rng.uniform(-math.pi, math.pi)))
                scan, beams = Lidar(spec, rng).scan(world, _still((0.0, 0.0, 0.0)), 0.0)
                on = (beams.owner_id == 1) & np.isfinite(scan.ranges_m)
                on &= np.abs(scan.ranges_m - beams.true_range_m) < 0.3
                lidar_sees = int(np.count_nonzero(on)) >= need
                frame = ThermalRenderer(world, weather, cam, t.netd_c, rng).render(
                    0.0, (0.0, 0.0, 0.0)
                )
                found = detector.detect(frame)
                u, v, _ = cam.project(np.array([r]), np.array([y]), np.zeros(1))
                bound = float(cam.ground_error_bound_m(u, v, dt, da)[0])
                gap = np.hypot(found.detections.x_m - r, found.detections.y_m - y)
                thermal_sees = bool(gap.shape[0]) and float(gap.min()) <= bound + 0.5
                seen_lidar += lidar_sees
                seen_both += lidar_sees or thermal_sees
            recall[(name, r)] = (seen_lidar / seeds, seen_both / seeds)
            rows.append([name, r, round(spec.attenuated_max_range_m, 1),
                         seen_lidar / seeds, seen_both / seeds])  # fmt: skip
    evidence.table(
        f"pedestrian recall by range, {seeds} placements each (one frame, open loop)",
        ["weather", "range [m]", "LiDAR reach [m]", "recall LiDAR", "recall LiDAR + thermal"],
        rows,
    )
    # What the figure is for: beyond the LiDAR's reach (fog) or resolution (a person's two
    # shins at night) the thermal camera still finds the person.
    for where in (("night", 20.0), ("fog", 15.0)):
        assert recall[where][0] == 0.0, where
        assert recall[where][1] > 0.0, where
