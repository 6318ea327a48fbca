"""Thermal and radar detections fused into the LiDAR tracks, with freshness (SR-FUS-1, SR-FUS-3).

Freshness
---------
Fusion is given the freshness guard, a safety formula proved with z3
(:func:`safety.model.freshness.is_fresh`, the role :class:`pipeline.roles.FreshnessGuard`);
a detection is used at decision time ``now_s`` only where the guard says it is fresh for the
sensor's maximum age and the configured clock skew (SR-FUS-1).

Fusion
------
Fresh thermal detections are matched one-to-one to live (not dormant) tracks whose position,
taken back to the detection's stamp at the track's velocity, lies within ``fusion.gate_m``:
the global nearest-neighbour assignment (:func:`pipeline.track.associate.assign` on squared
distances). A match raises the track's confidence by ``fusion.confidence_boost`` (capped at 1);
an unmatched fresh detection becomes a thermal-only pedestrian whose confidence is below
``classify.medium_confidence_min``, so the governor gives it the most cautious margin tier.
Fresh radar returns are matched the same way (Euclidean, ``fusion.gate_m``) unless a
:class:`pipeline.sensors.radar.RadarGate` is given: then returns already filtered and moved
into the tracking frame by the radar's front-end (:mod:`pipeline.sensors.radar`) are matched
one-to-one to live tracks within the tracker's own gates, Euclidean and Mahalanobis with the
return's and the body's extent in the covariance (:func:`pipeline.sensors.radar.radar_costs`,
SR-FUS-7), and where the front-end gave a return a position weight (a degraded LiDAR) its
position updates the track too (:func:`pipeline.sensors.radar.position_update`). A match's
Doppler range rate updates the track's state (:func:`doppler_update`); radar alone never
creates an object. Stale detections are counted and skipped: the cycle falls back to LiDAR only
(:attr:`FusionCounts.lidar_only`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pipeline.config import FusionSection
from pipeline.errors import SafecaseError
from pipeline.frames import is_identity, to_parent
from pipeline.roles import FreshnessGuard
from pipeline.sensors.radar import RadarGate, position_covariance, position_update, radar_costs
from pipeline.track.associate import assign
from pipeline.types import (
    BoolArray,
    FloatArray,
    FusedTracks,
    FusionCounts,
    IntArray,
    Pose,
    RadarDetections,
    ThermalDetections,
    Tracks,
    TrackStatus,
)

__all__ = [
    "FusionError",
    "GatedFusion",
    "doppler_row",
    "doppler_update",
    "fuse",
    "thermal_in_frame",
]

_LIVE = (TrackStatus.TENTATIVE, TrackStatus.CONFIRMED, TrackStatus.LOST)


class FusionError(SafecaseError, ValueError):
    """Fusion input that does not fit the tracks (a confidence array of the wrong length)."""


def thermal_in_frame(thermal: ThermalDetections, pose: Pose) -> ThermalDetections:
    """Thermal detections moved from the robot frame at ``pose`` into the tracking frame."""
    if is_identity(pose):
        return thermal
    x_m, y_m = to_parent(pose, thermal.x_m, thermal.y_m)
    return ThermalDetections(
        stamp_s=thermal.stamp_s, x_m=x_m, y_m=y_m, confidence=thermal.confidence
    )


def doppler_row(bearing_rad: FloatArray) -> FloatArray:
    """Measurement rows ``H`` (n, 4) of Doppler range rates for the CV state [x, y, vx, vy].

    A target at bearing ``b`` from the radar moving at ``(vx, vy)`` relative to it has range
    rate ``cos(b) vx + sin(b) vy``: linear in the state once the measured bearing is fixed, so
    the update is an ordinary Kalman update with ``H = [0, 0, cos b, sin b]``.
    """
    h = np.zeros((bearing_rad.shape[0], 4))
    h[:, 2] = np.cos(bearing_rad)
    h[:, 3] = np.sin(bearing_rad)
    return h


def doppler_update(
    x: FloatArray,
    p: FloatArray,
    bearing_rad: FloatArray,
    radial_velocity_mps: FloatArray,
    std_mps: float,
) -> tuple[FloatArray, FloatArray]:
    """Kalman update of states ``x`` (n, 4) and covariances ``p`` (n, 4, 4) with one Doppler
    range rate each [m/s] of standard deviation ``std_mps`` (SR-FUS-1).

    Scalar measurement ``z = H x + noise`` with ``H`` from :func:`doppler_row`; the covariance
    uses the Joseph form ``(I - K H) P (I - K H)' + K R K'`` like filterpy's ``KalmanFilter``
    (checked against it to 1e-9), batched over the leading axis.
    """
    h = doppler_row(bearing_rad)
    r = std_mps * std_mps
    ph = np.einsum("nij,nj->ni", p, h)  # P H'
    s = np.einsum("ni,ni->n", h, ph) + r
    k = ph / s[:, None]
    y = radial_velocity_mps - np.einsum("ni,ni->n", h, x)
    x_new = x + k * y[:, None]
    hp = np.einsum("ni,nij->nj", h, p)  # H P
    ap = p - k[:, :, None] * hp[:, None, :]  # (I - K H) P
    aph = np.einsum("nij,nj->ni", ap, h)
    p_new = ap - aph[:, :, None] * k[:, None, :] + r * k[:, :, None] * k[:, None, :]
    return x_new, 0.5 * (p_new + np.swapaxes(p_new, 1, 2))


def _classify_ages(
    guard: FreshnessGuard,
    now_s: float,
    stamp_s: FloatArray,
    valid: BoolArray,
    max_age_s: float,
    skew_s: float,
) -> tuple[BoolArray, int, int]:
    """Fresh mask among ``valid`` entries, and the counts of stale and future ones."""
    fresh = valid & guard(now_s, stamp_s, max_age_s, skew_s)
    with np.errstate(invalid="ignore"):
        future = valid & ~fresh & (now_s - stamp_s < -skew_s)
    return fresh, int(np.count_nonzero(valid & ~fresh & ~future)), int(np.count_nonzero(future))


def _cap(fresh: BoolArray, x_m: FloatArray, y_m: FloatArray, cap: int) -> tuple[IntArray, int]:
    """Indices of the fresh detections kept (nearest ``cap`` to the robot) and the overflow."""
    idx = np.flatnonzero(fresh)
    if idx.shape[0] <= cap:
        return idx.astype(np.int64), 0
    order = np.argsort(np.hypot(x_m[idx], y_m[idx]), kind="stable")
    return np.sort(idx[order[:cap]]).astype(np.int64), int(idx.shape[0] - cap)


def _gated_match(
    tracks: Tracks,
    live: IntArray,
    det_x_m: FloatArray,
    det_y_m: FloatArray,
    det_stamp_s: FloatArray,
    gate_m: float,
) -> tuple[IntArray, IntArray]:
    """One-to-one nearest-neighbour pairs (detection, track) within ``gate_m``.

    Each live track's position is taken back (or forward) to the detection's stamp at its
    filtered velocity before measuring the distance.
    """
    if det_x_m.shape[0] == 0 or live.shape[0] == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty
    state = tracks.state[live]
    dt = det_stamp_s[:, None] - tracks.stamp_s
    dx = det_x_m[:, None] - (state[None, :, 0] + state[None, :, 2] * dt)
    dy = det_y_m[:, None] - (state[None, :, 1] + state[None, :, 3] * dt)
    d2 = dx * dx + dy * dy
    rows, cols = assign(np.where(d2 <= gate_m * gate_m, d2, np.inf))
    return rows, live[cols]


def _gated_radar(
    now_s: float,
    tracks: Tracks,
    live: IntArray,
    radar: RadarDetections,
    valid: BoolArray,
    f: FusionSection,
    guard: FreshnessGuard,
    gate: RadarGate,
) -> tuple[IntArray, IntArray, IntArray, FloatArray, dict[str, int]]:
    """Freshness, cap and one-to-one matching of radar returns within the tracker's gates
    (module docstring, SR-FUS-7): the kept returns, the positions in that list that matched,
    the tracks they matched, each kept return's position covariance, and the counts."""
    fresh, stale, future = _classify_ages(
        guard, now_s, radar.stamp_s, valid, f.radar_max_age_s, f.clock_skew_s
    )
    # The cap keeps the returns nearest the radar.
    kept, over = _cap(fresh, radar.range_m, np.zeros(radar.n), f.max_radar)
    det_cov = position_covariance(
        radar.range_m[kept], radar.bearing_rad[kept], gate.range_std_m, gate.azimuth_std_rad
    )
    rows = cols = np.empty(0, dtype=np.int64)
    if kept.shape[0] and live.shape[0]:
        state = tracks.state[live]
        dt = radar.stamp_s[kept][:, None] - tracks.stamp_s
        xy = state[None, :, :2] + state[None, :, 2:] * dt[:, :, None]
        extent = np.nan_to_num(np.maximum(tracks.length_m[live], tracks.width_m[live]))
        det_xy = np.stack([radar.x_m[kept], radar.y_m[kept]], axis=1)
        cost = radar_costs(xy, tracks.covariance[live, :2, :2], extent, det_xy, det_cov, gate)
        rows, cols = assign(cost)
    counts = {
        "n_radar": radar.n,
        "n_radar_invalid": int(np.count_nonzero(~valid)),
        "n_radar_stale": stale,
        "n_radar_future": future,
        "n_radar_over_cap": over,
        "n_radar_matched": int(rows.shape[0]),
    }
    return kept, rows, live[cols], det_cov, counts


