"""A simulated LWIR camera: apparent-temperature frames rendered from the scene (SR-SIM-7).

The camera (:class:`pipeline.sensors.camera.PinholeCamera`, #22: 640 x 512 px, 32 deg, 30 Hz)
looks at a world whose objects stand on the ground with the heights of :data:`APPEARANCE`
(:data:`STRUCTURE_APPEARANCE` for static parts). A frame is painted far to near:

* **background**, row by row: the sky above the horizon (:attr:`Weather.sky_c`), below it the
  ground (:attr:`Weather.ground_c`) seen through the air along the centre column's ray;
* **bodies and vehicles**, each the screen rectangle spanning its outline's vertices from the
  ground to its height (a person: a 0.5 m wide figure facing the camera). A person's clothes
  show ``ambient + 0.6 (34 - ambient)`` and the head (the top eighth) 34 C; metal shows the
  air's temperature plus the sun's load by day (1 C below the air at night, radiating to the
  sky); an idling tug's exhaust at its rear shows 250 C. By day, sunlit strips of asphalt are
  ``0.8 sun_load`` above the air;
* every surface's difference to the air fades over its distance ``d`` as
  ``exp(-beta d)`` (:attr:`Weather.lwir_extinction_per_m`); water on the window
  (``lens_contamination`` c) scales every difference to the air by ``1 - c``; each pixel gets
  Gaussian noise of the camera's NETD.

The renderer is given the camera's true extrinsic, which may differ from the configured one by
a calibration error (:meth:`pipeline.sensors.camera.PinholeCamera.perturbed`): the camera
renders with the true one while the detector projects with the configured one.
:meth:`ThermalRenderer.people` tells, for measurements, how much of each person the camera can
see.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.frames import to_child
from pipeline.sensors.camera import PinholeCamera
from pipeline.sources.sim.objects import ObjectKind
from pipeline.sources.sim.weather import Weather
from pipeline.sources.sim.world import World
from pipeline.types import FloatArray
from pipeline.types.sensors import ThermalImage

__all__ = ["APPEARANCE", "STRUCTURE_APPEARANCE", "Appearance", "PersonView", "ThermalRenderer"]

BODY_CORE_C = 34.0
"""Skin temperature of the face [deg C] (core 37 C)."""

CLOTHING_SHARE = 0.6
"""Share of the skin-to-air difference that clothing shows."""

EXHAUST_C = 250.0
"""An idling diesel tug's exhaust pipe [deg C]."""

PERSON_WIDTH_M = 0.5


@dataclass(frozen=True, slots=True)
class Appearance:
    """How a kind of thing looks to a thermal camera: height [m], surface (``body``, ``metal``,
    ``warm`` electronics at ``air + 4``, ``plain`` at ``air + 0.3 sun``) and, for engines, the
    exhaust's body-frame position ``(x_m, y_m)``."""

    height_m: float
    surface: str
    exhaust: tuple[float, float] | None = None


APPEARANCE: dict[ObjectKind, Appearance] = {
    ObjectKind.PERSON: Appearance(1.75, "body"),
    ObjectKind.COUNTERBALANCE_FORKLIFT: Appearance(2.1, "metal"),
    ObjectKind.REACH_TRUCK: Appearance(2.4, "metal"),
    ObjectKind.PALLET_JACK: Appearance(1.2, "metal"),
    ObjectKind.CART: Appearance(1.0, "plain"),
    ObjectKind.AMR: Appearance(0.45, "warm"),
    ObjectKind.BAGGAGE_TUG: Appearance(1.6, "metal", exhaust=(-1.45, -0.45)),
    ObjectKind.DOLLY: Appearance(1.1, "metal"),
    ObjectKind.ULD_CONTAINER: Appearance(1.63, "metal"),
}

STRUCTURE_APPEARANCE: dict[str, Appearance] = {
    "wall": Appearance(4.0, "plain"),
    "rack_upright": Appearance(4.0, "metal"),
    "pallet_load": Appearance(1.2, "plain"),
    "cone": Appearance(0.5, "plain"),
    "gpu": Appearance(1.5, "metal"),
    "aircraft_tyre": Appearance(1.17, "plain"),
    "passenger_stairs": Appearance(3.0, "metal"),
}
_DEFAULT = Appearance(1.0, "plain")


def _surface_c(surface: str, weather: Weather) -> float:
    air, sun = weather.ambient_c, weather.sun_c
    if surface == "body":
        return air + CLOTHING_SHARE * (BODY_CORE_C - air)
    if surface == "metal":
        return air + sun if sun > 0.0 else air - 1.0
    if surface == "warm":
        return air + 4.0
    return air + 0.3 * sun


@dataclass(frozen=True, slots=True)
class PersonView:
    """How the camera sees a person: whether the figure is in the image at all, the fraction
    of it not covered by anything nearer, whether no other person's figure comes within a
    pixel of it (so that the detector can see it as one component of its own), and whether the
    whole figure lies inside the image (not cut by an edge)."""

    in_image: bool
    visible_fraction: float
    isolated: bool
    whole_in_frame: bool


