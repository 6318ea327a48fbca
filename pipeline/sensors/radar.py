"""The radar's front-end: filtering, ego-motion compensation, Mahalanobis gating and the
position update by LiDAR degradation (SR-FUS-7).

**Filters** (airside recommendation #24), each return landing in one bin of
:class:`RadarCounts`: a return without finite values is invalid; below ``radar.min_rcs_dbsm``
(weak reflectors, anomalous multipath echoes) or ``radar.min_snr_db`` it is dropped; a return
lower than ``radar.min_height_m`` above the ground (its elevation from the mount's height) is
ground clutter; a return that lies more than ``radar.ghost_margin_m`` beyond a mapped large
reflector along its own ray is a multipath ghost (the mirror image of a real target seen via
that surface). The kept returns never see a track before these filters ran.

**Ego-motion compensation.** A radar at ``m`` on a robot moving at ``(vx, vy)`` and turning at
``w`` moves at ``v_r = (vx - w m_y, vy + w m_x)`` (robot frame). A return in unit direction ``u``
of a target moving at ``v_t`` measures the range rate ``u . (v_t - v_r)``; adding ``u . v_r``
leaves ``u . v_t``, the target's own velocity along the ray, which is what the tracker's state
(absolute velocity in the tracking frame) predicts. The return is then moved into the tracking
frame with the robot's pose (bearing plus yaw, mount and positions by the rigid transform), so a
moving robot can use the radar.

**Gating.** A return at ``z`` with range ``r`` and bearing ``b`` has the position covariance
``R = s_r^2 u u' + (r s_a)^2 v v'`` (``u`` along the ray, ``v`` across it); it may lie anywhere
on the target's body, which adds ``(e / 2)^2 I`` for a body of extent ``e`` (its larger box side).
It is feasible for a live track at ``x`` (taken to the return's stamp at the track's velocity)
with position covariance ``P`` when ``|z - x| <= track.gate_euclidean_m`` and
``d^2 = (z - x)' (P + R + E)^-1 (z - x) <= track.gate_mahalanobis_chi2``: the tracker's own
gates. Returns and tracks are matched one to one by the Hungarian assignment on ``d^2``.

**Weighting by LiDAR degradation.** The LiDAR's degradation index ``d`` of a scan is its share of
isolated returns near the scanner (points in no kept cluster nearer than
``radar.degraded_within_m``: fog backscatter, rain and spray) over
``radar.degraded_noise_fraction``, capped at 1. Only near ones count: an open apron in clear air
leaves 40-50 % of a scan's returns isolated at long range (sparse far structure), none of them
within 5 m, while fog puts 60-80 % of the returns there (docs/findings/sensors.md). From
``d >= radar.degraded_from`` the matched returns' positions also update their tracks, with
covariance ``(R + E) / d``: the radar is trusted more the worse the LiDAR sees; below it only
their Doppler does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.frames import Pose, is_identity, to_parent
from pipeline.types import BoolArray, FloatArray, RadarDetections
from pipeline.types.sensors import Twist

__all__ = [
    "RadarCounts",
    "RadarFrontEnd",
    "RadarGate",
    "degradation_index",
    "position_covariance",
    "position_update",
    "radar_costs",
]


@dataclass(frozen=True, slots=True)
class RadarGate:
    """What fusion needs to gate and weigh radar returns (module docstring): the radar's range
    and azimuth noise [m, rad], the tracker's gates [m, chi^2]."""

    range_std_m: float = 0.15
    azimuth_std_rad: float = math.radians(0.3)
    gate_m: float = 2.0
    gate_chi2: float = 9.21

    @staticmethod
    def from_config(config: SafecaseConfig) -> RadarGate:
        """The ``radar`` section's noise and the ``track`` section's gates."""
        return RadarGate(
            range_std_m=config.radar.range_std_m,
            azimuth_std_rad=math.radians(config.radar.azimuth_std_deg),
            gate_m=config.track.gate_euclidean_m,
            gate_chi2=config.track.gate_mahalanobis_chi2,
        )


def position_covariance(
    range_m: FloatArray, bearing_rad: FloatArray, range_std_m: float, azimuth_std_rad: float
) -> FloatArray:
    """Cartesian covariance ``(n, 2, 2)`` of returns measured in range and bearing."""
    u = np.stack([np.cos(bearing_rad), np.sin(bearing_rad)], axis=1)
    v = np.stack([-u[:, 1], u[:, 0]], axis=1)
    across = (range_m * azimuth_std_rad) ** 2
    out: FloatArray = range_std_m**2 * u[:, :, None] * u[:, None, :] + (
        across[:, None, None] * v[:, :, None] * v[:, None, :]
    )
    return out