def _sort_detections(
    sensor: str,
    now_s: float,
    tracks: Tracks,
    live: IntArray,
    stamp_s: FloatArray,
    x_m: FloatArray,
    y_m: FloatArray,
    valid: BoolArray,
    max_age_s: float,
    cap: int,
    f: FusionSection,
    guard: FreshnessGuard,
) -> tuple[IntArray, IntArray, IntArray, dict[str, int]]:
    """Freshness, cap and gated matching of one sensor's detections.

    Returns the kept (fresh, within the cap) detection indices, the positions in that list
    that matched, the tracks they matched, and the counts named ``n_<sensor>_*``.
    """
    fresh, stale, future = _classify_ages(guard, now_s, stamp_s, valid, max_age_s, f.clock_skew_s)
    kept, over = _cap(fresh, x_m, y_m, cap)
    rows, matched = _gated_match(tracks, live, x_m[kept], y_m[kept], stamp_s[kept], f.gate_m)
    counts = {
        f"n_{sensor}": int(stamp_s.shape[0]),
        f"n_{sensor}_invalid": int(np.count_nonzero(~valid)),
        f"n_{sensor}_stale": stale,
        f"n_{sensor}_future": future,
        f"n_{sensor}_over_cap": over,
        f"n_{sensor}_matched": int(rows.shape[0]),
    }
    return kept, rows, matched, counts