@dataclass(frozen=True, slots=True)
class _Patch:
    """A rectangle to paint: rows, columns, temperature, distance [m]; ``head`` rows at the top
    of a body."""

    v0: int
    v1: int
    u0: int
    u1: int
    temp_c: float
    distance_m: float
    head: int = 0
    clipped: bool = False


class ThermalRenderer:
    """Renders frames of ``world`` in ``weather`` with ``camera`` (the true extrinsic) and
    ``netd_c`` pixel noise from ``rng``; ``sunlit_m`` are ground rectangles ``(k, 4)``
    ``[x0, x1, y0, y1]`` (world frame) of sunlit asphalt."""

    def __init__(
        self,
        world: World,
        weather: Weather,
        camera: PinholeCamera,
        netd_c: float,
        rng: np.random.Generator,
        sunlit_m: FloatArray | None = None,
    ) -> None:
        self.world = world
        self.weather = weather
        self.camera = camera
        self.netd_c = netd_c
        self._rng = rng
        self._sunlit = np.zeros((0, 4)) if sunlit_m is None else np.asarray(sunlit_m)
        self._background = self._rows()

    def _rows(self) -> FloatArray:
        """Background temperature of each row (sky or ground through the air), ``(H, 1)``."""
        cam, w = self.camera, self.weather
        v = np.arange(cam.height_px, dtype=np.float64) + 0.5
        x, y, ground = cam.ground_point(np.full_like(v, cam.cx), v)
        f, lft, _ = cam.camera_offsets(x, y, np.zeros_like(x))
        fade = np.exp(-w.lwir_extinction_per_m * np.where(ground, np.hypot(f, lft), 0.0))
        out = np.where(ground, w.ambient_c + (w.ground_c - w.ambient_c) * fade, w.sky_c)
        return out[:, None]

    def _patch(
        self, x_m: FloatArray, y_m: FloatArray, z0_m: float, z1_m: float, temp_c: float
    ) -> _Patch | None:
        """The screen rectangle of robot-frame footprint points from height z0 to z1."""
        cam = self.camera
        xs = np.concatenate([x_m, x_m])
        ys = np.concatenate([y_m, y_m])
        zs = np.concatenate([np.full_like(x_m, z0_m), np.full_like(x_m, z1_m)])
        u, v, depth = cam.project(xs, ys, zs)
        seen = depth > 0.2
        if not seen.any():
            return None
        box = (
            math.floor(float(u[seen].min())),
            math.ceil(float(u[seen].max())),
            math.floor(float(v[seen].min())),
            math.ceil(float(v[seen].max())),
        )
        u0, u1 = max(box[0], 0), min(box[1], cam.width_px)
        v0, v1 = max(box[2], 0), min(box[3], cam.height_px)
        if u0 >= u1 or v0 >= v1:
            return None
        f, lft, _ = cam.camera_offsets(x_m, y_m, np.zeros_like(x_m))
        distance = float(np.hypot(f, lft).min())
        clipped = not seen.all() or (u0, u1, v0, v1) != box
        return _Patch(v0, v1, u0, u1, temp_c, distance, clipped=clipped)

    def _patches(self, t_s: float, ego_pose: tuple[float, float, float]) -> list[_Patch]:
        w = self.weather
        out: list[_Patch] = []
        st = self.world.structure
        for kind, part in zip(st.part_kinds, st.outline.parts(), strict=True):
            look = STRUCTURE_APPEARANCE.get(kind, _DEFAULT)
            px, py = to_child(ego_pose, part[:, 0], part[:, 1])
            patch = self._patch(px, py, 0.0, look.height_m, _surface_c(look.surface, w))
            if patch is not None:
                out.append(patch)
        polygons = self.world.object_polygons(t_s)
        for obj, parts in zip(self.world.objects, polygons, strict=True):
            look = APPEARANCE.get(obj.model.kind, _DEFAULT)
            state = obj.trajectory.at(np.array([t_s]))
            cx, cy, heading = (float(state[k][0]) for k in ("x_m", "y_m", "heading_rad"))
            if look.surface == "body":
                rx, ry = to_child(ego_pose, np.array([cx]), np.array([cy]))
                px, py = self._facing(float(rx[0]), float(ry[0]))
                patch = self._patch(px, py, 0.0, look.height_m, _surface_c("body", w))
                if patch is not None:
                    head = max(1, (patch.v1 - patch.v0) // 8)
                    patch = _Patch(*_fields(patch)[:-2], head=head, clipped=patch.clipped)
            else:
                verts = np.concatenate(parts)
                px, py = to_child(ego_pose, verts[:, 0], verts[:, 1])
                patch = self._patch(px, py, 0.0, look.height_m, _surface_c(look.surface, w))
            if patch is None:
                continue
            out.append(patch)
            if look.exhaust is not None:
                hot = self._exhaust(look.exhaust, (cx, cy, heading), ego_pose, patch.distance_m)
                if hot is not None:
                    out.append(hot)
        if not w.night and w.sun_c > 0.0:
            for x0, x1, y0, y1 in self._sunlit:
                gx, gy = to_child(ego_pose, np.array([x0, x1, x1, x0]), np.array([y0, y0, y1, y1]))
                hot = self._patch(gx, gy, 0.0, 0.0, w.ambient_c + 0.8 * w.sun_c)
                if hot is not None:
                    out.append(hot)
        out.sort(key=lambda p: -p.distance_m)
        return out

    def _facing(self, x_m: float, y_m: float) -> tuple[FloatArray, FloatArray]:
        """A person's figure: a 0.5 m segment across the camera's line of sight."""
        cam = self.camera
        dx, dy = x_m - cam.mount_x_m, y_m - cam.mount_y_m
        norm = max(math.hypot(dx, dy), 1e-9)
        half = 0.5 * PERSON_WIDTH_M
        px, py = -dy / norm * half, dx / norm * half
        return np.array([x_m - px, x_m + px]), np.array([y_m - py, y_m + py])

    def _exhaust(
        self,
        at: tuple[float, float],
        pose: tuple[float, float, float],
        ego_pose: tuple[float, float, float],
        body_distance_m: float,
    ) -> _Patch | None:
        """The exhaust pipe's patch, when it is on the camera's side of the vehicle."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        wx = pose[0] + c * at[0] - s * at[1]
        wy = pose[1] + s * at[0] + c * at[1]
        rx, ry = to_child(ego_pose, np.array([wx - 0.12, wx + 0.12]), np.array([wy, wy]))
        cam = self.camera
        centre = to_child(ego_pose, np.array([pose[0]]), np.array([pose[1]]))
        f, lft, _ = cam.camera_offsets(centre[0], centre[1], np.zeros(1))
        patch = self._patch(rx, ry, 0.3, 0.6, EXHAUST_C)
        if patch is None or patch.distance_m > float(np.hypot(f, lft)[0]):
            return None  # on the far side of the vehicle
        return _Patch(*_fields(patch)[:-3], min(patch.distance_m, body_distance_m) - 1e-3)

    def render(self, t_s: float, ego_pose: tuple[float, float, float]) -> ThermalImage:
        """The frame captured at ``t_s`` with the robot at ``ego_pose`` (world frame)."""
        cam, w = self.camera, self.weather
        air = w.ambient_c
        img = np.empty((cam.height_px, cam.width_px), dtype=np.float32)
        img[:] = self._background
        beta = w.lwir_extinction_per_m
        for p in self._patches(t_s, ego_pose):
            fade = math.exp(-beta * p.distance_m)
            img[p.v0 : p.v1, p.u0 : p.u1] = air + (p.temp_c - air) * fade
            if p.head:
                img[p.v0 : p.v0 + p.head, p.u0 : p.u1] = air + (BODY_CORE_C - air) * fade
        if w.lens_contamination > 0.0:
            img = np.float32(air) + (img - np.float32(air)) * np.float32(1.0 - w.lens_contamination)
        img += np.float32(self.netd_c) * self._rng.standard_normal(img.shape, dtype=np.float32)
        return ThermalImage(t_s, img)

    def people(self, t_s: float, ego_pose: tuple[float, float, float]) -> dict[int, PersonView]:
        """How the camera sees each person (object id) at ``t_s`` (:class:`PersonView`)."""
        patches = self._patches(t_s, ego_pose)
        figures: dict[int, _Patch | None] = {}
        for obj in self.world.objects:
            if obj.model.kind is ObjectKind.PERSON:
                state = obj.trajectory.at(np.array([t_s]))
                rx, ry = to_child(ego_pose, state["x_m"], state["y_m"])
                px, py = self._facing(float(rx[0]), float(ry[0]))
                height = APPEARANCE[ObjectKind.PERSON].height_m
                figures[obj.object_id] = self._patch(px, py, 0.0, height, 0.0)
        out: dict[int, PersonView] = {}
        for key, me in figures.items():
            if me is None:
                out[key] = PersonView(False, 0.0, False, False)
                continue
            free = np.ones((me.v1 - me.v0, me.u1 - me.u0), dtype=bool)
            for p in patches:
                if p.distance_m < me.distance_m - 1e-6:
                    r0, r1 = max(p.v0, me.v0) - me.v0, min(p.v1, me.v1) - me.v0
                    c0, c1 = max(p.u0, me.u0) - me.u0, min(p.u1, me.u1) - me.u0
                    if r0 < r1 and c0 < c1:
                        free[r0:r1, c0:c1] = False
            alone = all(
                other is None
                or other.u0 > me.u1 + 1
                or other.u1 < me.u0 - 1
                or other.v0 > me.v1 + 1
                or other.v1 < me.v0 - 1
                for k, other in figures.items()
                if k != key
            )
            out[key] = PersonView(True, float(free.mean()), alone, not me.clipped)
        return out


def _fields(p: _Patch) -> tuple[int, int, int, int, float, float, int, bool]:
    return (p.v0, p.v1, p.u0, p.u1, p.temp_c, p.distance_m, p.head, p.clipped)