def radar_costs(
    track_xy_m: FloatArray,
    track_pos_cov: FloatArray,
    extent_m: FloatArray,
    det_xy_m: FloatArray,
    det_cov: FloatArray,
    gate: RadarGate,
) -> FloatArray:
    """Cost matrix (returns x tracks): ``d^2`` where both gates pass, else inf (module
    docstring). ``track_xy_m`` (d, t, 2) are the tracks' positions at each return's stamp."""
    s = (
        track_pos_cov[None, :, :, :]
        + det_cov[:, None, :, :]
        + (0.25 * extent_m**2)[None, :, None, None] * np.eye(2)
    )
    r = det_xy_m[:, None, :] - track_xy_m
    det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
    d2 = (s[..., 1, 1] * r[..., 0] ** 2 - (s[..., 0, 1] + s[..., 1, 0]) * r[..., 0] * r[..., 1]
          + s[..., 0, 0] * r[..., 1] ** 2) / det  # fmt: skip
    near = r[..., 0] ** 2 + r[..., 1] ** 2 <= gate.gate_m * gate.gate_m
    out: FloatArray = np.where(near & (d2 <= gate.gate_chi2), d2, np.inf)
    return out


def position_update(
    x: FloatArray, p: FloatArray, z_m: FloatArray, r: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Kalman update of states ``x`` (n, 4) and covariances ``p`` (n, 4, 4) with positions
    ``z_m`` (n, 2) of covariances ``r`` (n, 2, 2): ``H = [I 0]``, Joseph form, like filterpy's
    ``KalmanFilter.update``."""
    s = p[:, :2, :2] + r
    s_inv = np.linalg.inv(s)
    k = np.matmul(p[:, :, :2], s_inv)
    y = z_m - x[:, :2]
    x_new = x + np.matmul(k, y[:, :, None])[:, :, 0]
    a = np.eye(4)[None] - np.concatenate([k, np.zeros_like(k)], axis=2)  # I - K H
    p_new = np.matmul(np.matmul(a, p), np.swapaxes(a, 1, 2)) + np.matmul(
        np.matmul(k, r), np.swapaxes(k, 1, 2)
    )
    return x_new, 0.5 * (p_new + np.swapaxes(p_new, 1, 2))


def degradation_index(
    range_m: FloatArray, isolated: BoolArray, within_m: float, full_fraction: float
) -> float:
    """The LiDAR degradation index of a scan (module docstring): the share of its valid returns
    (ranges ``range_m`` [m] from the scanner, ``isolated`` in no kept cluster) that are isolated
    and nearer than ``within_m``, over ``full_fraction``, capped at 1 (0 for a scan without
    valid returns). SR-FUS-7."""
    n_valid = int(range_m.shape[0])
    if isolated.shape != range_m.shape:
        raise ValueError(
            f"degradation_index: {isolated.shape[0]} isolated flags for {n_valid} returns"
        )
    if n_valid == 0:
        return 0.0
    near = int(np.count_nonzero(isolated & (range_m < within_m)))
    return min(1.0, (near / n_valid) / full_fraction)


@dataclass(frozen=True, slots=True)
class RadarCounts:
    """What the front-end did with one scan's returns; every return lands in one bin."""

    n_returns: int = 0
    n_invalid: int = 0
    n_low_rcs: int = 0
    n_low_snr: int = 0
    n_clutter: int = 0
    n_ghost: int = 0
    n_kept: int = 0

    def __post_init__(self) -> None:
        bins = (
            self.n_invalid, self.n_low_rcs, self.n_low_snr, self.n_clutter, self.n_ghost,
            self.n_kept,
        )  # fmt: skip
        if min(bins) < 0 or sum(bins) != self.n_returns:
            raise ValueError(f"RadarCounts: bins {bins} must sum to {self.n_returns}")


def _behind_reflectors(
    mount_xy: tuple[float, float], x_m: FloatArray, y_m: FloatArray, seg: FloatArray, margin: float
) -> BoolArray:
    """Returns farther than ``margin`` beyond a reflector segment crossing their ray."""
    if seg.shape[0] == 0 or x_m.shape[0] == 0:
        return np.zeros(x_m.shape[0], dtype=bool)
    ox, oy = mount_xy
    dx, dy = x_m - ox, y_m - oy  # ray from the radar to each return
    ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    wx, wy = seg[:, 0] - ox, seg[:, 1] - oy
    denom = dx[:, None] * ey[None, :] - dy[:, None] * ex[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx[None, :] * ey[None, :] - wy[None, :] * ex[None, :]) / denom  # along the ray
        s = (wx[None, :] * dy[:, None] - wy[None, :] * dx[:, None]) / denom  # along the segment
    length = np.hypot(dx, dy)
    crossed = (denom != 0.0) & (s >= 0.0) & (s <= 1.0) & (t > 0.0)
    beyond = (1.0 - t) * length[:, None] > margin
    out: BoolArray = (crossed & beyond).any(axis=1)
    return out


class RadarFrontEnd:
    """Filters, compensates and frames one radar scan (module docstring)."""

    def __init__(self, config: SafecaseConfig) -> None:
        self.section = config.radar

    def filter(
        self, radar: RadarDetections, pose: Pose, reflectors_m: FloatArray | None
    ) -> tuple[BoolArray, RadarCounts]:
        """Which returns survive the filters, and the counts. ``reflectors_m`` are segments in
        the tracking frame placed by ``pose``."""
        c = self.section
        n = radar.n
        with np.errstate(invalid="ignore"):
            valid = (
                np.isfinite(radar.stamp_s)
                & np.isfinite(radar.range_m)
                & np.isfinite(radar.bearing_rad)
                & np.isfinite(radar.radial_velocity_mps)
                & (radar.range_m >= 0.0)
            )
        nan = np.full(n, np.nan)
        rcs = nan if radar.rcs_dbsm is None else radar.rcs_dbsm
        snr = nan if radar.snr_db is None else radar.snr_db
        # A value not reported is not filtered on; a reported non-finite one fails.
        low_rcs = valid & (radar.rcs_dbsm is not None) & ~(rcs >= c.min_rcs_dbsm)
        low_snr = valid & ~low_rcs & (radar.snr_db is not None) & ~(snr >= c.min_snr_db)
        rest = valid & ~low_rcs & ~low_snr
        clutter = np.zeros(n, dtype=bool)
        if radar.elevation_rad is not None:
            height = c.mount_z_m + radar.range_m * np.sin(radar.elevation_rad)
            clutter = rest & ~(height >= c.min_height_m)
        rest &= ~clutter
        ghost = np.zeros(n, dtype=bool)
        if reflectors_m is not None and rest.any():
            idx = np.flatnonzero(rest)
            x, y = to_parent(pose, radar.x_m[idx], radar.y_m[idx])
            mx, my = to_parent(pose, np.array([radar.mount_x_m]), np.array([radar.mount_y_m]))
            ghost[idx] = _behind_reflectors(
                (float(mx[0]), float(my[0])), x, y, reflectors_m, c.ghost_margin_m
            )
        kept = rest & ~ghost
        counts = RadarCounts(
            n_returns=n,
            n_invalid=int(np.count_nonzero(~valid)),
            n_low_rcs=int(np.count_nonzero(low_rcs)),
            n_low_snr=int(np.count_nonzero(low_snr)),
            n_clutter=int(np.count_nonzero(clutter)),
            n_ghost=int(np.count_nonzero(ghost)),
            n_kept=int(np.count_nonzero(kept)),
        )
        return kept, counts

    def in_tracking_frame(
        self,
        radar: RadarDetections,
        kept: BoolArray,
        pose: Pose,
        twist: Twist | None,
        degradation: float,
    ) -> RadarDetections:
        """The kept returns in the tracking frame, Doppler compensated for the robot's motion,
        with the position weight the LiDAR's ``degradation`` index gives (module docstring).
        Raises ValueError when the robot's pose is not the identity and its velocity is
        unknown (the Doppler cannot be compensated)."""
        if twist is None and not is_identity(pose):
            raise ValueError(
                "radar: the robot's velocity (odometry twist) is needed to take its own motion "
                "out of the Doppler; the frame has a pose but no twist"
            )
        idx = np.flatnonzero(kept)
        b = radar.bearing_rad[idx]
        rate = radar.radial_velocity_mps[idx]
        if twist is not None:
            w = twist.yaw_rate_rps
            vrx = twist.vx_mps - w * radar.mount_y_m
            vry = twist.vy_mps + w * radar.mount_x_m
            rate = rate + np.cos(b) * vrx + np.sin(b) * vry
        mx, my = to_parent(pose, np.array([radar.mount_x_m]), np.array([radar.mount_y_m]))
        weight = degradation if degradation >= self.section.degraded_from else 0.0
        return RadarDetections(
            stamp_s=radar.stamp_s[idx],
            range_m=radar.range_m[idx],
            bearing_rad=b + pose[2],
            radial_velocity_mps=rate,
            mount_x_m=float(mx[0]),
            mount_y_m=float(my[0]),
            position_weight=np.full(idx.shape[0], weight),
        )
