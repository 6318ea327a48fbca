"""The simulated sensors in closed loop with the robot moving (SR-FUS-9, campaigns): a reversing
tug with LiDAR alone against LiDAR + radar, and people at night with LiDAR alone against LiDAR +
thermal.

**Reversal.** The named scenario ``reversing_tug_fog`` (a tug ahead in the robot's lane drives
away, brakes to rest and reverses towards the robot), in clear air (``--weather``; in the
scenario's own fog the LiDAR's backscatter holds the robot at rest from its first cycles, so
nothing would be measured while moving), run in closed loop by the runtime twice per seed: with
the LiDAR alone (``runtime.sim_sensors = []``) and with the simulated radar beside it
(``["radar"]``, :mod:`pipeline.sources.sim.sensors_source`: at its own ``radar.rate_hz``, each
frame's returns from its newest scan), the chain running the radar's front-end with the robot's
pose and twist. Each run decides its own commands, so the two runs of
a seed part once the radar changes a decision; the frames are counted from each run's own true
reversal. The reversal counts as detected at the first cycle, at or after the first cycle at
which the tug's true velocity towards the robot exceeds :data:`THRESHOLD_MPS` ("true"), at which

* **track**: the track nearest the tug's true centre (within :data:`GATE_M`) after fusion (the
  tracker's state plus that cycle's radar Doppler update, in the run with radar) moves towards
  the robot faster than :data:`THRESHOLD_MPS`;
* **radar**: (run with radar) one of the radar returns kept by the front-end within
  :data:`GATE_M` of the tug has a compensated Doppler (its own radial speed) below
  ``-THRESHOLD_MPS``: the radar itself has seen it, whether or not a track took it.

Per run also: contacts while moving, the closest approach [m], the progress along the route [m],
the robot's speed at the true reversal [m/s] and the cycles with a radar return matched to a
track.

**People at night** (:func:`walker_run`): ``night_fog_walker_behind_tug`` in the given weathers,
LiDAR alone and with the thermal camera; per person the range at which they were first seen and
the recall over the cycles they stood in the camera's view.

``python -m properties.sensors_loop_study [--seeds N]`` prints the two tables
docs/findings/sensors.md shows.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.config import SafecaseConfig, load_config, overridden
from pipeline.sensors.radar import RadarFrontEnd
from pipeline.sources.sim.sensors_source import SensorsSource, sensors_beside
from pipeline.sources.sim.simulation import BOUNDED
from pipeline.sources.sim.source import SimSource
from pipeline.sources.sim.weather import WEATHER_PRESETS
from pipeline.sources.sim.weather_scenarios import weather_simulation
from safety.cycle import CycleInput, CycleOutput
from safety.run import contact_speeds, run, run_simulation
from safety.runtime import Runtime

__all__ = [
    "GATE_M",
    "HEADER",
    "THRESHOLD_MPS",
    "WALKER_HEADER",
    "ReversalRun",
    "WalkerRun",
    "main",
    "reversal_run",
    "table",
    "walker_run",
    "walker_table",
]

THRESHOLD_MPS = 0.3
"""Speed towards the robot that counts as reversing [m/s] (as the open-loop study,
properties/test_radar_reversal.py)."""
GATE_M = 2.0
"""How near the tug's true centre a track or a radar return must be to count as it [m]."""


@dataclass(frozen=True, slots=True)
class ReversalRun:
    """One closed-loop run (module docstring); frames are 10 Hz cycles, None: never."""

    seed: int
    radar: bool
    true_frame: int | None
    track_frame: int | None
    radar_frame: int | None
    moving_contacts: int
    closest_m: float
    progress_m: float
    cycles: int
    radar_matched_cycles: int
    speed_at_reversal_mps: float


def _first(frames: list[int], after: int | None) -> int | None:
    return None if after is None else next((f for f in frames if f >= after), None)


