"""How much sooner the radar sees a tug reverse than the LiDAR track does (SR-FUS-7, a
measurement; open loop, robot standing).

The named fog scenario ``reversing_tug_fog``: a tug ahead drives away, stops and reverses
towards the robot. Each LiDAR scan goes through the tracking chain (points, clusters, shapes,
Kalman tracks); the simulated radar scans the same instant and its returns go through the
radar front-end and fusion with the radar gate. The reversal counts as seen at the first frame,
after the tug's true velocity towards the robot passes 0.3 m/s, where:

* LiDAR only: the tug's track moves towards the robot faster than 0.3 m/s;
* radar: the tug's compensated Doppler (its own radial speed) does;
* fused: the tug's track after that cycle's Doppler update does.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from evidence.profiles import certifying
from pipeline.config import SafecaseConfig, overridden
from pipeline.frames import to_child
from pipeline.fusion import fuse
from pipeline.perception import Perception
from pipeline.sensors.radar import RadarFrontEnd, RadarGate
from pipeline.sources.sim.radar import RadarSpec, SimRadar
from pipeline.sources.sim.weather_scenarios import weather_simulation
from pipeline.types import Frame
from pipeline.types.sensors import Twist
from properties.ahead import ahead
from safety.model.freshness import is_fresh

THRESHOLD_MPS = 0.3
CODE = ["pipeline/sensors/radar.py", "pipeline/fusion.py", "pipeline/sources/sim/radar.py"]


def _first(frames: list[int], after: int) -> int | None:
    return next((f for f in frames if f >= after), None)


def _run(config: SafecaseConfig, seed: int, weather: str) -> tuple[int | None, ...]:
    """Frames of the true reversal and of its detection by LiDAR, radar and fused tracks."""
    sim = weather_simulation(config, "reversing_tug_fog", seed, 9.0, weather)
    chain = Perception.from_config(config, guard=is_fresh, tracking_only=True)
    radar = SimRadar(RadarSpec(clutter_per_scan=3.0), np.random.default_rng(seed))
    front = RadarFrontEnd(config)
    gate = RadarGate.from_config(config)
    sim.command(0.0)
    true_f, lidar_f, radar_f, fused_f = [], [], [], []
    k = 0
    while (frame := sim.next_frame()) is not None:
        truth, stamp = frame.truth, frame.scan.stamp_s
        pose = (float(truth.ego_pose[0]), float(truth.ego_pose[1]), float(truth.ego_pose[2]))
        tug = int(np.flatnonzero(truth.object_id == 1)[0])
        tx, ty = to_child(pose, truth.x_m[tug : tug + 1], truth.y_m[tug : tug + 1])
        # Velocity towards the robot: minus the component along the robot-to-tug line.
        los = np.array([tx[0], ty[0]]) / math.hypot(tx[0], ty[0])
        c, s = math.cos(pose[2]), math.sin(pose[2])
        v_robot = np.array([c * truth.vx_mps[tug] + s * truth.vy_mps[tug],
                            -s * truth.vx_mps[tug] + c * truth.vy_mps[tug]])  # fmt: skip
        if -float(los @ v_robot) > THRESHOLD_MPS:
            true_f.append(k)
        tracks = chain.track(Frame(frame.scan, stamp)).tracks
        if tracks.n:
            near = int(np.argmin(np.hypot(tracks.state[:, 0] - tx[0], tracks.state[:, 1] - ty[0])))
            if math.hypot(tracks.state[near, 0] - tx[0], tracks.state[near, 1] - ty[0]) < 2.0:
                if -float(los @ tracks.state[near, 2:]) > THRESHOLD_MPS:
                    lidar_f.append(k)
                returns, ids = radar.scan(sim.world, stamp, pose, Twist(0.0, 0.0, 0.0))
                returns = type(returns)(
                    np.full(returns.n, stamp), returns.range_m, returns.bearing_rad,
                    returns.radial_velocity_mps, returns.mount_x_m, returns.mount_y_m,
                    returns.elevation_rad, returns.rcs_dbsm, returns.snr_db,
                )  # fmt: skip
                kept, _ = front.filter(returns, (0.0, 0.0, 0.0), None)
                framed = front.in_tracking_frame(returns, kept, (0.0, 0.0, 0.0), None, 0.0)
                own = ids[kept] == 1
                if own.any() and float(framed.radial_velocity_mps[own].min()) < -THRESHOLD_MPS:
                    radar_f.append(k)
                fused = fuse(stamp, tracks, config.fusion, guard=is_fresh, radar=framed,
                             radar_gate=gate)  # fmt: skip
                if -float(los @ fused.tracks.state[near, 2:]) > THRESHOLD_MPS:
                    fused_f.append(k)
        k += 1
    if not true_f:
        return (None, None, None, None)
    start = true_f[0]
    return (start, _first(lidar_f, start), _first(radar_f, start), _first(fused_f, start))


@pytest.mark.requirement("SR-FUS-7", kind="measurement", code=CODE)
@ahead
def test_radar_sees_the_reversal_sooner(safecase_config: SafecaseConfig, evidence: Any) -> None:
    bench = overridden(safecase_config, {"sim": {"ego_speed_mps": 0.0}})
    seeds = range(20 if certifying() else 3)
    rows: list[list[object]] = []
    lead: dict[str, list[int]] = {"clear": [], "fog": []}
    for weather in ("clear", "fog"):
        for seed in seeds:
            start, lidar, radar, fused = _run(bench, seed, weather)
            assert start is not None, seed  # the scenario does reverse
            assert radar is not None, seed  # the radar always sees it
            rows.append([weather, seed, start, lidar, radar, fused])
            if lidar is not None:
                lead[weather].append(lidar - radar)
    evidence.table(
        f"reversing_tug_fog, robot standing: frame (10 Hz) at which the reversal "
        f"(> {THRESHOLD_MPS} m/s towards the robot) is seen",
        ["weather", "seed", "true", "LiDAR track", "radar Doppler", "fused track"],
        rows,
    )
    late = sum(n < 0 for n in lead["fog"])
    evidence.note(
        f"Frames by which the radar sees the reversal before the LiDAR track: {lead}; in fog "
        f"the radar was later in {late} of {len(lead['fog'])} runs."
    )
    # In clear air the radar is never later than the LiDAR track. In fog its returns thin out
    # too: it may cross the threshold one frame after the track (seed 3 under certify), never
    # more.
    assert all(n >= 0 for n in lead["clear"])
    assert all(n >= -1 for n in lead["fog"])
    assert lead["clear"]
