"""Named, seeded scenarios and the factory that turns one into a :class:`Simulation` (SR-SIM-2).

Each scenario is a builder ``(rng, duration_s) -> ScenarioSpec`` that draws its free
parameters (start gaps, speeds, timings) from the generator it is given; the same seed gives
the same world, bit for bit. :func:`make_simulation` derives three independent streams from
the seed (layout, scanner noise, ego braking) with ``numpy.random.SeedSequence.spawn``.
``random_encounter`` (see :mod:`pipeline.sources.sim.encounters`) is listed here like any other
scenario, so campaigns run it by name with many seeds.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.errors import SafecaseError
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import EgoSpec, Route
from pipeline.sources.sim.layouts import apron_stand, warehouse_aisle
from pipeline.sources.sim.lidar import DEVICE_PRESETS, LidarSpec
from pipeline.sources.sim.objects import (
    ObjectModel,
    amr,
    baggage_tug,
    cart,
    counterbalance_forklift,
    dolly,
    pallet_jack,
    person,
    reach_truck,
    uld_container,
)
from pipeline.sources.sim.simulation import FULL, Retention, Simulation
from pipeline.sources.sim.truth import LabelRules
from pipeline.sources.sim.world import SimObject, World

__all__ = [
    "SCENARIOS",
    "ScenarioError",
    "ScenarioInfo",
    "ScenarioSpec",
    "build_scenario",
    "lidar_spec_from_config",
    "make_simulation",
    "place",
    "simulation_for_spec",
]


class ScenarioError(SafecaseError):
    """An unknown scenario name or a scenario that cannot be built."""


@dataclass(frozen=True)
class ScenarioSpec:
    """A built scenario: the world, the ego's route and (optionally) its start speed."""

    world: World
    route: Route
    initial_speed_mps: float | None = None


Builder = Callable[[np.random.Generator, float], ScenarioSpec]


@dataclass(frozen=True)
class ScenarioInfo:
    """A registered scenario."""

    name: str
    description: str
    environment: str
    builder: Builder


def place(
    object_id: int,
    name: str,
    model: ObjectModel,
    motion: mo.Motion,
    pose: tuple[float, float, float],
    duration_s: float,
) -> SimObject:
    """An object driven by ``motion`` from ``pose`` (x, y, heading) over the run."""
    traj = mo.integrate(motion, pose[0], pose[1], pose[2], duration_s + 0.5)
    return SimObject(object_id, name, model, traj, motion)


