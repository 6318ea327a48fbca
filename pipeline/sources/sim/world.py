"""The simulated world: static structure plus moving objects, posed at any instant.

:class:`World` keeps every object's parts in one combined
:class:`~pipeline.sources.sim.shapes.Outline` (with the owning object of each part and edge), so
posing all objects at ``T`` instants is a handful of array operations and the ray caster gets one
flat edge list (SR-SIM-1).
:func:`structure_clearance` measures how close each object comes to the static structure over
time (SR-SIM-3: no object may overlap a static structure; the scenario builders reject
layouts that would).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pipeline.sources.sim.motion import Motion, Trajectory
from pipeline.sources.sim.objects import ObjectModel
from pipeline.sources.sim.shapes import Outline, outline_distances, pose_points
from pipeline.types import FloatArray, IntArray, frozen_array

__all__ = ["SimObject", "Structure", "World", "structure_clearance"]


@dataclass(frozen=True, slots=True)
class Structure:
    """Static structure: closed CCW parts in the world frame and what each part is."""

    outline: Outline
    part_kinds: tuple[str, ...]

    @staticmethod
    def from_parts(parts: Sequence[tuple[str, FloatArray]]) -> Structure:
        """Build from ``(kind, polygon)`` pairs, e.g. ``("rack_upright", square)``."""
        return Structure(
            outline=Outline.from_parts([p for _, p in parts]),
            part_kinds=tuple(k for k, _ in parts),
        )


@dataclass(frozen=True, slots=True)
class SimObject:
    """One moving (or parked) object: its model, trajectory and the motion that made it.

    ``motion`` is None for objects whose trajectory was derived from another's (dollies in a
    train, a pallet jack's operator); labels that need the motion (forklift states) are
    defined only for objects that have one.
    """

    object_id: int
    name: str
    model: ObjectModel
    trajectory: Trajectory
    motion: Motion | None = None


@dataclass(frozen=True)
class World:
    """Static structure and objects; ``bounds_m`` = (x_min, x_max, y_min, y_max) for plots;
    ``decor`` are labelled outlines drawn in pictures only (e.g. an aircraft's fuselage,
    which is above the scan plane and invisible to the scanner)."""

    name: str
    structure: Structure
    objects: tuple[SimObject, ...]
    bounds_m: tuple[float, float, float, float]
    environment: str = "warehouse"
    decor: tuple[tuple[str, FloatArray], ...] = ()
    dynamic_outline: Outline = field(init=False, repr=False)
    part_owner: IntArray = field(init=False, repr=False)
    edge_owner: IntArray = field(init=False, repr=False)
    vertex_slices: tuple[tuple[int, int], ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        ids = [o.object_id for o in self.objects]
        if len(set(ids)) != len(ids) or any(i < 0 for i in ids):
            raise ValueError(f"World {self.name}: object ids must be unique and >= 0, got {ids}")
        parts: list[FloatArray] = []
        owners: list[int] = []
        slices: list[tuple[int, int]] = []
        start = 0
        for index, obj in enumerate(self.objects):
            obj_parts = obj.model.outline.parts()
            parts.extend(obj_parts)
            owners.extend([index] * len(obj_parts))
            slices.append((start, start + obj.model.outline.n_vertices))
            start += obj.model.outline.n_vertices
        if parts:
            outline = Outline.from_parts(parts)
        else:
            outline = Outline(
                vertices_m=np.zeros((0, 2)),
                edge_from=np.zeros(0, dtype=np.int64),
                edge_to=np.zeros(0, dtype=np.int64),
                part_starts=np.zeros(1, dtype=np.int64),
            )
        part_owner = np.array(owners, dtype=np.int64)
        sizes = np.diff(outline.part_starts)
        object.__setattr__(self, "dynamic_outline", outline)
        object.__setattr__(self, "part_owner", frozen_array(part_owner, np.int64))
        object.__setattr__(self, "edge_owner", frozen_array(np.repeat(part_owner, sizes), np.int64))
        object.__setattr__(self, "vertex_slices", tuple(slices))
        # Objects' models must store their parts in the same order Outline.from_parts keeps.
        for obj, (lo, hi) in zip(self.objects, slices, strict=True):
            if not np.array_equal(outline.vertices_m[lo:hi], obj.model.outline.vertices_m):
                raise ValueError(f"World {self.name}: {obj.name}'s outline is not CCW-normalised")

    @property
    def object_ids(self) -> IntArray:
        """Object ids in the order of :attr:`objects`."""
        return np.array([o.object_id for o in self.objects], dtype=np.int64)

    def object_vertices(self, t_s: FloatArray) -> FloatArray:
        """Every object's posed vertices at each of ``T`` instants, ``(T, V, 2)`` world frame."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        out = np.empty((t.shape[0], self.dynamic_outline.n_vertices, 2))
        for obj, (lo, hi) in zip(self.objects, self.vertex_slices, strict=True):
            st = obj.trajectory.at(t)
            body = obj.model.body_vertices(st["arc_m"], st["speed_mps"], st["articulation_rad"])
            out[:, lo:hi, :] = pose_points(body, st["x_m"], st["y_m"], st["heading_rad"])
        return out

    def object_polygons(self, t_s: float) -> list[list[FloatArray]]:
        """Each object's parts as world-frame polygons at one instant (plots, oracles)."""
        verts = self.object_vertices(np.array([t_s]))[0]
        out = []
        for obj, (lo, _hi) in zip(self.objects, self.vertex_slices, strict=True):
            s = obj.model.outline.part_starts
            out.append([verts[lo + s[p] : lo + s[p + 1]] for p in range(len(s) - 1)])
        return out


def structure_clearance(world: World, times_s: FloatArray, margin_m: float = 0.5) -> FloatArray:
    """Smallest distance of each object to the static structure over ``times_s``, ``(N,)``.

    0 means an object touched or overlapped a static part at one of the times. Only static
    parts whose bounding box comes within ``margin_m`` of the object's swept bounding box are
    examined (a distance beyond that is reported as at least ``margin_m``).
    """
    n = len(world.objects)
    out = np.full(n, np.inf)
    if n == 0 or world.structure.outline.n_parts == 0:
        return out
    verts_t = world.object_vertices(times_s)
    st = world.structure.outline
    sv = st.vertices_m
    starts = st.part_starts
    part_lo = np.minimum.reduceat(sv, starts[:-1], axis=0)
    part_hi = np.maximum.reduceat(sv, starts[:-1], axis=0)
    for index, (lo, hi) in enumerate(world.vertex_slices):
        v = verts_t[:, lo:hi, :]
        vlo = v.reshape(-1, 2).min(axis=0) - margin_m
        vhi = v.reshape(-1, 2).max(axis=0) + margin_m
        near = np.flatnonzero(np.all(part_lo <= vhi, axis=1) & np.all(part_hi >= vlo, axis=1))
        if near.size == 0:
            out[index] = margin_m
            continue
        sub = Outline.from_parts([sv[starts[p] : starts[p + 1]] for p in near])
        owners = np.zeros(sub.n_parts, dtype=np.int64)
        obj_outline = world.objects[index].model.outline
        best = np.inf
        for k in range(v.shape[0]):
            d = outline_distances(v[k], obj_outline, sub.vertices_m, sub, owners, 1)[0]
            best = min(best, float(d))
            if best == 0.0:
                break
        out[index] = min(best, margin_m) if np.isfinite(best) else margin_m
    return out
