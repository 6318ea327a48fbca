"""A simulated 4-D imaging radar: returns from the scene with RCS, SNR, elevation and Doppler,
multipath ghosts and ground clutter (SR-SIM-8).

Model (#24, Continental ARS548 class; each constant is a model parameter, named here):

* **targets**: every object whose nearest outline vertex lies within the field of view and
  range, seen along an unobstructed line (a mapped reflector between the radar and the target
  blocks it; objects do not block each other: a 77 GHz radar sees under and around vehicles
  often enough that this is the cautious choice for a filter's test). One return per object at
  that vertex, at the height of :data:`RETURN_HEIGHT_M`, with Gaussian range, azimuth and
  Doppler noise. Its RCS is :data:`RCS_DBSM` of its kind plus a uniform spread of
  +-:data:`RCS_SPREAD_DB`; its SNR ``SNR_AT_10M_DB + RCS - 40 log10(r / 10 m)`` (the radar
  equation's fourth power of range);
* **multipath ghosts**: a target's mirror image in each mapped reflector (a large metal surface:
  a hangar wall, a parked aircraft's fuselage) whose path radar -> reflector -> target is
  valid, :data:`GHOST_LOSS_DB` weaker, moving with the mirrored velocity;
* **ground clutter**: a Poisson number (mean ``clutter_per_scan``) of returns from the ground
  (height within 5 cm of it) at uniform range and bearing, weak (-25..0 dBsm), moving with the
  ground (static);
* the Doppler is the range rate ``u . (v_target - v_radar)`` with ``v_radar`` the mount's
  velocity (the robot's twist with the mount's lever arm); weather does not affect the radar.

:meth:`SimRadar.scan` returns the :class:`pipeline.types.RadarDetections` in the robot frame and
each return's truth (object id, :data:`GHOST_ID` or :data:`CLUTTER_ID`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.frames import to_child, to_parent
from pipeline.sources.sim.objects import ObjectKind
from pipeline.sources.sim.world import World
from pipeline.types import FloatArray, IntArray, RadarDetections
from pipeline.types.sensors import Twist

__all__ = ["CLUTTER_ID", "GHOST_ID", "RCS_DBSM", "RadarSpec", "SimRadar"]

GHOST_ID = -3
"""Truth of a multipath ghost."""

CLUTTER_ID = -4
"""Truth of a ground-clutter return."""

RCS_DBSM: dict[ObjectKind, float] = {
    ObjectKind.PERSON: -3.0,
    ObjectKind.AMR: 0.0,
    ObjectKind.CART: 5.0,
    ObjectKind.PALLET_JACK: 5.0,
    ObjectKind.DOLLY: 10.0,
    ObjectKind.COUNTERBALANCE_FORKLIFT: 15.0,
    ObjectKind.REACH_TRUCK: 15.0,
    ObjectKind.BAGGAGE_TUG: 15.0,
    ObjectKind.ULD_CONTAINER: 20.0,
}
"""Mean radar cross-section by kind [dBsm] at 77 GHz (model parameters)."""

RCS_SPREAD_DB = 3.0
SNR_AT_10M_DB = 30.0
"""SNR of a 0 dBsm target at 10 m [dB] (model parameter)."""
GHOST_LOSS_DB = 6.0
"""How much weaker a multipath ghost is than its target [dB] (model parameter)."""
RETURN_HEIGHT_M = 0.6
"""Height above the ground of an object's return [m]."""


@dataclass(frozen=True, slots=True)
class RadarSpec:
    """The radar's mount ``(x, y, z)`` [m] and yaw [rad] in the robot frame, field of view and
    range, noise, and mean clutter returns per scan."""

    mount_x_m: float = 0.45
    mount_y_m: float = 0.0
    mount_z_m: float = 0.5
    mount_yaw_rad: float = 0.0
    fov_rad: float = math.radians(120.0)
    max_range_m: float = 80.0
    range_std_m: float = 0.15
    azimuth_std_rad: float = math.radians(0.3)
    doppler_std_mps: float = 0.1
    clutter_per_scan: float = 5.0

    def __post_init__(self) -> None:
        values = (self.mount_x_m, self.mount_y_m, self.mount_z_m, self.mount_yaw_rad)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"RadarSpec: the mount must be finite, got {values}")
        if not (0.0 < self.fov_rad <= 2 * math.pi and self.max_range_m > 1.0):
            raise ValueError(f"RadarSpec: need 0 < fov <= 2 pi and range > 1 m, got {self}")
        if min(self.range_std_m, self.azimuth_std_rad, self.doppler_std_mps) < 0.0:
            raise ValueError("RadarSpec: noise must be >= 0")
        if not self.clutter_per_scan >= 0.0:
            raise ValueError("RadarSpec: clutter_per_scan must be >= 0")


