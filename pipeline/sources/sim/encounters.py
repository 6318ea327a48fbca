"""Randomised encounters for campaigns (SR-SIM-2, SR-SIM-3).

:func:`random_encounter` draws a layout (a warehouse aisle with two cross aisles, or the apron
stand), then 1-4 objects of random kinds, each with a motion suited to its kind and a
placement that brings it near the robot's route: along the aisle or road (same or opposite
direction, any of the motion profiles, including the forklift reversal), or across it through
a cross aisle, timed to meet a robot driving at a nominal 1 m/s. Every candidate is checked
over the whole run (every 0.05 s) before it is accepted: it must keep ``CLEARANCE_M`` from
the static structure and from the objects already placed, and must not start on the robot;
otherwise it is redrawn (at most ``ATTEMPTS`` times per object). Everything comes from the
generator given, so a seed reproduces the encounter bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable

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

__all__ = ["ATTEMPTS", "CLEARANCE_M", "random_encounter"]

CLEARANCE_M = 0.1
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
    ego_start: tuple[Outline, np.ndarray],
    times: np.ndarray,
) -> bool:
    """Whether ``candidate`` keeps its clearances over ``times`` (module docstring)."""
    probe = World("probe", structure, tuple(candidate), bounds)
    if (structure_clearance(probe, times, margin_m=2 * CLEARANCE_M) < CLEARANCE_M).any():
        return False
    cand_verts = probe.object_vertices(times)
    fp, fp_verts = ego_start
    d0 = outline_distances(
        fp_verts, fp, cand_verts[0], probe.dynamic_outline, probe.part_owner, len(candidate)
    )
    if (d0 < 1.0).any():
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


def random_encounter(rng: np.random.Generator, duration_s: float) -> tuple[World, Route]:
    """A random encounter world and the robot's route (module docstring)."""
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
    hl = 0.45  # nominal robot half-length for the start check
    fp = Outline.from_parts([rectangle(-hl, hl, -0.3, 0.3)])
    start = route.pose_at(np.array([0.0]))
    ego_start = (fp, pose_points(fp.vertices_m, start[:, 0], start[:, 1], start[:, 2])[0])
    placed: list[SimObject] = []
    n_wanted = int(rng.integers(1, 5))
    next_id = 1
    for _ in range(n_wanted):
        kind = kinds[int(rng.integers(0, len(kinds)))]
        for _attempt in range(ATTEMPTS):
            cand = _candidate(kind, rng, next_id, duration_s, lane, crossing)
            if _fits(cand, placed, structure, bounds, ego_start, times):
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
