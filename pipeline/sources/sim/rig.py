"""The simulated robot as the configuration equips it: which sensors a closed-loop run has.

:func:`sim_source` is the one place that turns a :class:`~pipeline.sources.sim.simulation.
Simulation` into the frame source a run reads (``safecase run``, :func:`safety.run.run_simulation`
and so every campaign): the LiDAR alone, with a second scanner (``scan2.enabled``,
:class:`~pipeline.sources.sim.second_lidar.SecondLidarSource`, SR-LID-1) and with the simulated
thermal camera and radar (``runtime.sim_sensors``,
:func:`~pipeline.sources.sim.sensors_source.sensors_beside`, SR-FUS-9). Each added sensor draws
from its own generator seeded by the run's seed alone, so the LiDAR's scans are the same bits
whatever the rig.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.sources.sim.scenarios import lidar_spec_from_config
from pipeline.sources.sim.second_lidar import SecondLidarSource
from pipeline.sources.sim.sensors_source import sensors_beside
from pipeline.sources.sim.simulation import Simulation
from pipeline.sources.sim.source import SimSource, SimSourceBeside

__all__ = ["sim_source"]

# Spawn key of the second scanner's noise.
SECOND_LIDAR_STREAM = 251


def sim_source(
    config: SafecaseConfig, sim: Simulation, *, outages: Sequence[tuple[float, float]] = ()
) -> SimSource | SimSourceBeside:
    """``sim`` in closed loop as the configuration's robot sees it: with a second scanner
    (:class:`SecondLidarSource`, the ``sim`` section's scanner model at ``scan2.mount_*``, noise
    seeded by the run's seed alone) when ``scan2.enabled``, and with the simulated sensors
    ``runtime.sim_sensors`` beside it (:func:`~pipeline.sources.sim.sensors_source.
    sensors_beside`, SR-FUS-9); else the plain source."""
    source: SimSource | SimSourceBeside = SimSource(sim)
    second = config.scan2
    if second.enabled:
        mount = (second.mount_x_m, second.mount_y_m, second.mount_yaw_rad)
        rng = np.random.default_rng([sim.seed, SECOND_LIDAR_STREAM])
        spec = lidar_spec_from_config(config)
        source = SecondLidarSource(source, spec, mount, rng, outages=outages)
    if config.runtime.sim_sensors:
        source = sensors_beside(config, sim, config.runtime.sim_sensors, upstream=source)
    return source
