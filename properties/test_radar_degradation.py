"""The LiDAR degradation index on simulated scans by weather (SR-FUS-7): clear air and night
never reach ``radar.degraded_from`` (the radar's positions stay out of the tracks), on the open
apron nor in a warehouse aisle between racks; fog always does; rain lies between. Seeds 0-2 of
both weather scenarios under ``certify``, one of one under ``ci``; the table is the figure in
docs/findings/sensors.md."""

from __future__ import annotations

import numpy as np
import pytest

from evidence.profiles import by_profile
from evidence.record import current
from pipeline.cluster.dbscan import cluster_scan
from pipeline.config import SafecaseConfig
from pipeline.sensors.radar import degradation_index
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from pipeline.sources.sim.weather_scenarios import weather_simulation
from pipeline.types import NOISE_LABEL
from properties.ahead import ahead

CODE = ["pipeline/sensors/radar.py", "pipeline/perception.py"]
WEATHERS = ("clear", "night", "rain", "heavy_rain", "fog", "night_fog")
# Warehouse aisles between racks: near structure, dense and clustered, must not count.
AISLE = ("reversing_forklift_aisle", "forklift_pass_by", "occlusion_behind_cart")


def _indices(config: SafecaseConfig, name: str, weather: str, seeds: range) -> list[float]:
    """The index of every scan of 6 s of ``name`` in ``weather`` (robot as the scenario sets it;
    ``weather`` "clear (warehouse)": ``name`` is a warehouse scenario, in clear air)."""
    r = config.radar
    found = []
    for seed in seeds:
        if weather == "clear (warehouse)":
            sim = make_simulation(config, name, seed, 6.0)
        else:
            sim = weather_simulation(config, name, seed, 6.0, weather)
        for frame in SimSource(sim).frames():
            if frame.scan is None:
                continue
            points, clusters = cluster_scan(frame.scan, config)
            isolated = clusters.point_labels == NOISE_LABEL
            found.append(
                degradation_index(
                    points.range_m, isolated, r.degraded_within_m, r.degraded_noise_fraction
                )
            )
    return found


@pytest.mark.requirement("SR-FUS-7", kind="measurement", code=CODE)
@ahead
def test_clear_air_never_reaches_the_degraded_threshold_and_fog_always_does(
    safecase_config: SafecaseConfig,
) -> None:
    threshold = safecase_config.radar.degraded_from
    names = by_profile(
        ci=("reversing_tug_fog",), certify=("reversing_tug_fog", "night_fog_walker_behind_tug")
    )
    seeds = range(by_profile(ci=1, certify=3))
    rows = []
    cases = [(name, weather) for name in names for weather in WEATHERS]
    cases += [(name, "clear (warehouse)") for name in by_profile(ci=AISLE[:1], certify=AISLE)]
    for name, weather in cases:
        d = np.array(_indices(safecase_config, name, weather, seeds))
        above = int(np.count_nonzero(d >= threshold))
        median, high = np.percentile(d, [50, 99])
        rows.append([name, weather, d.size, f"{median:.2f}", f"{high:.2f}", above])
        if weather in ("clear", "night", "clear (warehouse)"):
            assert above == 0, (name, weather, d.max())
        if weather in ("fog", "night_fog"):
            assert above == d.size, (name, weather, d.min())
    current().table(
        f"LiDAR degradation index by weather (threshold radar.degraded_from = {threshold})",
        ["scenario", "weather", "scans", "median", "p99", "scans at or above the threshold"],
        rows,
        caption="6 s per seed, robot as the scenario drives it; "
        "pytest properties/test_radar_degradation.py --hypothesis-profile=certify",
    )