def reversal_run(
    base: SafecaseConfig, seed: int, radar: bool, weather: str = "clear", duration_s: float = 9.0
) -> ReversalRun:
    """Run seed ``seed`` of ``reversing_tug_fog`` in ``weather``, with or without the radar."""
    config = overridden(base, {"runtime": {"sim_sensors": ["radar"] if radar else []}})
    sim = weather_simulation(config, "reversing_tug_fog", seed, duration_s, weather)
    sim.retain(BOUNDED)
    tug = sim.world.objects[0].trajectory
    front = RadarFrontEnd(config)
    true_f: list[int] = []
    track_f: list[int] = []
    radar_f: list[int] = []
    matched = [0]
    k = [0]
    stamps: dict[int, float] = {}

    def observe(inp: CycleInput, out: CycleOutput) -> None:
        i = k[0]
        k[0] += 1
        perceived = None if out.detail is None else out.detail.perceived
        if inp.scan is None:
            return
        stamps[i] = inp.scan.stamp_s
        at = tug.at(np.array([inp.scan.stamp_s]))
        centre = np.array([at["x_m"][0], at["y_m"][0]])
        towards = np.array(inp.robot_pose[:2]) - centre
        towards /= max(float(np.hypot(*towards)), 1e-9)  # unit vector from the tug to the robot
        if float(towards @ np.array([at["vx_mps"][0], at["vy_mps"][0]])) > THRESHOLD_MPS:
            true_f.append(i)
        if perceived is None:
            return
        matched[0] += perceived.fused.counts.n_radar_matched > 0
        tracks = perceived.fused.tracks
        if tracks.n:
            d = np.hypot(tracks.state[:, 0] - centre[0], tracks.state[:, 1] - centre[1])
            near = int(np.argmin(d))
            if d[near] <= GATE_M and float(towards @ tracks.state[near, 2:]) > THRESHOLD_MPS:
                track_f.append(i)
        if inp.radar is not None and inp.twist is not None:
            kept, _ = front.filter(inp.radar, inp.robot_pose, None)
            framed = front.in_tracking_frame(inp.radar, kept, inp.robot_pose, inp.twist, 0.0)
            own = np.hypot(framed.x_m - centre[0], framed.y_m - centre[1]) <= GATE_M
            if own.any() and float(framed.radial_velocity_mps[own].min()) < -THRESHOLD_MPS:
                radar_f.append(i)

    summary = run_simulation(config, sim, runtime=Runtime(config), observe=observe)
    result = summary.sim
    assert result is not None  # run_simulation sets it
    speeds = contact_speeds(result)
    start = true_f[0] if true_f else None
    # The robot's own speed at the reversal, from the simulator's log (the LiDAR-only frames
    # carry no twist).
    log = result.ego_log
    speed = math.nan
    if start is not None:
        speed = float(np.interp(stamps[start], log["t_s"], log["speed_mps"]))
    return ReversalRun(
        seed,
        radar,
        start,
        _first(track_f, start),
        _first(radar_f, start) if radar else None,
        int(np.count_nonzero(speeds > 0.0)),
        float(np.min(result.min_separation_m, initial=math.inf)),
        float(result.ego_log["arc_m"][-1]),
        summary.cycles,
        matched[0],
        speed,
    )


HEADER = [
    "seed",
    "true (LiDAR / +radar)",
    "track (LiDAR / +radar)",
    "radar Doppler",
    "track lead [frames]",
    "radar lead [frames]",
    "contacts moving",
    "closest [m]",
    "progress [m]",
    "robot speed at reversal [m/s]",
]


def _lead(lidar: ReversalRun, detected: int | None, start: int | None) -> str:
    """Frames by which a detection (counted from its run's true reversal ``start``) comes
    before the LiDAR-only track's (from its own); '-' when either never came."""
    if detected is None or start is None or lidar.track_frame is None or lidar.true_frame is None:
        return "-"
    return str((lidar.track_frame - lidar.true_frame) - (detected - start))


def _f(frame: int | None) -> str:
    return "never" if frame is None else str(frame)


