"""Named apron scenarios in fog and at night, where one LiDAR is not enough (SR-SIM-6).

Builders ``(rng, duration_s) -> (world, route)`` with the weather each is set in
(:data:`WEATHER_SCENARIOS`); :func:`weather_simulation` runs one with the configured scanner
degraded by that weather (:func:`pipeline.sources.sim.weather.weather_lidar`). They are kept
apart from :data:`pipeline.sources.sim.scenarios.SCENARIOS` (clear air) so that the clear-air
campaigns stay what they are. Both are on the apron stand (:func:`pipeline.sources.sim.layouts.
apron_stand`), the robot starting at (2, -1.2) on the service road facing +x.

* ``night_fog_walker_behind_tug``: night, fog of 40 m visibility (the LiDAR reaches about
  10.6 m). A baggage tug stands in the next lane with its engine running (hot exhaust); a
  ramp agent hidden behind it walks out across the robot's lane when the robot is a few metres
  short; a second agent stands at the road's edge 28-32 m ahead, beyond the LiDAR's reach.
* ``reversing_tug_fog``: fog of 60 m visibility. A tug ahead in the robot's lane drives away,
  brakes to rest within 0.4-0.6 s and reverses towards the robot at 1.0-1.5 m/s.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import Route
from pipeline.sources.sim.layouts import apron_stand
from pipeline.sources.sim.objects import baggage_tug, person
from pipeline.sources.sim.scenarios import (
    ScenarioError,
    ScenarioSpec,
    lidar_spec_from_config,
    place,
    simulation_for_spec,
)
from pipeline.sources.sim.simulation import FULL, Retention, Simulation
from pipeline.sources.sim.weather import WEATHER_PRESETS, weather_lidar
from pipeline.sources.sim.world import SimObject, World

__all__ = ["WEATHER_SCENARIOS", "weather_simulation"]

_LANE_Y = -1.2
_ROUTE = Route(np.array([[2.0, _LANE_Y], [42.0, _LANE_Y]]))


def _world(name: str, objects: list[SimObject]) -> World:
    layout = apron_stand()
    return World(name, layout.structure, tuple(objects), layout.bounds_m, "apron", layout.decor)


Built = tuple[World, Route]


def _spec(world: World) -> Built:
    return world, _ROUTE


def _night_fog_walker_behind_tug(rng: np.random.Generator, duration: float) -> Built:
    # The tug stands in the next lane; seen from the approaching robot, a walker at (17.5, 1.5)
    # lies in the tug's shadow until the robot is level with it (module docstring).
    tug_x = float(rng.uniform(14.5, 15.5))
    tug = place(1, "tug_idling", baggage_tug(), mo.stationary(), (tug_x, 0.6, 0.0), duration)
    speed = float(rng.uniform(1.1, 1.4))
    # The robot (1 m/s from x = 2) is 3-5 m short of the walker's line when they enter its lane.
    walk_x = tug_x + 2.4
    enter_s = (walk_x - 2.0 - 0.45 - float(rng.uniform(3.0, 5.0))) / 1.0
    delay = max(0.5, enter_s - (1.5 - (_LANE_Y + 0.6)) / speed)
    walker = place(
        2,
        "hidden_walker",
        person(),
        mo.accelerate(0.0, speed, delay, 1.5),
        (walk_x, 1.5, -math.pi / 2),
        duration,
    )
    standing = place(
        3,
        "agent_at_road_edge",
        person(),
        mo.stationary(),
        (float(rng.uniform(28.0, 32.0)), -3.4, math.pi / 2),
        duration,
    )
    return _spec(_world("night_fog_walker_behind_tug", [tug, walker, standing]))


def _reversing_tug_fog(rng: np.random.Generator, duration: float) -> Built:
    motion = mo.reversing(
        forward_mps=float(rng.uniform(1.5, 2.0)),
        slow_start_s=float(rng.uniform(2.5, 3.5)),
        slow_s=float(rng.uniform(0.4, 0.6)),
        dwell_s=float(rng.uniform(0.0, 0.3)),
        reverse_mps=float(rng.uniform(1.0, 1.5)),
        reverse_accel_mps2=float(rng.uniform(1.0, 1.5)),
        reverse_s=3.0,
    )
    pose = (float(rng.uniform(10.0, 12.0)), _LANE_Y + float(rng.uniform(-0.2, 0.2)), 0.0)
    tug = place(1, "tug_reversing", baggage_tug(), motion, pose, duration)
    return _spec(_world("reversing_tug_fog", [tug]))


WEATHER_SCENARIOS: dict[str, tuple[str, str, Callable[[np.random.Generator, float], Built]]] = {
    "night_fog_walker_behind_tug": (
        "Apron at night in fog (40 m): a walker hidden behind an idling tug steps into the "
        "robot's lane; another stands at the road's edge beyond the LiDAR's reach.",
        "night_fog",
        _night_fog_walker_behind_tug,
    ),
    "reversing_tug_fog": (
        "Apron in fog (60 m): a tug ahead drives away, stops within half a second and reverses "
        "towards the robot.",
        "fog",
        _reversing_tug_fog,
    ),
}
"""Name -> (description, weather preset of :data:`pipeline.sources.sim.weather.WEATHER_PRESETS`,
builder)."""


def weather_simulation(
    config: SafecaseConfig,
    name: str,
    seed: int,
    duration_s: float,
    weather: str | None = None,
    retention: Retention = FULL,
) -> Simulation:
    """A ready-to-run simulation of weather scenario ``name`` with the configured scanner in the
    scenario's weather (or the preset ``weather``, to compare the same scene in other
    conditions), its streams drawn from ``seed`` as :func:`pipeline.sources.sim.scenarios.
    make_simulation` draws them, keeping ``retention`` for its result (a campaign keeps
    :data:`~pipeline.sources.sim.simulation.BOUNDED`). The simulation carries the preset's name
    (``Simulation.weather``), so the simulated camera beside it sees the same weather
    (:func:`pipeline.sources.sim.sensors_source.sensors_beside`). An unknown name or preset
    raises :class:`pipeline.sources.sim.scenarios.ScenarioError`."""
    if name not in WEATHER_SCENARIOS:
        raise ScenarioError(
            f"unknown weather scenario {name!r}; known: {', '.join(sorted(WEATHER_SCENARIOS))}"
        )
    _, preset, build = WEATHER_SCENARIOS[name]
    preset = preset if weather is None else weather
    if preset not in WEATHER_PRESETS:
        raise ScenarioError(
            f"unknown weather {preset!r}; known: {', '.join(sorted(WEATHER_PRESETS))}"
        )
    scenario_ss = np.random.SeedSequence(seed).spawn(3)[0]
    world, route = build(np.random.default_rng(scenario_ss), duration_s)
    lidar = weather_lidar(lidar_spec_from_config(config), WEATHER_PRESETS[preset])
    spec = ScenarioSpec(world, route)
    return simulation_for_spec(
        config, spec, name, seed, duration_s, lidar, retention, weather=preset
    )