def _reversing_forklift_aisle(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    layout = warehouse_aisle(rng, cross_aisles_m=((12.6, 15.6), (24.0, 27.0)))
    gap = float(rng.uniform(5.5, 7.0))
    slow_start = float(rng.uniform(3.0, 4.5))
    objects = [
        place(
            1,
            "forklift",
            counterbalance_forklift(),
            mo.random_reversing(rng, slow_start),
            (gap, float(rng.uniform(-0.2, 0.2)), 0.0),
            duration,
        ),
        place(
            2,
            "reach_truck_parked",
            reach_truck(),
            mo.stationary(),
            (14.1, -4.2, -math.pi / 2),
            duration,
        ),
        place(
            3,
            "walker",
            person(),
            mo.accelerate(0.0, float(rng.uniform(1.1, 1.5)), float(rng.uniform(6.0, 9.0)), 1.5),
            (25.5, -5.0, math.pi / 2),
            duration,
        ),
    ]
    world = World("reversing_forklift_aisle", layout.structure, tuple(objects), layout.bounds_m)
    return ScenarioSpec(world, Route(np.array([[0.0, 0.0], [30.0, 0.0]])))


def _crossing_pedestrian(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    layout = warehouse_aisle(rng, cross_aisles_m=((9.0, 12.0),))
    speed = float(rng.uniform(1.2, 1.6))
    # Timed so the walker reaches the ego's lane when the robot is 1.5-3.5 m short of it.
    ahead = float(rng.uniform(1.5, 3.5))
    start_y = -5.5
    t_reach = (10.5 - 0.45 - ahead) / 1.0
    delay = max(0.5, t_reach - (abs(start_y) - 0.6) / speed - 0.5)
    walker = place(
        1,
        "pedestrian",
        person(),
        mo.accelerate(0.0, speed, delay, 2.0),
        (10.5 + float(rng.uniform(-0.5, 0.5)), start_y, math.pi / 2),
        duration,
    )
    parked = place(2, "cart_parked", cart(), mo.stationary(), (5.0, 1.25, 0.0), duration)
    world = World("crossing_pedestrian", layout.structure, (walker, parked), layout.bounds_m)
    return ScenarioSpec(world, Route(np.array([[0.0, 0.0], [30.0, 0.0]])))


def _pallet_jack_slow(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    layout = warehouse_aisle(rng, cross_aisles_m=((18.0, 21.0),))
    jack_model = pallet_jack(loaded=True)
    speed = float(rng.uniform(0.3, 0.6))
    x0 = float(rng.uniform(16.0, 20.0))
    y = 0.95
    jack = place(1, "pallet_jack", jack_model, mo.constant(speed), (x0, y, math.pi), duration)
    operator_dx = jack_model.length_m / 2 + 0.55  # walking ahead, holding the handle
    op_traj = mo.offset_trajectory(jack.trajectory, operator_dx, 0.0)
    operator = SimObject(2, "jack_operator", person(), op_traj, None)
    world = World("pallet_jack_slow", layout.structure, (jack, operator), layout.bounds_m)
    return ScenarioSpec(world, Route(np.array([[0.0, -0.2], [30.0, -0.2]])))


def _occlusion_behind_cart(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    layout = warehouse_aisle(rng, cross_aisles_m=((11.0, 14.0),))
    parked = place(1, "cart_parked", cart(), mo.stationary(), (11.0, 1.2, 0.0), duration)
    speed = float(rng.uniform(1.0, 1.4))
    delay = float(rng.uniform(6.0, 7.5))
    hidden = place(
        2,
        "hidden_walker",
        person(),
        mo.accelerate(0.0, speed, delay, 2.0),
        (12.3, 1.25, -math.pi / 2),
        duration,
    )
    world = World("occlusion_behind_cart", layout.structure, (parked, hidden), layout.bounds_m)
    return ScenarioSpec(world, Route(np.array([[0.0, 0.0], [30.0, 0.0]])))


def _forklift_pass_by(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    layout = warehouse_aisle(rng, aisle_width_m=4.0, cross_aisles_m=((20.0, 23.0),))
    speed = float(rng.uniform(1.5, 2.2))
    x0 = float(rng.uniform(22.0, 28.0))
    # Drives past the robot and brakes (1 m/s^2) to stop with its centre at x = -1 m,
    # short of the aisle's end wall.
    brake_at = (x0 + 1.0 - speed**2 / 2.0) / speed
    fork = place(
        1,
        "forklift_oncoming",
        counterbalance_forklift(),
        mo.accelerate(speed, 0.0, brake_at, 1.0),
        (x0, 0.95, math.pi),
        duration,
    )
    other = place(
        2,
        "amr_crossing",
        amr(),
        mo.accelerate(0.0, 1.0, float(rng.uniform(2.0, 5.0)), 0.5),
        (21.5, -5.0, math.pi / 2),
        duration,
    )
    world = World("forklift_pass_by", layout.structure, (fork, other), layout.bounds_m)
    return ScenarioSpec(world, Route(np.array([[0.0, -0.7], [30.0, -0.7]])))


def _dolly_train_turn(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    layout = apron_stand()
    speed = float(rng.uniform(2.2, 3.0))
    radius = float(rng.uniform(6.0, 8.0))
    lane_y, ego_x0, y0 = -1.2, 2.0, 20.0
    # South towards the road, then a 90 deg left turn into the robot's lane ahead of it
    # (heading +x), timed for a nominal 1 m/s robot to be 8-11 m short of the turn's end.
    straight = y0 - (lane_y + radius)
    t_cross = (straight + 0.5 * math.pi * radius) / speed
    x0 = ego_x0 + t_cross * 1.0 + float(rng.uniform(8.0, 11.0)) - radius
    tug_motion = mo.turning(speed, straight / speed, math.pi / 2, speed / radius)
    tug = place(1, "baggage_tug", baggage_tug(), tug_motion, (x0, y0, -math.pi / 2), duration)
    dollies = mo.tow_train(tug.trajectory, 3)
    objects = [tug] + [
        SimObject(2 + i, f"dolly_{i + 1}", dolly(), traj, None) for i, traj in enumerate(dollies)
    ]
    objects.append(
        place(5, "uld_parked", uld_container(), mo.stationary(), (1.0, 5.0, 0.0), duration)
    )
    objects.append(
        place(
            6,
            "ramp_agent",
            person(),
            mo.stop_and_go(1.2, 1.5, 2.0, 2.5, 1.5, 4),
            (24.0, 14.0, 0.0),
            duration,
        )
    )
    world = World(
        "dolly_train_turn", layout.structure, tuple(objects), layout.bounds_m, "apron", layout.decor
    )
    return ScenarioSpec(world, Route(np.array([[ego_x0, lane_y], [42.0, lane_y]])))


def _random_encounter(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    from pipeline.sources.sim.encounters import random_encounter

    world, route = random_encounter(rng, duration)
    return ScenarioSpec(world, route)


def _tug_overtaking(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    from pipeline.sources.sim.overtaking import tug_overtaking

    return ScenarioSpec(*tug_overtaking(rng, duration))


SCENARIOS: dict[str, ScenarioInfo] = {
    info.name: info
    for info in (
        ScenarioInfo(
            "reversing_forklift_aisle",
            "A forklift ahead in the aisle drives away, stops within 3-5 frames and "
            "reverses towards the robot; a parked reach truck and a walker in the "
            "cross aisles.",
            "warehouse",
            _reversing_forklift_aisle,
        ),
        ScenarioInfo(
            "crossing_pedestrian",
            "A person steps out of a cross aisle, hidden by the racks, into the "
            "robot's lane 1.5-3.5 m ahead of it.",
            "warehouse",
            _crossing_pedestrian,
        ),
        ScenarioInfo(
            "pallet_jack_slow",
            "A loaded manual pallet jack pulled by its operator comes down the aisle "
            "at 0.3-0.6 m/s; the robot passes it with little room.",
            "warehouse",
            _pallet_jack_slow,
        ),
        ScenarioInfo(
            "occlusion_behind_cart",
            "A person waiting behind a parked cart walks across the aisle while the "
            "robot approaches.",
            "warehouse",
            _occlusion_behind_cart,
        ),
        ScenarioInfo(
            "forklift_pass_by",
            "An oncoming forklift passes the robot in a 4 m aisle; another AMR crosses further on.",
            "warehouse",
            _forklift_pass_by,
        ),
        ScenarioInfo(
            "dolly_train_turn",
            "Apron: a baggage tug with three dollies turns onto the service road "
            "ahead of the robot (the dollies cut the corner); a parked ULD and a "
            "ramp agent.",
            "apron",
            _dolly_train_turn,
        ),
        ScenarioInfo(
            "tug_overtaking",
            "Apron: a baggage tug overtakes the robot from behind and turns across its "
            "lane 3.5-5 m ahead (what a rear scanner is for).",
            "apron",
            _tug_overtaking,
        ),
        ScenarioInfo(
            "random_encounter",
            "Randomised encounter for campaigns: warehouse or apron layout, 1-4 "
            "objects of random kinds, motions and timings.",
            "any",
            _random_encounter,
        ),
    )
}


def build_scenario(name: str, seed: int, duration_s: float) -> ScenarioSpec:
    """Build the named scenario with its layout stream drawn from ``seed``."""
    info = SCENARIOS.get(name)
    if info is None:
        raise ScenarioError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}")
    layout_ss = np.random.SeedSequence(seed).spawn(3)[0]
    return info.builder(np.random.default_rng(layout_ss), duration_s)


def lidar_spec_from_config(config: SafecaseConfig) -> LidarSpec:
    """The scanner configured in the ``sim`` section."""
    sim = config.sim
    sensor = {
        "range_noise_std_m": sim.range_noise_std_m,
        "noise_clip_sigma": sim.noise_clip_sigma,
        "dropout_prob": sim.dropout_prob,
        "mixed_pixel_prob": sim.mixed_pixel_prob,
        "mixed_pixel_min_jump_m": sim.mixed_pixel_min_jump_m,
        "time_skew": sim.time_skew,
    }
    if sim.lidar_device != "generic":
        return DEVICE_PRESETS[sim.lidar_device]().with_changes(**sensor)
    return LidarSpec.generic(
        sim.beams,
        math.radians(sim.fov_deg),
        scan_rate_hz=sim.scan_rate_hz,
        min_range_m=sim.min_range_m,
        max_range_m=sim.max_range_m,
        **sensor,
    )


def make_simulation(
    config: SafecaseConfig,
    name: str | None = None,
    seed: int | None = None,
    duration_s: float | None = None,
    lidar: LidarSpec | None = None,
    retention: Retention = FULL,
) -> Simulation:
    """A ready-to-run simulation of scenario ``name`` (default: ``sim.scenario``) with the
    configured scanner, ego robot and label rules, keeping ``retention`` for its result."""
    sim = config.sim
    name = sim.scenario if name is None else name
    seed = sim.seed if seed is None else seed
    duration = sim.duration_s if duration_s is None else duration_s
    spec = build_scenario(name, seed, duration)
    return simulation_for_spec(config, spec, name, seed, duration, lidar, retention)


def simulation_for_spec(
    config: SafecaseConfig,
    spec: ScenarioSpec,
    name: str,
    seed: int,
    duration: float,
    lidar: LidarSpec | None = None,
    retention: Retention = FULL,
    *,
    weather: str | None = None,
) -> Simulation:
    """A ready-to-run simulation of an already built scenario (e.g. one that is not in
    :data:`SCENARIOS`), with the scanner noise and ego braking streams drawn from ``seed`` as
    :func:`make_simulation` draws them; ``weather`` names the preset it is set in
    (``Simulation.weather``; None: not stated)."""
    sim = config.sim
    _, lidar_ss, ego_ss = np.random.SeedSequence(seed).spawn(3)
    ego_rng = np.random.default_rng(ego_ss)
    max_speed = max(config.stopping.robot_max_speed_mps, sim.ego_speed_mps)
    start = sim.ego_speed_mps if spec.initial_speed_mps is None else spec.initial_speed_mps
    ego = EgoSpec(
        route=spec.route,
        length_m=sim.ego_length_m,
        width_m=sim.ego_width_m,
        accel_mps2=sim.ego_accel_mps2,
        decel_mps2=float(ego_rng.uniform(sim.ego_decel_min_mps2, sim.ego_decel_max_mps2)),
        actuation_latency_s=sim.actuation_latency_s,
        max_speed_mps=max_speed,
        initial_speed_mps=min(start, max_speed),
        mount=(sim.mount_x_m, sim.mount_y_m, math.radians(sim.mount_yaw_deg)),
    )
    return Simulation(
        spec.world,
        ego,
        lidar if lidar is not None else lidar_spec_from_config(config),
        rng=np.random.default_rng(lidar_ss),
        duration_s=duration,
        step_s=sim.step_s,
        rules=LabelRules.from_config(sim),
        name=name,
        seed=seed,
        retention=retention,
        weather=weather,
    )