def table(runs: list[ReversalRun]) -> list[list[str]]:
    """One row per seed (columns :data:`HEADER`): LiDAR only / LiDAR + radar."""
    by = {(r.seed, r.radar): r for r in runs}
    rows = []
    for seed in sorted({r.seed for r in runs}):
        a, b = by[(seed, False)], by[(seed, True)]
        rows.append(
            [
                str(seed),
                f"{_f(a.true_frame)} / {_f(b.true_frame)}",
                f"{_f(a.track_frame)} / {_f(b.track_frame)}",
                _f(b.radar_frame),
                _lead(a, b.track_frame, b.true_frame),
                _lead(a, b.radar_frame, b.true_frame),
                f"{a.moving_contacts} / {b.moving_contacts}",
                f"{a.closest_m:.2f} / {b.closest_m:.2f}",
                f"{a.progress_m:.1f} / {b.progress_m:.1f}",
                f"{a.speed_at_reversal_mps:.2f} / {b.speed_at_reversal_mps:.2f}",
            ]
        )
    return rows


WALKER_IDS = {2: "walker", 3: "agent ahead"}
"""The people of ``night_fog_walker_behind_tug``: the walker stepping out from behind the tug and
the agent standing at the road's edge 28-32 m ahead."""
SEEN_M = 1.0
"""How near a person's true centre a track must be to count as them [m]; a thermal-only
pedestrian within ``max(SEEN_M, 0.1 * range)`` (its ground position is less certain far away,
SR-FUS-6)."""


@dataclass(frozen=True, slots=True)
class WalkerRun:
    """One closed-loop run of ``night_fog_walker_behind_tug`` (LiDAR only or with the camera):
    per person, the range [m] from the robot at which they were first seen (NaN: never) and
    the share of the cycles, in which they stood in the camera's field of view within
    :data:`VIEW_M`, that saw them; contacts while moving, the closest approach to the walker
    [m] and the progress [m]."""

    seed: int
    weather: str
    thermal: bool
    first_seen_m: dict[str, float]
    recall: dict[str, float]
    moving_contacts: int
    closest_walker_m: float
    progress_m: float


VIEW_M = 40.0
"""Farthest range at which a person counts towards the recall [m]."""


def walker_run(
    base: SafecaseConfig, seed: int, thermal: bool, weather: str, duration_s: float = 12.0
) -> WalkerRun:
    """Run seed ``seed`` of ``night_fog_walker_behind_tug`` in ``weather`` (a preset), with or
    without the thermal camera (which sees that weather)."""
    config = overridden(base, {"runtime": {"sim_sensors": ["thermal"] if thermal else []}})
    sim = weather_simulation(config, "night_fog_walker_behind_tug", seed, duration_s, weather)
    people = {o.object_id: o.trajectory for o in sim.world.objects if o.object_id in WALKER_IDS}
    half_fov = 0.5 * math.radians(config.thermal.hfov_deg)
    first: dict[str, float] = dict.fromkeys(WALKER_IDS.values(), math.nan)
    shown: dict[str, int] = dict.fromkeys(WALKER_IDS.values(), 0)
    hits: dict[str, int] = dict.fromkeys(WALKER_IDS.values(), 0)

    def observe(inp: CycleInput, out: CycleOutput) -> None:
        perceived = None if out.detail is None else out.detail.perceived
        if inp.scan is None or perceived is None:
            return
        fused = perceived.fused
        x, y, yaw = inp.robot_pose
        for oid, trajectory in people.items():
            name = WALKER_IDS[oid]
            at = trajectory.at(np.array([inp.scan.stamp_s]))
            px, py = float(at["x_m"][0]), float(at["y_m"][0])
            rng = math.hypot(px - x, py - y)
            bearing = math.remainder(math.atan2(py - y, px - x) - yaw, 2 * math.pi)
            near = np.hypot(fused.tracks.state[:, 0] - px, fused.tracks.state[:, 1] - py)
            seen = bool(np.any(near <= SEEN_M))
            gate = max(SEEN_M, 0.1 * rng)
            ped = np.hypot(fused.pedestrian_x_m - px, fused.pedestrian_y_m - py)
            seen |= bool(np.any(ped <= gate))
            if seen and math.isnan(first[name]):
                first[name] = rng
            if abs(bearing) <= half_fov and rng <= VIEW_M:
                shown[name] += 1
                hits[name] += seen

    source: SimSource | SensorsSource = SimSource(sim)
    if thermal:
        source = sensors_beside(config, sim, ["thermal"], weather=WEATHER_PRESETS[weather])
    for _ in run(config, source, Runtime(config), observe=observe):
        pass
    result = source.result()
    speeds = contact_speeds(result)
    walker = next(k for k, o in enumerate(sim.world.objects) if o.object_id == 2)
    return WalkerRun(
        seed,
        weather,
        thermal,
        first,
        {k: (hits[k] / shown[k] if shown[k] else math.nan) for k in shown},
        int(np.count_nonzero(speeds > 0.0)),
        float(result.min_separation_m[walker]),
        float(result.ego_log["arc_m"][-1]),
    )


