"""Apron scenarios for association, shape and re-identification measurements (SR-TRK-7, -8, -9).

Builders ``(rng, duration_s) -> ScenarioSpec`` in the form of :mod:`pipeline.sources.sim.
scenarios`, listed in :data:`AIRSIDE_SCENARIOS` (name -> description and builder); the
measurement campaigns run them (``properties/airside_runs.py``). All are laid out on the
apron stand (:func:`pipeline.sources.sim.layouts.apron_stand`): the robot starts at (2, -1.2)
on the service road facing +x, at rest (``initial_speed_mps`` 0), so that a measurement run can
keep it standing and a closed-loop run lets the governor drive it along the road.

* ``dolly_train_close``: a tug tows four covered baggage carts 0.30-0.45 m apart past the robot
  (dense, similar, parallel targets);
* ``adjacent_ulds``: five LD3 containers parked 0.2-0.4 m apart beside the road, a ramp agent
  walking along them within 0.6 m and a tug passing;
* ``walker_crowd``: two groups of four walkers about 0.7 m apart cross the road ahead of the
  robot in opposite directions, through each other;
* ``apron_clutter``: 30 cones, chocks and debris scattered ahead, two walkers and a tug moving
  among them;
* ``walker_behind_carts``: a walker passes behind a row of parked baggage carts (seen in the
  gaps) while a second walker comes out from behind the row further on;
* ``tug_behind_stand``: a tug drives behind parked passenger stairs and comes out the other
  side; a second tug waits parked near where it comes out;
* ``vehicle_headings``: tugs, carts, containers and robots parked at random headings at 3-25 m,
  and vehicles driving, turning and creeping among them (heading estimation).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import Route
from pipeline.sources.sim.layouts import apron_stand
from pipeline.sources.sim.objects import (
    ObjectKind,
    ObjectModel,
    amr,
    baggage_tug,
    cart,
    person,
    uld_container,
)
from pipeline.sources.sim.scenarios import ScenarioSpec, place
from pipeline.sources.sim.shapes import Outline, rectangle, regular_polygon
from pipeline.sources.sim.world import SimObject, Structure, World
from pipeline.types import FloatArray

__all__ = ["AIRSIDE_SCENARIOS", "covered_baggage_cart"]

_EGO_START = (2.0, -1.2)
_ROUTE = Route(np.array([[_EGO_START[0], _EGO_START[1]], [42.0, _EGO_START[1]]]))


def covered_baggage_cart() -> ObjectModel:
    """A covered baggage cart of the common 3 x 1.5 m class whose side curtains come down to
    the scan plane: a plain 2.9 x 1.5 m box to the scanner."""
    outline = Outline.from_parts([rectangle(-1.45, 1.45, -0.75, 0.75)])
    return ObjectModel(ObjectKind.DOLLY, outline, length_m=2.9, width_m=1.5, reflectivity=0.5)


def _world(
    name: str, objects: Sequence[SimObject], extra: Sequence[tuple[str, FloatArray]] = ()
) -> World:
    layout = apron_stand()
    st = layout.structure
    parts = list(zip(st.part_kinds, st.outline.parts(), strict=True)) + list(extra)
    structure = Structure.from_parts(parts) if extra else st
    return World(name, structure, tuple(objects), layout.bounds_m, "apron", layout.decor)


def _spec(world: World) -> ScenarioSpec:
    return ScenarioSpec(world, _ROUTE, initial_speed_mps=0.0)


def _train(
    first_id: int,
    leader: SimObject,
    model: ObjectModel,
    n: int,
    gaps_m: FloatArray,
    name: str,
) -> list[SimObject]:
    """``n`` bodies following ``leader`` in a straight line, ``gaps_m`` apart (body to body)."""
    out = []
    back = leader.model.length_m / 2
    for i in range(n):
        back += gaps_m[i] + model.length_m / 2
        traj = mo.offset_trajectory(leader.trajectory, -back, 0.0)
        out.append(SimObject(first_id + i, f"{name}_{i + 1}", model, traj, None))
        back += model.length_m / 2
    return out


def _dolly_train_close(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    speed = float(rng.uniform(1.5, 2.5))
    lane_y = float(rng.uniform(2.5, 3.5))
    x0 = float(rng.uniform(14.0, 18.0))
    tug = place(
        1, "baggage_tug", baggage_tug(), mo.constant(speed), (x0, lane_y, math.pi), duration
    )
    gaps = rng.uniform(0.30, 0.45, 4)
    carts = _train(2, tug, covered_baggage_cart(), 4, gaps, "covered_cart")
    agent = place(
        6,
        "ramp_agent",
        person(),
        mo.constant(float(rng.uniform(1.0, 1.3))),
        (float(rng.uniform(8.0, 12.0)), 7.0, -math.pi / 2),
        duration,
    )
    return _spec(_world("dolly_train_close", [tug, *carts, agent]))


def _adjacent_ulds(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    objects: list[SimObject] = []
    x = float(rng.uniform(6.0, 8.0))
    row_y = float(rng.uniform(2.6, 3.2))
    model = uld_container()
    for i in range(5):
        objects.append(
            place(1 + i, f"uld_{i + 1}", model, mo.stationary(), (x, row_y, 0.0), duration)
        )
        x += model.length_m + float(rng.uniform(0.2, 0.4))
    walk_y = row_y + model.width_m / 2 + float(rng.uniform(0.35, 0.6))
    objects.append(
        place(
            6,
            "ramp_agent",
            person(),
            mo.constant(float(rng.uniform(0.9, 1.3))),
            (float(rng.uniform(4.0, 5.5)), walk_y, 0.0),
            duration,
        )
    )
    objects.append(
        place(
            7,
            "baggage_tug",
            baggage_tug(),
            mo.constant(float(rng.uniform(2.0, 3.0))),
            (float(rng.uniform(28.0, 34.0)), row_y + 3.2, math.pi),
            duration,
        )
    )
    return _spec(_world("adjacent_ulds", objects))


def _walker_crowd(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    objects: list[SimObject] = []
    centre_x = float(rng.uniform(5.0, 6.5))
    for group, (y0, heading) in enumerate(((-6.0, math.pi / 2), (5.0, -math.pi / 2))):
        speed = float(rng.uniform(1.0, 1.4))
        delay = float(rng.uniform(0.5, 1.5))
        for k in range(4):
            dx = (k % 2 - 0.5) * 0.7 + float(rng.uniform(-0.1, 0.1)) + 0.4 * group
            dy = (k // 2) * 0.7 + float(rng.uniform(-0.1, 0.1))
            y = y0 - dy if heading > 0 else y0 + dy
            walk = mo.accelerate(0.0, speed + float(rng.uniform(-0.1, 0.1)), delay, 1.5)
            objects.append(
                place(
                    1 + 4 * group + k,
                    f"walker_{group + 1}{k + 1}",
                    person(),
                    walk,
                    (centre_x + dx, y, heading),
                    duration,
                )
            )
    return _spec(_world("walker_crowd", objects))


def _apron_clutter(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    tug_y = 4.5
    walker_x = (float(rng.uniform(6.0, 9.0)), float(rng.uniform(13.0, 17.0)))
    extra: list[tuple[str, FloatArray]] = []
    while len(extra) < 30:
        cx, cy = float(rng.uniform(4.0, 22.0)), float(rng.uniform(-6.0, 8.0))
        # Keep the robot's lane, the tug's lane and the walkers' paths clear of clutter.
        if abs(cy - _EGO_START[1]) < 1.2 or abs(cy - tug_y) < 1.2:
            continue
        if min(abs(cx - w) for w in walker_x) < 0.8:
            continue
        kind = ("cone", "chock", "debris")[int(rng.integers(3))]
        size = {"cone": 0.11, "chock": 0.15, "debris": 0.08}[kind]
        extra.append((kind, regular_polygon(size, 8 if kind == "cone" else 6, (cx, cy))))
    objects = [
        place(
            1,
            "baggage_tug",
            baggage_tug(),
            mo.constant(float(rng.uniform(1.5, 2.5))),
            (float(rng.uniform(24.0, 28.0)), tug_y, math.pi),
            duration,
        ),
        place(
            2,
            "walker_1",
            person(),
            mo.constant(float(rng.uniform(1.0, 1.4))),
            (walker_x[0], -7.5, math.pi / 2),
            duration,
        ),
        place(
            3,
            "walker_2",
            person(),
            mo.constant(float(rng.uniform(1.0, 1.4))),
            (walker_x[1], 9.5, -math.pi / 2),
            duration,
        ),
    ]
    return _spec(_world("apron_clutter", objects, extra))


def _walker_behind_carts(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    model = cart()
    row_y = float(rng.uniform(1.6, 1.9))
    objects: list[SimObject] = []
    # The row stands abeam of the robot, where its gaps are seen straight through.
    x = float(rng.uniform(-1.5, -0.5))
    end = x
    for i in range(4):
        objects.append(
            place(1 + i, f"cart_parked_{i + 1}", model, mo.stationary(), (x, row_y, 0.0), duration)
        )
        end = x + model.length_m / 2
        x += model.length_m + float(rng.uniform(0.8, 1.2))
    behind = row_y + model.width_m / 2 + float(rng.uniform(0.5, 0.8))
    objects.append(
        place(
            5,
            "walker_behind",
            person(),
            mo.constant(float(rng.uniform(1.0, 1.4))),
            (float(rng.uniform(-4.0, -3.0)), behind, 0.0),
            duration,
        )
    )
    # A second walker waits past the row's end, further back, and steps out across the first
    # one's path towards the road: near where the first, hidden behind a cart, is predicted to
    # come out (a chance to re-identify the wrong person).
    objects.append(
        place(
            6,
            "walker_out",
            person(),
            mo.accelerate(0.0, float(rng.uniform(1.0, 1.3)), float(rng.uniform(3.0, 6.0)), 1.5),
            (end + float(rng.uniform(0.5, 1.0)), behind + 0.8, -math.pi / 2),
            duration,
        )
    )
    return _spec(_world("walker_behind_carts", objects))


def _tug_behind_stand(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    # Passenger stairs (4 x 2 m) parked 2.7 m off the robot's lane; the tug's lane just behind
    # them lies in their shadow for about 2 s at its speed.
    cx, cy = float(rng.uniform(6.5, 7.5)), 2.5
    stairs = rectangle(cx - 2.0, cx + 2.0, cy - 1.0, cy + 1.0)
    lane_y = cy + 1.0 + float(rng.uniform(0.9, 1.2))
    objects = [
        place(
            1,
            "baggage_tug",
            baggage_tug(),
            mo.constant(float(rng.uniform(2.5, 3.5))),
            (float(rng.uniform(-1.0, 1.0)), lane_y, 0.0),
            duration,
        ),
        place(
            2,
            "tug_parked",
            baggage_tug(),
            mo.stationary(),
            (float(rng.uniform(17.0, 20.0)), lane_y + 2.2, 0.0),
            duration,
        ),
    ]
    return _spec(_world("tug_behind_stand", objects, [("passenger_stairs", stairs)]))


def _vehicle_headings(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    models = (baggage_tug(), covered_baggage_cart(), uld_container(), amr(), cart())
    objects: list[SimObject] = []
    taken: list[tuple[float, float, float]] = []
    attempts = 0
    while len(objects) < 8 and attempts < 400:
        attempts += 1
        rng_range, bearing = float(rng.uniform(3.0, 25.0)), float(rng.uniform(-0.6, 1.6))
        x = _EGO_START[0] + rng_range * math.cos(bearing)
        y = _EGO_START[1] + rng_range * math.sin(bearing)
        model = models[int(rng.integers(len(models)))]
        reach = 0.5 * math.hypot(model.length_m, model.width_m)
        moving = len(objects) % 2 == 1
        travel = 6.0 if moving else 0.0
        if y < 1.0 or y > 20.0 or x < 2.0 or x > 38.0:
            continue  # off the robot's lane and clear of the aircraft's gear
        if any(math.hypot(x - a, y - b) < reach + r + travel + 1.0 for a, b, r in taken):
            continue
        heading = float(rng.uniform(-math.pi, math.pi))
        if moving:
            speed = float(rng.choice([0.2, 0.5, 1.0, 2.0]))
            motion = mo.turning(speed, 1.0, float(rng.uniform(-1.0, 1.0)), 0.3)
        else:
            motion = mo.stationary()
        objects.append(
            place(
                1 + len(objects),
                f"{model.kind.value}_{len(objects) + 1}",
                model,
                motion,
                (x, y, heading),
                duration,
            )
        )
        taken.append((x, y, reach))
    return _spec(_world("vehicle_headings", objects))


Builder = Callable[[np.random.Generator, float], ScenarioSpec]

AIRSIDE_SCENARIOS: dict[str, tuple[str, Builder]] = {
    "dolly_train_close": (
        "Apron: a tug tows four covered baggage carts 0.30-0.45 m apart past the robot; a ramp "
        "agent crosses behind.",
        _dolly_train_close,
    ),
    "adjacent_ulds": (
        "Apron: five LD3 containers parked 0.2-0.4 m apart, a ramp agent walking along them, a "
        "tug passing.",
        _adjacent_ulds,
    ),
    "walker_crowd": (
        "Apron: two groups of four walkers cross the road ahead of the robot in opposite "
        "directions, through each other.",
        _walker_crowd,
    ),
    "apron_clutter": (
        "Apron: 30 cones, chocks and debris ahead; two walkers and a tug move among them.",
        _apron_clutter,
    ),
    "walker_behind_carts": (
        "Apron: a walker passes behind a row of parked baggage carts; another comes out from "
        "behind the row.",
        _walker_behind_carts,
    ),
    "tug_behind_stand": (
        "Apron: a tug drives behind parked passenger stairs and comes out; another tug waits "
        "parked there.",
        _tug_behind_stand,
    ),
    "vehicle_headings": (
        "Apron: vehicles parked at random headings, others driving, turning and creeping among "
        "them.",
        _vehicle_headings,
    ),
}
