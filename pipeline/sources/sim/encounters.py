"""Randomised encounters for campaigns (SR-SIM-2, SR-SIM-3).

:func:`random_encounter` draws a layout (a warehouse aisle with two cross aisles, or the apron
stand), then 1-4 objects of random kinds, each with a motion suited to its kind and a
placement that brings it near the robot's route: along the aisle or road (same or opposite
direction, any of the motion profiles, including the forklift reversal), or across it through
a cross aisle, timed to meet a robot driving at a nominal 1 m/s. Every candidate is checked
over the whole run (every 0.05 s) before it is accepted: it must keep ``CLEARANCE_M`` from
the static structure and from the objects already placed, must start at least
``START_GAP_M`` from the robot, and must leave the robot room to stop (SR-SIM-9): a
:class:`BrakingRobot` that drives on for its reaction time and then brakes at its weakest
deceleration keeps ``CLEARANCE_M`` from the candidate until it stands. A start that fails the
last check is one no controller that can only brake could survive (an object driving into
the robot faster than it can stop), so it says nothing about a safety layer. A rejected
candidate is redrawn (at most ``ATTEMPTS`` times per object). Everything comes from the
generator given, so a seed reproduces the encounter bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import Route
from pipeline.sources.sim.layouts import apron_stand, warehouse_aisle
from pipeline.sources.sim.objects import (
    ObjectKind,
    model_for,
    pallet_jack,
    person,
)
from pipeline.sources.sim.shapes import Outline, outline_distances, pose_points, rectangle
from pipeline.sources.sim.world import SimObject, Structure, World, structure_clearance
from pipeline.types import FloatArray

__all__ = ["ATTEMPTS", "CLEARANCE_M", "START_GAP_M", "BrakingRobot", "random_encounter"]

CLEARANCE_M = 0.1
START_GAP_M = 1.0
ATTEMPTS = 40
_CHECK_DT_S = 0.05
_WAREHOUSE_KINDS = (
    ObjectKind.COUNTERBALANCE_FORKLIFT,
    ObjectKind.COUNTERBALANCE_FORKLIFT,
    ObjectKind.REACH_TRUCK,
    ObjectKind.PALLET_JACK,
    ObjectKind.CART,
    ObjectKind.PERSON,
    ObjectKind.PERSON,
    ObjectKind.AMR,
)
_APRON_KINDS = (
    ObjectKind.BAGGAGE_TUG,
    ObjectKind.BAGGAGE_TUG,
    ObjectKind.PERSON,
    ObjectKind.AMR,
    ObjectKind.ULD_CONTAINER,
    ObjectKind.CART,
)


@dataclass(frozen=True)
class BrakingRobot:
    """The robot a random encounter must leave room to stop (SR-SIM-9): a ``length_m`` x
    ``width_m`` footprint [m] starting at ``speed_mps`` along the route, driving on for
    ``reaction_s`` [s] and then braking at ``decel_mps2`` [m/s^2] until it stands.

    The defaults are the simulator's defaults at their least favourable: ``sim.ego_speed_mps``
    (1 m/s), the weakest braking a run draws (``sim.ego_decel_min_mps2``, 1.25 m/s^2), and
    the earliest a controller's brake can act: the first scan's end (0.1 s at 10 Hz) plus
    ``sim.actuation_latency_s`` (0.05 s) plus one simulation step (0.01 s), since a command
    acts from the first step that starts at or after it is due.
    """

    speed_mps: float = 1.0
    decel_mps2: float = 1.25
    reaction_s: float = 0.16
    length_m: float = 0.9
    width_m: float = 0.6

    def __post_init__(self) -> None:
        if not (self.speed_mps >= 0.0 and self.decel_mps2 > 0.0 and self.reaction_s >= 0.0):
            raise ValueError(
                f"BrakingRobot: need speed >= 0, deceleration > 0 and reaction >= 0; got "
                f"{self.speed_mps}, {self.decel_mps2}, {self.reaction_s}"
            )
        if not (self.length_m > 0.0 and self.width_m > 0.0):
            raise ValueError(f"BrakingRobot: size {self.length_m} x {self.width_m} must be > 0")

    @property
    def stop_s(self) -> float:
        """When the robot stands [s] (at once when it starts standing)."""
        if self.speed_mps == 0.0:
            return 0.0
        return self.reaction_s + self.speed_mps / self.decel_mps2

    def arc_m(self, t_s: FloatArray) -> FloatArray:
        """Distance along the route [m] driven by each time ``t_s`` [s]."""
        t = np.asarray(t_s, dtype=np.float64)
        braking = np.clip(t - self.reaction_s, 0.0, max(self.stop_s - self.reaction_s, 0.0))
        coast = self.speed_mps * np.minimum(t, self.reaction_s)
        arc: FloatArray = coast + braking * (self.speed_mps - 0.5 * self.decel_mps2 * braking)
        return arc

    def footprints(self, route: Route, times_s: FloatArray) -> tuple[Outline, FloatArray]:
        """The footprint and its posed vertices ``(T, 4, 2)`` at ``times_s`` on ``route``."""
        hl, hw = self.length_m / 2, self.width_m / 2
        fp = Outline.from_parts([rectangle(-hl, hl, -hw, hw)])
        pose = route.pose_at(self.arc_m(times_s))
        return fp, pose_points(fp.vertices_m, pose[:, 0], pose[:, 1], pose[:, 2])


def _motion_for(kind: ObjectKind, rng: np.random.Generator) -> mo.Motion:
    """A random motion profile suited to ``kind``."""
    u = float(rng.random())
    if kind in (ObjectKind.CART, ObjectKind.ULD_CONTAINER):
        return mo.stationary()
    if kind in (ObjectKind.COUNTERBALANCE_FORKLIFT, ObjectKind.REACH_TRUCK):
        if u < 0.4:
            return mo.random_reversing(rng, float(rng.uniform(1.0, 8.0)))
        if u < 0.55:
            return mo.stationary()
        if u < 0.7:
            return mo.stop_and_go(
                float(rng.uniform(0.8, 2.0)),
                1.0,
                1.5,
                float(rng.uniform(1.5, 4.0)),
                float(rng.uniform(0.5, 2.0)),
                3,
            )
        if u < 0.85:
            return mo.accelerate(
                0.0, float(rng.uniform(0.8, 2.0)), float(rng.uniform(0.5, 5.0)), 0.8
            )
        return mo.constant(float(rng.uniform(0.8, 2.0)))
    if kind == ObjectKind.PERSON:
        if u < 0.2:
            return mo.stationary()
        if u < 0.45:
            return mo.stop_and_go(
                float(rng.uniform(0.8, 1.5)),
                1.5,
                2.0,
                float(rng.uniform(1.0, 3.0)),
                float(rng.uniform(0.5, 2.0)),
                4,
            )
        return mo.constant(float(rng.uniform(0.8, 1.6)))
    if kind == ObjectKind.PALLET_JACK:
        return mo.constant(float(rng.uniform(0.3, 0.7)))
    if kind == ObjectKind.BAGGAGE_TUG:
        return mo.constant(float(rng.uniform(1.5, 3.0)))
    return mo.constant(float(rng.uniform(0.5, 1.5)))  # AMR


def _crossing_motion(kind: ObjectKind, rng: np.random.Generator, delay_s: float) -> mo.Motion:
    """Wait ``delay_s`` (if positive), then cross at a speed suited to ``kind``."""
    speed = {
        ObjectKind.PERSON: rng.uniform(1.0, 1.6),
        ObjectKind.AMR: rng.uniform(0.6, 1.5),
        ObjectKind.BAGGAGE_TUG: rng.uniform(1.5, 3.0),
    }.get(kind, rng.uniform(0.8, 2.0))
    if delay_s <= 0:
        return mo.constant(float(speed))
    return mo.accelerate(0.0, float(speed), delay_s, 1.5)


def _candidate(
    kind: ObjectKind,
    rng: np.random.Generator,
    next_id: int,
    duration: float,
    lane: Callable[[np.random.Generator, float], tuple[float, float, float]],
    crossing: Callable[[np.random.Generator], tuple[float, float, float, float]] | None,
) -> list[SimObject]:
    """One randomly placed object (two for a pallet jack with its operator; a tug may tow
    dollies)."""
    model = model_for(kind)
    if kind == ObjectKind.PALLET_JACK:
        model = pallet_jack(loaded=bool(rng.random() < 0.6))
    if (
        crossing is not None
        and kind
        in (
            ObjectKind.PERSON,
            ObjectKind.AMR,
            ObjectKind.COUNTERBALANCE_FORKLIFT,
            ObjectKind.BAGGAGE_TUG,
        )
        and rng.random() < 0.45
    ):
        x, y, heading, meet_s = crossing(rng)
        motion = _crossing_motion(kind, rng, 0.0)
        v = float(abs(motion.speed_at(np.array([10.0]))[0]))
        delay = meet_s - abs(y) / max(v, 0.1)
        motion = _crossing_motion(kind, rng, delay)
    else:
        motion = _motion_for(kind, rng)
        x, y, heading = lane(rng, model.width_m)
    traj = mo.integrate(motion, x, y, heading, duration + 0.5)
    name = f"{kind.value}_{next_id}"
    objs = [SimObject(next_id, name, model, traj, motion)]
    if kind == ObjectKind.PALLET_JACK:
        op = mo.offset_trajectory(traj, model.length_m / 2 + 0.55, 0.0)
        objs.append(SimObject(next_id + 1, f"operator_{next_id + 1}", person(), op, None))
    if kind == ObjectKind.BAGGAGE_TUG:
        for i, d_traj in enumerate(mo.tow_train(traj, int(rng.integers(0, 4)))):
            objs.append(
                SimObject(
                    next_id + 1 + i,
                    f"dolly_{next_id + 1 + i}",
                    model_for(ObjectKind.DOLLY),
                    d_traj,
                    None,
                )
            )
    return objs


def _fits(
    candidate: list[SimObject],
    placed: list[SimObject],
    structure: Structure,
    bounds: tuple[float, float, float, float],
    braking: tuple[Outline, FloatArray],
    times: np.ndarray,
) -> bool:
    """Whether ``candidate`` keeps its clearances over ``times`` (module docstring);
    ``braking`` is the braking robot's footprint and its vertices at ``times[:k]``, the check
    times while it still moves (at least the start)."""
    probe = World("probe", structure, tuple(candidate), bounds)
    if (structure_clearance(probe, times, margin_m=2 * CLEARANCE_M) < CLEARANCE_M).any():
        return False
    cand_verts = probe.object_vertices(times)
    fp, fp_verts = braking
    d = outline_distances(
        fp_verts,
        fp,
        cand_verts[: len(fp_verts)],
        probe.dynamic_outline,
        probe.part_owner,
        len(candidate),
    )
    if (d[0] < START_GAP_M).any() or (d < CLEARANCE_M).any():
        return False
    if not placed:
        return True
    others = World("others", structure, tuple(placed), bounds)
    other_verts = others.object_vertices(times)
    for index, obj in enumerate(candidate):
        lo, hi = probe.vertex_slices[index]
        d = outline_distances(
            cand_verts[:, lo:hi],
            obj.model.outline,
            other_verts,
            others.dynamic_outline,
            others.part_owner,
            len(placed),
        )
        if (d < CLEARANCE_M).any():
            return False
    return True


def random_encounter(
    rng: np.random.Generator, duration_s: float, robot: BrakingRobot | None = None
) -> tuple[World, Route]:
    """A random encounter world and the robot's route (module docstring); ``robot`` is the
    robot it must leave room to stop (default :class:`BrakingRobot`'s defaults)."""
    robot = BrakingRobot() if robot is None else robot
    apron = bool(rng.random() < 0.35)
    if apron:
        layout = apron_stand()
        structure, bounds, decor = layout.structure, layout.bounds_m, layout.decor
        lane_y = -1.2
        route = Route(np.array([[2.0, lane_y], [42.0, lane_y]]))
        kinds: tuple[ObjectKind, ...] = _APRON_KINDS

        def lane(g: np.random.Generator, width: float) -> tuple[float, float, float]:
            forward = bool(g.random() < 0.5)
            y = lane_y if forward else -lane_y
            return float(g.uniform(8.0, 38.0)), y, 0.0 if forward else math.pi

        def crossing(g: np.random.Generator) -> tuple[float, float, float, float]:
            meet = float(g.uniform(3.0, 14.0))
            x = 2.0 + meet + float(g.uniform(1.0, 6.0))
            y0 = float(g.uniform(6.0, 12.0))
            return x, y0, -math.pi / 2, meet
    else:
        width = float(rng.uniform(3.0, 4.0))
        c1 = float(rng.uniform(8.0, 14.0))
        c2 = float(rng.uniform(20.0, 28.0))
        aisles = ((c1, c1 + 3.0), (c2, c2 + 3.0))
        wl = warehouse_aisle(rng, length_m=40.0, aisle_width_m=width, cross_aisles_m=aisles)
        structure, bounds, decor = wl.structure, wl.bounds_m, ()
        route = Route(np.array([[0.0, 0.0], [34.0, 0.0]]))
        kinds = _WAREHOUSE_KINDS
        half = wl.half_width_m

        def lane(g: np.random.Generator, width: float) -> tuple[float, float, float]:
            room = max(0.0, half - width / 2 - 0.2)
            return (
                float(g.uniform(3.0, 34.0)),
                float(g.uniform(-room, room)),
                float(g.choice([0.0, math.pi])),
            )

        def crossing(g: np.random.Generator) -> tuple[float, float, float, float]:
            lo, hi = aisles[int(g.integers(0, 2))]
            side = float(g.choice([-1.0, 1.0]))
            meet = max(0.5, (lo + 1.5) - 0.45 - float(g.uniform(1.0, 6.0)))
            return (
                float(g.uniform(lo + 1.0, hi - 1.0)),
                side * float(g.uniform(4.0, 6.0)),
                -side * math.pi / 2,
                meet,
            )

    times = np.arange(0.0, duration_s + 1e-9, _CHECK_DT_S)
    moving = max(1, int(np.count_nonzero(times < robot.stop_s)))
    braking = robot.footprints(route, times[:moving])
    placed: list[SimObject] = []
    n_wanted = int(rng.integers(1, 5))
    next_id = 1
    for _ in range(n_wanted):
        kind = kinds[int(rng.integers(0, len(kinds)))]
        for _attempt in range(ATTEMPTS):
            cand = _candidate(kind, rng, next_id, duration_s, lane, crossing)
            if _fits(cand, placed, structure, bounds, braking, times):
                placed.extend(cand)
                next_id += len(cand)
                break
    if not placed:  # every draw was rejected: a person standing in the robot's way
        fallback = route.pose_at(np.array([route.length_m * 0.7]))[0]
        traj = mo.integrate(mo.stationary(), fallback[0], fallback[1], 0.0, duration_s + 0.5)
        placed.append(SimObject(next_id, f"person_{next_id}", person(), traj, mo.stationary()))
    world = World(
        "random_encounter",
        structure,
        tuple(placed),
        bounds,
        "apron" if apron else "warehouse",
        decor,
    )
    return world, route