def fuse(
    now_s: float,
    tracks: Tracks,
    section: FusionSection,
    *,
    guard: FreshnessGuard,
    confidence: FloatArray | None = None,
    thermal: ThermalDetections | None = None,
    radar: RadarDetections | None = None,
    radar_gate: RadarGate | None = None,
) -> FusedTracks:
    """Fuse fresh thermal and radar detections into ``tracks`` at decision time ``now_s`` [s].

    ``confidence`` is the classifier's per-track confidence in [0, 1] (default: unknown, 0;
    non-finite values count as 0). Serves SR-FUS-1 (only fresh detections are fused; stale
    ones give the LiDAR-only fallback) and SR-FUS-3 (unmatched fresh thermal detections become
    low-confidence pedestrians). Raises :class:`FusionError` when ``confidence`` does not have
    one entry per track. ``guard`` decides freshness (:class:`pipeline.roles.FreshnessGuard`);
    ``radar_gate`` (the radar's noise and the tracker's gates) selects the front-end's gating
    and position weighting (SR-FUS-7); None keeps the Euclidean gate.
    """
    f = section
    n = tracks.n
    if confidence is None:
        base = np.zeros(n)
    else:
        base = np.asarray(confidence, dtype=np.float64)
        if base.shape != (n,):
            raise FusionError(
                f"fuse: confidence has shape {base.shape}; expected one value per track ({n},)"
            )
        base = np.where(np.isfinite(base), np.clip(base, 0.0, 1.0), 0.0)
    live = np.flatnonzero(tracks.with_status(*_LIVE)).astype(np.int64)
    conf = base.copy()
    thermal_index = np.full(n, -1, dtype=np.int64)
    radar_index = np.full(n, -1, dtype=np.int64)

    thermal = thermal or ThermalDetections(np.empty(0), np.empty(0), np.empty(0), np.empty(0))
    valid = np.isfinite(thermal.stamp_s) & np.isfinite(thermal.x_m) & np.isfinite(thermal.y_m)
    kept, rows, matched, counts = _sort_detections(
        "thermal", now_s, tracks, live, thermal.stamp_s, thermal.x_m, thermal.y_m, valid,
        f.thermal_max_age_s, f.max_thermal, f, guard,
    )  # fmt: skip
    conf[matched] = np.minimum(conf[matched] + f.confidence_boost, 1.0)
    thermal_index[matched] = kept[rows]
    unmatched = np.ones(kept.shape[0], dtype=bool)
    unmatched[rows] = False
    ped = kept[unmatched]
    # The detector's own score only ever lowers a pedestrian's confidence (NaN: ignored).
    ped_conf = np.clip(np.fmin(thermal.confidence[ped], f.thermal_only_confidence), 0.0, None)
    counts["n_thermal_only"] = int(ped.shape[0])

    state, cov = tracks.state, tracks.covariance
    if radar is not None and radar.n:
        rx, ry = radar.x_m, radar.y_m
        with np.errstate(invalid="ignore"):
            valid = (
                np.isfinite(radar.stamp_s)
                & np.isfinite(rx)
                & np.isfinite(ry)
                & np.isfinite(radar.radial_velocity_mps)
                & (radar.range_m >= 0.0)
            )
        det_cov = np.empty((0, 2, 2))
        if radar_gate is None:
            kept, rows, matched, radar_counts = _sort_detections(
                "radar", now_s, tracks, live, radar.stamp_s, rx, ry, valid,
                f.radar_max_age_s, f.max_radar, f, guard,
            )  # fmt: skip
        else:
            kept, rows, matched, det_cov, radar_counts = _gated_radar(
                now_s, tracks, live, radar, valid, f, guard, radar_gate
            )
        if rows.shape[0]:
            used = kept[rows]
            new_x, new_p = doppler_update(
                state[matched],
                cov[matched],
                radar.bearing_rad[used],
                radar.radial_velocity_mps[used],
                f.radar_doppler_std_mps,
            )
            weight = np.zeros(used.shape[0])
            if radar_gate is not None and radar.position_weight is not None:
                weight = np.nan_to_num(radar.position_weight[used])
            by_pos = weight > 0.0
            if by_pos.any():
                extent = np.nan_to_num(
                    np.maximum(tracks.length_m[matched], tracks.width_m[matched])
                )[by_pos]
                r = det_cov[rows][by_pos] + (0.25 * extent**2)[:, None, None] * np.eye(2)
                z = np.stack([radar.x_m[used], radar.y_m[used]], axis=1)[by_pos]
                new_x[by_pos], new_p[by_pos] = position_update(
                    new_x[by_pos], new_p[by_pos], z, r / weight[by_pos, None, None]
                )
            state, cov = state.copy(), cov.copy()
            state[matched], cov[matched] = new_x, new_p
            radar_index[matched] = used
        counts.update(radar_counts, n_radar_unmatched=int(kept.shape[0] - rows.shape[0]))
    fused_tracks = tracks if state is tracks.state else replace(tracks, state=state, covariance=cov)
    return FusedTracks(
        stamp_s=float(now_s),
        tracks=fused_tracks,
        confidence=conf,
        thermal_index=thermal_index,
        radar_index=radar_index,
        pedestrian_x_m=thermal.x_m[ped],
        pedestrian_y_m=thermal.y_m[ped],
        pedestrian_stamp_s=thermal.stamp_s[ped],
        pedestrian_confidence=ped_conf,
        pedestrian_index=ped,
        counts=FusionCounts(**counts),
    )


@dataclass(frozen=True)
class GatedFusion:
    """The fusion role's default: :func:`fuse` with the ``fusion`` section, a guard and, for a
    radar behind its front-end, the radar gate (None: the Euclidean gate)."""

    config: FusionSection
    guard: FreshnessGuard
    radar_gate: RadarGate | None = None

    def fuse(
        self,
        now_s: float,
        tracks: Tracks,
        confidence: FloatArray,
        thermal: ThermalDetections | None,
        radar: RadarDetections | None,
    ) -> FusedTracks:
        """Tracks with fresh thermal and radar detections fused in, at decision time ``now_s``."""
        return fuse(
            now_s,
            tracks,
            self.config,
            guard=self.guard,
            confidence=confidence,
            thermal=thermal,
            radar=radar,
            radar_gate=self.radar_gate,
        )