WALKER_HEADER = [
    "weather",
    "seed",
    "walker first seen at [m] (LiDAR / +thermal)",
    "walker recall",
    "agent ahead first seen at [m]",
    "agent ahead recall",
    "contacts moving",
    "closest to walker [m]",
    "progress [m]",
]


def _pair(a: WalkerRun, b: WalkerRun, get: Callable[[WalkerRun], float], fmt: str) -> str:
    return f"{format(get(a), fmt)} / {format(get(b), fmt)}"


def walker_table(runs: list[WalkerRun]) -> list[list[str]]:
    """One row per weather and seed (columns :data:`WALKER_HEADER`): LiDAR only / + thermal."""
    by = {(r.weather, r.seed, r.thermal): r for r in runs}
    rows = []
    for weather, seed in sorted({(r.weather, r.seed) for r in runs}):
        a, b = by[(weather, seed, False)], by[(weather, seed, True)]
        rows.append(
            [
                weather,
                str(seed),
                _pair(a, b, lambda r: r.first_seen_m["walker"], ".1f"),
                _pair(a, b, lambda r: r.recall["walker"], ".2f"),
                _pair(a, b, lambda r: r.first_seen_m["agent ahead"], ".1f"),
                _pair(a, b, lambda r: r.recall["agent ahead"], ".2f"),
                f"{a.moving_contacts} / {b.moving_contacts}",
                _pair(a, b, lambda r: r.closest_walker_m, ".2f"),
                _pair(a, b, lambda r: r.progress_m, ".1f"),
            ]
        )
    return rows


def _print(header: list[str], rows: list[list[str]]) -> None:
    print("| " + " | ".join(header) + " |")
    print("|" + "---:|" * len(header))
    for row in rows:
        print("| " + " | ".join(row) + " |")


def main() -> None:
    """Print the study's two tables for seeds 0..N-1."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--weather", default="clear")
    parser.add_argument("--walker-weather", nargs="*", default=["night", "night_fog"])
    parser.add_argument("--config", help="TOML file overriding the built-in configuration")
    args = parser.parse_args()
    base = load_config(args.config)
    runs = [
        reversal_run(base, s, radar, args.weather)
        for s in range(args.seeds)
        for radar in (False, True)
    ]
    _print(HEADER, table(runs))
    matched = [r.radar_matched_cycles for r in runs if r.radar]
    print(f"\ncycles with a radar return matched to a track (runs with radar): {matched}\n")
    walkers = [
        walker_run(base, s, thermal, weather)
        for weather in args.walker_weather
        for s in range(args.seeds)
        for thermal in (False, True)
    ]
    _print(WALKER_HEADER, walker_table(walkers))


if __name__ == "__main__":
    main()
