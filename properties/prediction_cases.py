"""Synthetic tracks and true motions that satisfy the prediction model's assumptions (SR-PRED-*).

A case is one track as the tracker would report it (estimated position and velocity with
their covariances, box size, centroid history) plus a *true* motion of the object that
satisfies the assumptions of :mod:`pipeline.predict` for that track's mode:

* start within ``k sigma_p`` of the estimated position;
* moving (cone): initial velocity within ``k sigma_v`` of the estimate, speed at most
  ``|v| + k sigma_v`` throughout, direction of travel within ``cone + asin(k sigma_v / |v|)`` of
  the estimated heading;
* near reversal: forwards along the last confirmed heading (within the cone) at most at the
  speed bound, slowing to rest, then (reverse mode) backwards within the cone of the opposite
  heading at most at the reversal speed;
* footprint: standing still;
* unknown: any direction, speed at most the speed bound (and a reversal at most at the
  reversal speed);
* never faster than ``predict.max_object_speed_mps`` (the operating domain's limit, which
  caps every speed bound).

Motions are :class:`pipeline.sources.sim.motion.Motion` profiles integrated by the simulator
(:func:`pipeline.sources.sim.motion.integrate`), so the true positions are the simulator's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.classify.model import MODEL_CLASSES
from pipeline.config import SafecaseConfig
from pipeline.features import N_FEATURES, feature_index
from pipeline.sources.sim import motion as mo
from pipeline.types import Classification, FloatArray, TrackFeatures, Tracks, TrackStatus

__all__ = ["Case", "classification", "features_for", "make_case", "tracks_of"]

MODES = ("cone", "stop", "reverse", "footprint", "unknown")


@dataclass(frozen=True)
class Case:
    """One synthetic track and the true path of its object (positions and headings)."""

    mode: str
    tracks: Tracks
    class_name: str | None
    confidence: float
    true_t_s: FloatArray
    true_x_m: FloatArray
    true_y_m: FloatArray
    true_heading_rad: FloatArray
    width_m: float
    length_m: float


def tracks_of(
    xy: FloatArray,
    v: FloatArray,
    sigma_p: float,
    sigma_v: float,
    width_m: float,
    length_m: float,
    history_xy: FloatArray,
    history_len: int = 15,
) -> Tracks:
    """A one-track snapshot (confirmed) with isotropic covariances."""
    cov = np.zeros((1, 4, 4))
    cov[0, 0, 0] = cov[0, 1, 1] = sigma_p**2
    cov[0, 2, 2] = cov[0, 3, 3] = sigma_v**2
    hist = np.full((1, history_len, 2), np.nan)
    k = min(history_xy.shape[0], history_len)
    hist[0, history_len - k :] = history_xy[-k:]
    one = np.ones(1, dtype=np.int64)
    return Tracks(
        stamp_s=0.0,
        track_id=np.zeros(1, dtype=np.int64),
        status=np.full(1, int(TrackStatus.CONFIRMED)),
        state=np.array([[xy[0], xy[1], v[0], v[1]]]),
        covariance=cov,
        detection_index=np.zeros(1, dtype=np.int64),
        age_frames=one * 30,
        hits=one * 30,
        misses=0 * one,
        last_update_s=np.zeros(1),
        width_m=np.array([width_m]),
        length_m=np.array([length_m]),
        size_variance_m2=np.zeros(1),
        decel_mps2=np.zeros(1),
        history_xy_m=hist,
        history_speed_mps=np.where(np.isnan(hist[:, :, 0]), np.nan, float(np.hypot(*v))),
        history_t_s=np.where(
            np.isnan(hist[:, :, 0]), np.nan, 0.1 * (np.arange(history_len) - history_len + 1)
        ),
        history_len=one * k,
        max_width_m=np.array([width_m]),
        max_length_m=np.array([length_m]),
        reid_count=0 * one,
        history_end_xy_m=np.full((1, history_len, 4), np.nan),
        history_end_occluded=np.full((1, history_len, 2), np.nan),
    )


def classification(tracks: Tracks, class_name: str | None, confidence: float) -> Classification:
    """The track classified as ``class_name`` (None: unscored) with ``confidence``."""
    n, c = tracks.n, len(MODEL_CLASSES)
    index = -1 if class_name is None else MODEL_CLASSES.index(class_name)
    prob = np.full((n, c), np.nan if index < 0 else (1.0 - confidence) / max(c - 1, 1))
    if index >= 0:
        prob[:, index] = confidence
    return Classification(
        stamp_s=tracks.stamp_s,
        track_id=tracks.track_id,
        class_index=np.full(n, index, dtype=np.int64),
        probability=prob,
        confidence=np.full(n, confidence if index >= 0 else 0.0),
        class_names=MODEL_CLASSES,
        model_sha256="synthetic",
    )


def features_for(tracks: Tracks, near_reversal: bool) -> TrackFeatures:
    """Feature rows with the near-reversal flag set or not, the tracks' speeds and boxes, and a
    history that never moved (what prediction reads)."""
    values = np.zeros((tracks.n, N_FEATURES))
    values[:, feature_index("bbox_width_m")] = tracks.width_m
    values[:, feature_index("bbox_length_m")] = tracks.length_m
    values[:, feature_index("is_near_reversal")] = float(near_reversal)
    values[:, feature_index("velocity_magnitude_mps")] = np.hypot(
        tracks.state[:, 2], tracks.state[:, 3]
    )
    values[:, feature_index("time_since_moving_s")] = np.nan
    return TrackFeatures(tracks.stamp_s, tracks.track_id, tracks.status, values)


def _within(rng: np.random.Generator, radius: float) -> FloatArray:
    """A point uniformly in the disc of ``radius`` (boundary included by scaling up)."""
    angle = rng.uniform(-math.pi, math.pi)
    r = radius * math.sqrt(rng.uniform(0.0, 1.0)) if rng.random() < 0.8 else radius
    return np.array([r * math.cos(angle), r * math.sin(angle)])


def _heading_path(
    rng: np.random.Generator, start: float, centre: float, half: float, t1: float, t2: float
) -> tuple[FloatArray, FloatArray]:
    """Yaw segments keeping the heading within ``centre +/- half`` (start must lie in it)."""
    mid = centre + rng.uniform(-half, half)
    end = centre + rng.choice([-half, half, rng.uniform(-half, half)])
    return np.array([0.0, t1, t2]), np.array([(mid - start) / t1, (end - mid) / (t2 - t1), 0.0])


def make_case(rng: np.random.Generator, mode: str, config: SafecaseConfig) -> Case:
    """A random case of ``mode`` whose true motion satisfies the model's assumptions."""
    pc = config.predict
    k, horizon = pc.velocity_sigmas, pc.horizon_s
    cone = math.radians(pc.cone_half_angle_deg)
    sigma_p = float(rng.uniform(0.0, 0.08))
    sigma_v = float(rng.uniform(0.005, 0.3))
    width, length = sorted(rng.uniform(0.05, 3.0, size=2))
    xy = rng.uniform(-10.0, 10.0, size=2)
    heading = float(rng.uniform(-math.pi, math.pi))
    u = np.array([math.cos(heading), math.sin(heading)])
    start_xy = xy + _within(rng, k * sigma_p)
    t1, t2 = sorted(rng.uniform(0.05, horizon, size=2))
    t2 = max(t2, t1 + 0.01)
    speed_est = float(rng.uniform(0.0, 2.5))
    if mode in ("stop", "reverse"):
        speed_est = float(rng.uniform(0.0, pc.near_reversal_speed_mps))
    v_est = speed_est * u
    bound = min(speed_est + k * sigma_v, pc.max_object_speed_mps)
    history = xy[None, :] - u[None, :] * np.linspace(1.5, 0.0, 15)[:, None]  # 1.5 m travelled
    class_name: str | None
    confidence = float(rng.uniform(config.classify.medium_confidence_min, 1.0))
    yaw_t, yaw_r = np.zeros(1), np.zeros(1)
    true_heading = heading
    if mode == "cone":
        class_name = "forklift_moving"
        v_true = v_est + _within(rng, k * sigma_v)
        speed0 = float(np.hypot(*v_true))
        if speed0 > pc.max_object_speed_mps:  # the domain's limit holds for the truth too
            v_true *= pc.max_object_speed_mps / speed0
            speed0 = float(np.hypot(*v_true))
        certain = speed_est > k * sigma_v
        spread = math.asin(min(k * sigma_v / speed_est, 1.0)) if certain else math.pi
        half = cone + spread
        if speed0 > 0:  # the same direction, unwrapped next to the estimated heading
            turn = math.atan2(v_true[1], v_true[0]) - heading
            true_heading = heading + math.atan2(math.sin(turn), math.cos(turn))
        if half < 0.5 * math.pi:
            yaw_t, yaw_r = _heading_path(rng, true_heading, heading, half, t1, t2)
        else:  # direction unknown: any turn
            yaw_t, yaw_r = np.array([0.0, t1]), np.array([rng.uniform(-3, 3), rng.uniform(-3, 3)])
        knots_v = [speed0, rng.uniform(0.0, bound), rng.uniform(0.0, bound)]
        motion = mo.Motion(np.array([0.0, t1, t2]), np.array(knots_v), yaw_t, yaw_r, "case")
    elif mode in ("stop", "reverse"):
        class_name = "forklift_near_reversal"
        true_heading = heading + rng.uniform(-cone, cone)
        yaw_t, yaw_r = _heading_path(rng, true_heading, heading, cone, t1, t2)
        fwd = float(rng.uniform(0.0, bound))
        stop_at = float(rng.uniform(0.01, horizon))
        kt, kv = [0.0, stop_at], [fwd, 0.0]
        if mode == "reverse":
            back_at = stop_at + float(rng.uniform(0.0, 0.5))
            kt += [back_at + 0.001, back_at + 0.001 + rng.uniform(0.01, 1.0)]
            kv += [0.0, -float(rng.uniform(0.0, pc.reversal_speed_mps))]
        motion = mo.Motion(np.array(kt), np.array(kv), yaw_t, yaw_r, "case")
    elif mode == "footprint":
        class_name = str(rng.choice(["static", "forklift_stationary", "cart"]))
        motion = mo.stationary()
    else:
        class_name = None if rng.random() < 0.5 else "person"
        if class_name is not None:
            confidence = float(rng.uniform(0.0, config.classify.medium_confidence_min * 0.999))
        yaw_t = np.array([0.0, t1, t2])
        yaw_r = rng.uniform(-4.0, 4.0, size=3)
        fwd = float(rng.uniform(0.0, bound))
        kt = [0.0, t1, t2, t2 + 0.01]
        kv = [fwd, rng.uniform(0.0, bound), 0.0, -float(rng.uniform(0.0, pc.reversal_speed_mps))]
        motion = mo.Motion(np.array(kt), np.array(kv), yaw_t, yaw_r, "case")
    path = mo.integrate(motion, float(start_xy[0]), float(start_xy[1]), true_heading, horizon)
    keep = path.t_s <= horizon + 1e-12
    tracks = tracks_of(xy, v_est, sigma_p, sigma_v, float(width), float(length), history)
    return Case(
        mode=mode,
        tracks=tracks,
        class_name=class_name,
        confidence=confidence,
        true_t_s=path.t_s[keep],
        true_x_m=path.x_m[keep],
        true_y_m=path.y_m[keep],
        true_heading_rad=path.heading_rad[keep],
        width_m=float(width),
        length_m=float(length),
    )