def _crosses(ax: float, ay: float, bx: FloatArray, by: FloatArray, seg: FloatArray) -> FloatArray:
    """``(n, k)``: whether the segment from ``(ax, ay)`` to each ``(bx, by)`` crosses each
    reflector segment ``[x0, y0, x1, y1]`` (strictly inside both)."""
    dx, dy = (bx - ax)[:, None], (by - ay)[:, None]
    ex, ey = (seg[:, 2] - seg[:, 0])[None, :], (seg[:, 3] - seg[:, 1])[None, :]
    wx, wy = (seg[:, 0] - ax)[None, :], (seg[:, 1] - ay)[None, :]
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / denom
        s = (wx * dy - wy * dx) / denom
    out: FloatArray = (denom != 0.0) & (t > 0.0) & (t < 1.0) & (s > 0.0) & (s < 1.0)
    return out


class SimRadar:
    """Radar scans of a simulated world (module docstring); randomness from ``rng``."""

    def __init__(self, spec: RadarSpec, rng: np.random.Generator) -> None:
        self.spec = spec
        self._rng = rng

    def scan(
        self,
        world: World,
        t_s: float,
        ego_pose: tuple[float, float, float],
        twist: Twist,
        reflectors_m: FloatArray | None = None,
    ) -> tuple[RadarDetections, IntArray]:
        """Returns at ``t_s`` of the robot at ``ego_pose`` (world frame) moving at ``twist``;
        ``reflectors_m`` are segments ``(k, 4)`` in the world frame. The detections are in
        the robot frame; the truth gives each return's object id, ghost or clutter."""
        spec, rng = self.spec, self._rng
        seg = np.zeros((0, 4)) if reflectors_m is None else np.asarray(reflectors_m).reshape(-1, 4)
        mx, my = to_parent(ego_pose, np.array([spec.mount_x_m]), np.array([spec.mount_y_m]))
        m = (float(mx[0]), float(my[0]))
        # The mount's world velocity: the robot's twist plus the yaw rate times the lever arm.
        c, s = math.cos(ego_pose[2]), math.sin(ego_pose[2])
        vbx = twist.vx_mps - twist.yaw_rate_rps * spec.mount_y_m
        vby = twist.vy_mps + twist.yaw_rate_rps * spec.mount_x_m
        v_radar = (c * vbx - s * vby, s * vbx + c * vby)
        px, py, vx, vy, rcs, ids = [], [], [], [], [], []
        for obj, parts in zip(world.objects, world.object_polygons(t_s), strict=True):
            verts = np.concatenate(parts)
            near = int(np.argmin(np.hypot(verts[:, 0] - m[0], verts[:, 1] - m[1])))
            state = obj.trajectory.at(np.array([t_s]))
            px.append(float(verts[near, 0]))
            py.append(float(verts[near, 1]))
            vx.append(float(state["vx_mps"][0]))
            vy.append(float(state["vy_mps"][0]))
            spread = float(rng.uniform(-RCS_SPREAD_DB, RCS_SPREAD_DB))
            rcs.append(RCS_DBSM.get(obj.model.kind, 0.0) + spread)
            ids.append(obj.object_id)
        x, y = np.array(px), np.array(py)
        v = np.stack([np.array(vx), np.array(vy)], axis=1).reshape(-1, 2)
        rcs_a, id_a = np.array(rcs), np.array(ids, dtype=np.int64)
        seen = ~_crosses(m[0], m[1], x, y, seg).any(axis=1)
        gx, gy, gv, grcs = self._ghosts(m, x[seen], y[seen], v[seen], rcs_a[seen], seg)
        n_clutter = int(rng.poisson(spec.clutter_per_scan))
        r_c = rng.uniform(1.0, min(spec.max_range_m, 30.0), n_clutter)
        b_c = spec.mount_yaw_rad + ego_pose[2] + rng.uniform(-0.5, 0.5, n_clutter) * spec.fov_rad
        all_x = np.concatenate([x[seen], gx, m[0] + r_c * np.cos(b_c)])
        all_y = np.concatenate([y[seen], gy, m[1] + r_c * np.sin(b_c)])
        all_v = np.concatenate([v[seen], gv, np.zeros((n_clutter, 2))])
        all_rcs = np.concatenate([rcs_a[seen], grcs, rng.uniform(-25.0, 0.0, n_clutter)])
        truth = np.concatenate([id_a[seen], np.full(gx.shape[0], GHOST_ID),
                                np.full(n_clutter, CLUTTER_ID)]).astype(np.int64)  # fmt: skip
        height = np.concatenate([np.full(gx.shape[0] + int(seen.sum()), RETURN_HEIGHT_M),
                                 rng.uniform(-0.05, 0.05, n_clutter)])  # fmt: skip
        return self._measure(t_s, ego_pose, m, v_radar, all_x, all_y, all_v, all_rcs, height, truth)

    def _ghosts(
        self,
        m: tuple[float, float],
        x: FloatArray,
        y: FloatArray,
        v: FloatArray,
        rcs: FloatArray,
        seg: FloatArray,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Mirror images of the targets in the reflectors whose bounce path is valid."""
        out_x, out_y, out_v, out_rcs = [], [], [], []
        for x0, y0, x1, y1 in seg:
            ex, ey = x1 - x0, y1 - y0
            norm = math.hypot(ex, ey)
            if norm == 0.0:
                continue
            nx, ny = -ey / norm, ex / norm
            side_m = (m[0] - x0) * nx + (m[1] - y0) * ny
            side_t = (x - x0) * nx + (y - y0) * ny
            # Mirror across the reflector's line; valid when the target is on the radar's side
            # and the line to the image meets the reflector segment itself.
            gx, gy = x - 2 * side_t * nx, y - 2 * side_t * ny
            same = side_t * side_m > 0.0
            hit = _crosses(m[0], m[1], gx, gy, np.array([[x0, y0, x1, y1]]))[:, 0]
            ok = same & hit
            d = v[:, 0] * nx + v[:, 1] * ny
            gv = np.stack([v[:, 0] - 2 * d * nx, v[:, 1] - 2 * d * ny], axis=1)
            out_x.append(gx[ok])
            out_y.append(gy[ok])
            out_v.append(gv[ok])
            out_rcs.append(rcs[ok] - GHOST_LOSS_DB)
        if not out_x:
            return np.empty(0), np.empty(0), np.empty((0, 2)), np.empty(0)
        return (np.concatenate(out_x), np.concatenate(out_y), np.concatenate(out_v),
                np.concatenate(out_rcs))  # fmt: skip

    def _measure(
        self,
        t_s: float,
        ego_pose: tuple[float, float, float],
        m: tuple[float, float],
        v_radar: tuple[float, float],
        x: FloatArray,
        y: FloatArray,
        v: FloatArray,
        rcs: FloatArray,
        height: FloatArray,
        truth: IntArray,
    ) -> tuple[RadarDetections, IntArray]:
        """Range, bearing (robot frame), Doppler, elevation, SNR with noise; field of view and
        range applied to the true geometry."""
        spec, rng = self.spec, self._rng
        r = np.hypot(x - m[0], y - m[1])
        bearing_w = np.arctan2(y - m[1], x - m[0])
        off = np.angle(np.exp(1j * (bearing_w - ego_pose[2] - spec.mount_yaw_rad)))
        keep = (r > 0.2) & (r <= spec.max_range_m) & (np.abs(off) <= 0.5 * spec.fov_rad)
        r, bearing_w, v, rcs, height, truth = (
            a[keep] for a in (r, bearing_w, v, rcs, height, truth)
        )
        n = r.shape[0]
        u = np.stack([np.cos(bearing_w), np.sin(bearing_w)], axis=1)
        rate = np.sum(u * (v - np.array(v_radar)), axis=1)
        snr = SNR_AT_10M_DB + rcs - 40.0 * np.log10(np.maximum(r, 0.5) / 10.0)
        elevation = np.arcsin(np.clip((height - spec.mount_z_m) / r, -1.0, 1.0))
        # The mount's robot-frame position, and bearings relative to the robot's heading.
        lx, ly = to_child(ego_pose, np.array([m[0]]), np.array([m[1]]))
        detections = RadarDetections(
            stamp_s=np.full(n, t_s),
            range_m=r + rng.normal(0.0, spec.range_std_m, n),
            bearing_rad=bearing_w - ego_pose[2] + rng.normal(0.0, spec.azimuth_std_rad, n),
            radial_velocity_mps=rate + rng.normal(0.0, spec.doppler_std_mps, n),
            mount_x_m=float(lx[0]),
            mount_y_m=float(ly[0]),
            elevation_rad=elevation,
            rcs_dbsm=rcs,
            snr_db=snr,
        )
        return detections, truth
