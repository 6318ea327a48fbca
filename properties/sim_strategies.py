"""Hypothesis strategies for the simulator (SR-SIM-*): scenes, motions, scanner layouts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.lidar import LidarSpec
from pipeline.sources.sim.objects import ObjectKind, model_for
from pipeline.sources.sim.scenarios import SCENARIOS
from pipeline.sources.sim.shapes import chamfered_rectangle, pose_points, rectangle, regular_polygon
from pipeline.sources.sim.world import SimObject, Structure, World
from pipeline.types import FloatArray

__all__ = ["RandomScene", "lidar_specs", "random_motions", "random_scenes"]

NAMED = tuple(name for name in SCENARIOS if name != "random_encounter")


@dataclass(frozen=True)
class RandomScene:
    """A world of random static polygons and parked objects, and a scanner pose outside all
    (and off their boundaries)."""

    world: World
    pose: tuple[float, float, float]


def _inside(point: FloatArray, polygon: FloatArray, clearance_m: float = 1e-6) -> bool:
    """Whether ``point`` is inside ``polygon`` or within ``clearance_m`` of its boundary (a
    scanner sits in free space, never on a surface, where a ray's first hit is ambiguous)."""
    x, y = point
    px, py = polygon[:, 0], polygon[:, 1]
    qx, qy = np.roll(px, -1), np.roll(py, -1)
    straddle = (py > y) != (qy > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = px + (y - py) * (qx - px) / (qy - py)
    if np.count_nonzero(straddle & (x < xc)) % 2:
        return True
    ex, ey = qx - px, qy - py
    length2 = np.maximum(ex * ex + ey * ey, 1e-300)
    t = np.clip(((x - px) * ex + (y - py) * ey) / length2, 0.0, 1.0)
    gap = np.hypot(px + t * ex - x, py + t * ey - y)
    return bool(gap.min() <= clearance_m)


@st.composite
def random_scenes(draw: st.DrawFn, max_polygons: int = 12, max_objects: int = 4) -> RandomScene:
    """Random rectangles, chamfered boxes and n-gons (10 m around the origin) plus parked
    object models; every polygon containing the scanner is left out (a scanner is never
    inside an object)."""
    pose = (
        draw(st.floats(-2.0, 2.0), label="scanner x"),
        draw(st.floats(-2.0, 2.0), label="scanner y"),
        draw(st.floats(-math.pi, math.pi), label="scanner yaw"),
    )
    origin = np.array(pose[:2])
    coord = st.floats(-10.0, 10.0)
    size = st.floats(0.05, 6.0)
    parts: list[tuple[str, FloatArray]] = []
    for _ in range(draw(st.integers(1, max_polygons), label="n polygons")):
        shape = draw(st.sampled_from(["rect", "chamfer", "ngon"]))
        cx, cy, w, h = draw(coord), draw(coord), draw(size), draw(size)
        if shape == "rect":
            poly = rectangle(cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2)
        elif shape == "chamfer":
            c = 0.4 * min(w, h) * draw(st.floats(0.0, 0.99))
            poly = chamfered_rectangle(
                cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2, rear_chamfer_m=c
            )
        else:
            poly = regular_polygon(max(w, h) / 2, draw(st.integers(3, 12)), (cx, cy))
        yaw = draw(st.floats(-math.pi, math.pi))
        c, s = math.cos(yaw), math.sin(yaw)
        centred = poly - np.array([cx, cy])
        poly = np.stack(
            [
                cx + c * centred[:, 0] - s * centred[:, 1],
                cy + s * centred[:, 0] + c * centred[:, 1],
            ],
            1,
        )
        if not _inside(origin, poly):
            parts.append(("block", poly))
    objects = []
    kinds = list(ObjectKind)
    for i in range(draw(st.integers(0, max_objects), label="n objects")):
        model = model_for(draw(st.sampled_from(kinds)))
        x, y, h = draw(coord), draw(coord), draw(st.floats(-math.pi, math.pi))
        traj = mo.integrate(mo.stationary(), x, y, h, 1.0)
        # The body as placed at rest (a person's shins stand apart from the outline's origin).
        rest = model.body_vertices(np.zeros(1), np.zeros(1), np.zeros(1))[0]
        verts = pose_points(rest, np.array([x]), np.array([y]), np.array([h]))[0]
        s_ = model.outline.part_starts
        if any(_inside(origin, verts[s_[p] : s_[p + 1]]) for p in range(model.outline.n_parts)):
            continue
        objects.append(
            SimObject(i + 1, f"{model.kind.value}_{i + 1}", model, traj, mo.stationary())
        )
    if not parts:
        parts.append(("block", rectangle(15.0, 16.0, 15.0, 16.0)))
    world = World("random_scene", Structure.from_parts(parts), tuple(objects), (-12, 12, -12, 12))
    return RandomScene(world, pose)


def lidar_specs(max_beams: int = 720) -> st.SearchStrategy[LidarSpec]:
    """Generic and device layouts, sensor effects off."""
    generic = st.builds(
        lambda n, fov, rmax: LidarSpec.generic(n, math.radians(fov), max_range_m=rmax),
        st.integers(16, max_beams),
        st.sampled_from([90.0, 180.0, 240.0, 270.0, 360.0]),
        st.floats(2.0, 30.0),
    )
    from pipeline.sources.sim.lidar import DEVICE_PRESETS

    devices = st.sampled_from(sorted(DEVICE_PRESETS)).map(lambda name: DEVICE_PRESETS[name]())
    return st.one_of(generic, devices)


@st.composite
def random_motions(draw: st.DrawFn) -> mo.Motion:
    """Any of the motion profiles with random parameters (reversals weighted up)."""
    kind = draw(
        st.sampled_from(
            ["reversing", "reversing", "stop_and_go", "accelerate", "constant", "stationary"]
        )
    )
    speed = st.floats(0.3, 2.5)
    if kind == "reversing":
        return mo.reversing(
            draw(speed),
            draw(st.floats(0.2, 6.0)),
            0.1 * draw(st.integers(3, 5)),
            draw(st.floats(0.0, 1.5)),
            draw(st.floats(0.3, 1.5)),
            draw(st.floats(0.3, 2.0)),
            draw(st.one_of(st.none(), st.floats(0.2, 4.0))),
        )
    if kind == "stop_and_go":
        return mo.stop_and_go(
            draw(speed),
            draw(st.floats(0.3, 2.0)),
            draw(st.floats(0.3, 3.0)),
            draw(st.floats(0.2, 3.0)),
            draw(st.floats(0.1, 2.0)),
            draw(st.integers(1, 3)),
        )
    if kind == "accelerate":
        v0 = draw(st.floats(-1.5, 2.0))
        return mo.accelerate(
            v0, draw(st.floats(-1.5, 2.0)), draw(st.floats(0.0, 5.0)), draw(st.floats(0.2, 2.0))
        )
    if kind == "constant":
        return mo.constant(draw(st.floats(-2.0, 2.0)))
    return mo.stationary()
