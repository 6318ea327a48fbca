"""The simulated thermal camera and radar beside the closed-loop simulator (SR-FUS-9): chosen
by ``runtime.sim_sensors``, each from its own seeded stream (the LiDAR's bits unchanged), and
their detections fused in the runtime's cycles."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.sources.sim.rig import sim_source
from pipeline.sources.sim.second_lidar import SecondLidarSource
from pipeline.sources.sim.sensors_source import SensorsSource, sensors_beside
from pipeline.sources.sim.source import SimSource
from pipeline.sources.sim.weather import WEATHER_PRESETS
from pipeline.sources.sim.weather_scenarios import weather_simulation
from pipeline.types import Frame
from safety.run import run
from safety.runtime import Runtime

CODE = ["pipeline/sources/sim/sensors_source.py", "pipeline/sources/sim/second_lidar.py"]
SENSORS = overridden(default_config(), {"runtime": {"sim_sensors": ["thermal", "radar"]}})


def _frames(config_sensors: bool, seed: int = 3, scan2: bool = False) -> list[Frame]:
    config = SENSORS if config_sensors else default_config()
    if scan2:
        config = overridden(config, {"scan2": {"enabled": True}})
    sim = weather_simulation(config, "night_fog_walker_behind_tug", seed, 1.05, "night")
    return list(sim_source(config, sim).frames())


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_the_switch_picks_the_source_and_leaves_the_lidar_streams_alone() -> None:
    plain = weather_simulation(default_config(), "reversing_tug_fog", 0, 0.5)
    assert type(sim_source(default_config(), plain)) is SimSource
    both = overridden(SENSORS, {"scan2": {"enabled": True}})
    source = sim_source(both, weather_simulation(both, "reversing_tug_fog", 0, 0.5))
    assert isinstance(source, SensorsSource)
    assert isinstance(source.upstream, SecondLidarSource)
    without, with_sensors = _frames(False), _frames(True)
    assert len(without) == len(with_sensors) == 10
    for i, (a, b) in enumerate(zip(without, with_sensors, strict=True)):
        assert a.scan is not None
        assert b.scan is not None
        np.testing.assert_array_equal(a.scan.ranges_m, b.scan.ranges_m)
        assert a.pose == b.pose
        assert a.radar is None
        assert b.twist is not None
        if i:  # the sensors' first captures come after the first scan's stamp (their phases)
            assert b.radar is not None
            assert b.thermal is not None
    for a, b in zip(_frames(True, scan2=True)[1:], with_sensors[1:], strict=True):
        assert a.second is not None
        assert a.radar is not None
        assert b.radar is not None
        np.testing.assert_array_equal(a.radar.range_m, b.radar.range_m)


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_the_sensors_reproduce_from_the_seed_and_differ_between_seeds() -> None:
    one, again, other = _frames(True, 3)[1:], _frames(True, 3)[1:], _frames(True, 4)[1:]
    for a, b in zip(one, again, strict=True):
        assert a.radar is not None and b.radar is not None  # noqa: PT018
        assert a.thermal is not None and b.thermal is not None  # noqa: PT018
        np.testing.assert_array_equal(a.radar.radial_velocity_mps, b.radar.radial_velocity_mps)
        np.testing.assert_array_equal(a.thermal.x_m, b.thermal.x_m)
    assert one[-1].radar is not None and other[-1].radar is not None  # noqa: PT018
    assert not np.array_equal(one[-1].radar.range_m, other[-1].radar.range_m)


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_the_runtime_fuses_what_the_camera_and_the_radar_found() -> None:
    # The scenario in clear night air: a simulation does not carry its weather, so a run in
    # other weather than the scenario's own gives the camera that weather.
    sim = weather_simulation(SENSORS, "night_fog_walker_behind_tug", 1, 6.0, "night")
    source = sensors_beside(SENSORS, sim, ["thermal", "radar"], weather=WEATHER_PRESETS["night"])
    totals: dict[str, float] = {}
    before = 0
    for out in run(SENSORS, source, Runtime(SENSORS)):
        assert not any(r.startswith("stage:") for r in out.command.reasons), out.command.reasons
        part = out.record.inputs["fusion"]
        if "n_radar_returns" not in part:  # before the radar's first scan (its phase)
            before += 1
            continue

        # Every raw radar return is accounted for: dropped by the front-end by reason, or kept
        # and then stale, unmatched or matched in fusion.
        dropped = ("dropped_invalid", "low_rcs", "low_snr", "clutter", "ghost")
        kept = sum(part[f"n_radar_{k}"] for k in dropped) + part["n_radar"]
        assert kept == part["n_radar_returns"], part
        for key, value in part.items():
            totals[key] = totals.get(key, 0) + value
    assert before <= 1, before  # the first cycle at most
    # At night in clear air the camera sees the people (one at 28-32 m, beyond the LiDAR's
    # clusters: thermal-only) and the radar the idling tug beside the lane.
    assert totals["n_thermal"] > 0, totals
    assert totals["n_thermal_only"] > 0, totals
    assert totals["n_radar_matched"] > 0, totals
    assert totals["n_radar_clutter"] > 0, totals  # the simulated ground clutter, filtered
