"""The radar's front-end and its fusion (SR-FUS-7).

Ego-motion compensation is checked against the range rate measured by finite differences of the
true geometry (a robot driving and turning past static and moving targets), not against the
formula it implements. Returns the filters drop (weak RCS or SNR, ground clutter, multipath
ghosts behind a mapped reflector) are placed exactly on tracks, which must come out of fusion
bit for bit as they went in. Radar updates (Doppler, and position when the LiDAR is degraded)
keep every covariance symmetric positive definite; the position update equals filterpy's; the
Mahalanobis gate equals a direct solve; the weighting rule is stated and measured. Fusion
without a radar gate is the Euclidean fusion of SR-FUS-1..4, unchanged.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.config import SafecaseConfig
from pipeline.frames import to_child, to_parent
from pipeline.fusion import fuse
from pipeline.sensors.radar import (
    RadarFrontEnd,
    RadarGate,
    degradation_index,
    position_covariance,
    position_update,
    radar_costs,
)
from pipeline.types import FloatArray, RadarDetections
from pipeline.types.sensors import Twist
from properties.fusion_cases import make_tracks, spd_matrix
from properties.radar_cases import pose_at
from safety.model.freshness import is_fresh

CODE = ["pipeline/sensors/radar.py", "pipeline/fusion.py"]


@pytest.mark.requirement("SR-FUS-7", kind="cross-check", code=["pipeline/sensors/radar.py"])
@settings(max_examples=examples(200), deadline=None)
@given(
    pose=st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-math.pi, math.pi)),
    twist=st.tuples(st.floats(-2.0, 2.0), st.floats(-0.5, 0.5), st.floats(-1.0, 1.0)),
    mount=st.tuples(st.floats(-1.0, 1.0), st.floats(-0.5, 0.5)),
    targets=st.lists(
        st.tuples(
            st.floats(2.0, 40.0),
            st.floats(-math.pi, math.pi),
            st.floats(-3.0, 3.0),
            st.floats(-3.0, 3.0),
        ),
        min_size=1,
        max_size=6,
    ),
    moving=st.booleans(),
)
def test_compensated_doppler_is_the_targets_own_radial_speed(
    safecase_config: SafecaseConfig,
    pose: tuple[float, float, float],
    twist: tuple[float, float, float],
    mount: tuple[float, float],
    targets: list[tuple[float, float, float, float]],
    moving: bool,
) -> None:
    tw = Twist(*twist)
    h = 1e-5
    # Targets in the world frame, placed by range and bearing from the radar at t = 0.
    radar_w = to_parent(pose, np.array([mount[0]]), np.array([mount[1]]))
    rng_m = np.array([t[0] for t in targets])
    brg = np.array([t[1] for t in targets]) + pose[2]
    p0 = np.stack([radar_w[0][0] + rng_m * np.cos(brg), radar_w[1][0] + rng_m * np.sin(brg)], 1)
    v = np.array([[t[2], t[3]] for t in targets]) if moving else np.zeros((len(targets), 2))

    def measured(t_s: float) -> tuple[FloatArray, FloatArray]:
        p = pose_at(pose, tw, t_s)
        mx, my = to_parent(p, np.array([mount[0]]), np.array([mount[1]]))
        pts = p0 + v * t_s
        lx, ly = to_child(p, pts[:, 0], pts[:, 1])
        return np.hypot(pts[:, 0] - mx[0], pts[:, 1] - my[0]), np.arctan2(
            ly - mount[1], lx - mount[0]
        )

    r_plus, _ = measured(h)
    r_minus, _ = measured(-h)
    r0, b0 = measured(0.0)
    rate = (r_plus - r_minus) / (2 * h)  # what the radar measures: the true range rate
    radar = RadarDetections(np.zeros(len(targets)), r0, b0, rate, mount[0], mount[1])
    front = RadarFrontEnd(safecase_config)
    kept, counts = front.filter(radar, pose, None)
    assert kept.all()
    assert counts.n_kept == len(targets)
    out = front.in_tracking_frame(radar, kept, pose, tw, 0.0)
    # In the tracking (world) frame: the target's own velocity along the ray from the radar.
    u = np.stack([np.cos(out.bearing_rad), np.sin(out.bearing_rad)], 1)
    own = np.sum(u * v, axis=1)
    assert np.allclose(out.radial_velocity_mps, own, rtol=0.0, atol=1e-4), (
        out.radial_velocity_mps,
        own,
    )
    assert np.allclose(out.x_m, p0[:, 0], atol=1e-9)
    assert np.allclose(out.y_m, p0[:, 1], atol=1e-9)
    current().count("worlds", "moving targets" if moving else "static world")
    # What the compensation removed: the robot's own motion along each ray.
    removed = int(np.count_nonzero(np.abs(rate - own) > 1e-3))
    current().count("returns", "robot's motion removed (> 1 mm/s)", removed)
    current().count("returns", "robot's motion negligible", len(targets) - removed)


def test_a_moving_pose_without_a_twist_is_refused(safecase_config: SafecaseConfig) -> None:
    radar = RadarDetections(np.zeros(1), np.ones(1), np.zeros(1), np.zeros(1))
    front = RadarFrontEnd(safecase_config)
    kept, _ = front.filter(radar, (1.0, 0.0, 0.0), None)
    with pytest.raises(ValueError, match="twist"):
        front.in_tracking_frame(radar, kept, (1.0, 0.0, 0.0), None, 0.0)


@st.composite
def _scene(draw: st.DrawFn) -> tuple[Any, RadarDetections, FloatArray, list[str]]:
    """Tracks in a row across the radar's view, one return exactly on each track, each return
    drawn to pass or to fail one filter; a wall (reflector) across the view at 12 m."""
    n = draw(st.integers(1, 8))
    fate = draw(st.lists(st.sampled_from(["kept", "low_rcs", "low_snr", "clutter", "ghost"]),
                         min_size=n, max_size=n))  # fmt: skip
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    bearing = np.linspace(-0.6, 0.6, n) if n > 1 else np.zeros(1)
    rng_m = np.array([rng.uniform(19.0, 28.0) if f == "ghost" else rng.uniform(3.0, 10.0)
                      for f in fate])  # fmt: skip
    rcs = np.where([f == "low_rcs" for f in fate], rng.uniform(-40.0, -15.5, n),
                   rng.uniform(-10.0, 20.0, n))  # fmt: skip
    snr = np.where([f == "low_snr" for f in fate], rng.uniform(-5.0, 9.5, n),
                   rng.uniform(12.0, 40.0, n))  # fmt: skip
    # Height above the ground 0.5 + r sin(e): clutter below 0.15 m, the rest 0.3-1.5 m.
    height = np.where([f == "clutter" for f in fate], rng.uniform(-0.5, 0.1, n),
                      rng.uniform(0.3, 1.5, n))  # fmt: skip
    elevation = np.arcsin(np.clip((height - 0.5) / rng_m, -1.0, 1.0))
    rate = rng.uniform(-3.0, 3.0, n)
    radar = RadarDetections(
        np.zeros(n), rng_m, bearing, rate, 0.0, 0.0, elevation_rad=elevation, rcs_dbsm=rcs,
        snr_db=snr,
    )  # fmt: skip
    xy = np.stack([radar.x_m, radar.y_m], 1)
    velocity = rng.normal(0.0, 1.0, (n, 2))
    tracks = make_tracks(0.0, xy, velocity, cov_scale=float(rng.uniform(0.05, 2.0)))
    wall = np.array([[12.0, -20.0, 12.0, 20.0]])
    return tracks, radar, wall, fate


@pytest.mark.requirement("SR-FUS-7", kind="property", code=CODE)
@settings(max_examples=examples(200), deadline=None)
@given(scene=_scene(), degraded=st.floats(0.0, 1.0))
def test_filtered_returns_never_update_a_track(
    safecase_config: SafecaseConfig,
    scene: tuple[Any, RadarDetections, FloatArray, list[str]],
    degraded: float,
) -> None:
    tracks, radar, wall, fate = scene
    front = RadarFrontEnd(safecase_config)
    pose = (0.0, 0.0, 0.0)
    kept, counts = front.filter(radar, pose, wall)
    assert kept.tolist() == [f == "kept" for f in fate]
    assert counts.n_low_rcs == fate.count("low_rcs")
    assert counts.n_ghost == fate.count("ghost")
    assert counts.n_low_snr == fate.count("low_snr")
    assert counts.n_clutter == fate.count("clutter")
    framed = front.in_tracking_frame(radar, kept, pose, Twist(0.0, 0.0, 0.0), degraded)
    fused = fuse(
        0.0, tracks, safecase_config.fusion, guard=is_fresh, radar=framed,
        radar_gate=RadarGate.from_config(safecase_config),
    )  # fmt: skip
    out = fused.tracks
    for i, f in enumerate(fate):
        if f != "kept":
            assert fused.radar_index[i] == -1
            assert np.array_equal(out.state[i], tracks.state[i])
            assert np.array_equal(out.covariance[i], tracks.covariance[i])
        else:
            # A return exactly on its track within every gate updates it.
            assert fused.radar_index[i] >= 0
        current().count("returns", f)


@pytest.mark.requirement("SR-FUS-7", kind="property", code=CODE)
@settings(max_examples=examples(200), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 6),
    weight=st.one_of(st.just(0.0), st.floats(0.3, 1.0)),
    offset=st.floats(0.0, 3.0),
)
def test_radar_updates_keep_covariances_positive_definite(
    safecase_config: SafecaseConfig, seed: int, n: int, weight: float, offset: float
) -> None:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-15.0, 15.0, (n, 2))
    tracks = make_tracks(0.0, xy, rng.normal(0.0, 2.0, (n, 2)))
    cov = np.stack([spd_matrix(rng, rng.uniform(0.01, 2.0)) for _ in range(n)])
    tracks = type(tracks)(**{**{k: getattr(tracks, k) for k in tracks.__dataclass_fields__},
                             "covariance": cov})  # fmt: skip
    # Returns near each track (within ``offset``), seen from a radar at the origin.
    target = xy + rng.normal(0.0, 1.0, (n, 2)) * offset / math.sqrt(2.0)
    rng_m = np.hypot(target[:, 0], target[:, 1])
    radar = RadarDetections(
        np.zeros(n), rng_m, np.arctan2(target[:, 1], target[:, 0]), rng.uniform(-3, 3, n),
        position_weight=np.full(n, weight),
    )  # fmt: skip
    gate = RadarGate.from_config(safecase_config)
    fused = fuse(0.0, tracks, safecase_config.fusion, guard=is_fresh, radar=radar,
                 radar_gate=gate)  # fmt: skip
    p = fused.tracks.covariance
    assert np.array_equal(p, np.swapaxes(p, 1, 2))
    assert np.all(np.linalg.eigvalsh(p) > 0.0)
    matched = fused.radar_index >= 0
    # An update never makes a track less certain in its position.
    trace_before = np.trace(cov[:, :2, :2], axis1=1, axis2=2)
    trace_after = np.trace(p[:, :2, :2], axis1=1, axis2=2)
    assert np.all(trace_after[matched] <= trace_before[matched] * (1 + 1e-12))
    current().count("tracks", "updated", int(matched.sum()))
    current().count("tracks", "outside the gates", int((~matched).sum()))


@pytest.mark.requirement("SR-FUS-7", kind="cross-check", code=["pipeline/sensors/radar.py"])
@settings(max_examples=examples(200))
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5))
def test_position_update_equals_filterpy(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 5.0, (n, 4))
    p = np.stack([spd_matrix(rng, rng.uniform(0.05, 3.0)) for _ in range(n)])
    r = np.stack([spd_matrix(rng, rng.uniform(0.01, 1.0))[:2, :2] for _ in range(n)])
    z = x[:, :2] + rng.normal(0.0, 1.0, (n, 2))
    ours_x, ours_p = position_update(x, p, z, r)
    for i in range(n):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x = x[i].reshape(4, 1).copy()
        kf.P = p[i].copy()
        kf.H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
        kf.R = r[i].copy()
        kf.update(z[i].reshape(2, 1))
        scale = max(1.0, float(np.abs(p[i]).max()))
        assert np.allclose(ours_x[i], kf.x.ravel(), rtol=0.0, atol=1e-9 * scale)
        assert np.allclose(ours_p[i], kf.P, rtol=0.0, atol=1e-9 * scale)


@pytest.mark.requirement("SR-FUS-7", kind="property", code=["pipeline/sensors/radar.py"])
@settings(max_examples=examples(200))
@given(seed=st.integers(0, 2**32 - 1), d=st.integers(1, 5), t=st.integers(1, 5))
def test_mahalanobis_gate_equals_a_direct_solve(
    safecase_config: SafecaseConfig, seed: int, d: int, t: int
) -> None:
    rng = np.random.default_rng(seed)
    gate = RadarGate.from_config(safecase_config)
    track_xy = rng.uniform(-10.0, 10.0, (t, 2))
    track_cov = np.stack([spd_matrix(rng, rng.uniform(0.05, 1.0))[:2, :2] for _ in range(t)])
    extent = rng.uniform(0.0, 3.0, t)
    det_xy = track_xy[rng.integers(0, t, d)] + rng.normal(0.0, 1.5, (d, 2))
    rng_m = np.hypot(det_xy[:, 0], det_xy[:, 1])
    det_cov = position_covariance(
        rng_m, np.arctan2(det_xy[:, 1], det_xy[:, 0]), gate.range_std_m, gate.azimuth_std_rad
    )
    cost = radar_costs(np.tile(track_xy, (d, 1, 1)), track_cov, extent, det_xy, det_cov, gate)
    for i in range(d):
        for j in range(t):
            s = track_cov[j] + det_cov[i] + 0.25 * extent[j] ** 2 * np.eye(2)
            r = det_xy[i] - track_xy[j]
            d2 = float(r @ np.linalg.solve(s, r))
            inside = d2 <= gate.gate_chi2 and float(np.hypot(*r)) <= gate.gate_m
            if inside:
                assert math.isclose(cost[i, j], d2, rel_tol=1e-9, abs_tol=1e-12)
            else:
                # Exactly at a gate's edge rounding may go either way.
                edge = abs(d2 - gate.gate_chi2) < 1e-9 * gate.gate_chi2
                assert edge or math.isinf(cost[i, j])
            current().count("pairs", "inside the gates" if inside else "outside")


@pytest.mark.requirement("SR-FUS-7", kind="property", code=CODE)
def test_weighting_rule_by_lidar_degradation(
    safecase_config: SafecaseConfig, evidence: Any
) -> None:
    """The rule: degradation index d = (share of returns isolated within
    radar.degraded_within_m / radar.degraded_noise_fraction) capped at 1; from
    radar.degraded_from, matched radar positions update their tracks with covariance (R + E) / d.
    Measured: a track 1 m off the radar's return, how far one update moves it."""
    c = safecase_config.radar
    gate = RadarGate.from_config(safecase_config)
    front = RadarFrontEnd(safecase_config)
    rows = []
    moved_by = []
    for isolated in (0.0, 0.02, 0.04, 0.05, 0.10, 0.15, 0.30):
        near = np.full(1000, 0.5 * c.degraded_within_m)
        d = degradation_index(near, np.arange(1000) < int(isolated * 1000),
                              c.degraded_within_m, c.degraded_noise_fraction)  # fmt: skip
        tracks = make_tracks(0.0, [[10.0, 1.0]], [[0.0, 0.0]], cov_scale=1.0)
        radar = RadarDetections(np.zeros(1), np.array([10.0]), np.zeros(1), np.zeros(1))
        framed = front.in_tracking_frame(radar, np.ones(1, bool), (0.0, 0.0, 0.0), None, d)
        fused = fuse(0.0, tracks, safecase_config.fusion, guard=is_fresh, radar=framed,
                     radar_gate=gate)  # fmt: skip
        moved = 1.0 - float(fused.tracks.state[0, 1])
        weight = float(framed.position_weight[0]) if framed.position_weight is not None else 0.0
        assert weight == (d if d >= c.degraded_from else 0.0)
        rows.append([isolated, round(d, 3), round(weight, 3), round(moved, 3)])
        moved_by.append(moved)
    evidence.table(
        "radar position weight by LiDAR degradation (a track 1 m beside the return)",
        ["isolated share of LiDAR returns", "degradation index", "position weight",
         "track moved towards the return [m]"],
        rows,
    )  # fmt: skip
    assert moved_by[0] == 0.0  # a clear LiDAR: the radar's position is not used
    assert all(a <= b for a, b in itertools.pairwise(moved_by))
    assert moved_by[-1] > 0.0


@pytest.mark.requirement("SR-FUS-7", kind="property", code=CODE)
@settings(max_examples=examples(200))
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 300),
    within=st.floats(0.5, 20.0),
    full=st.floats(0.01, 1.0),
)
def test_the_degradation_index_counts_isolated_returns_near_the_scanner_only(
    seed: int, n: int, within: float, full: float
) -> None:
    """d = min(1, #(isolated and nearer than within) / #returns / full), counted one return at a
    time; moving an isolated return beyond ``within`` never raises it."""
    rng = np.random.default_rng(seed)
    range_m = rng.uniform(0.1, 2.0 * within, n)
    isolated = rng.random(n) < rng.random()
    counted = sum(1 for r, i in zip(range_m, isolated, strict=True) if i and r < within)
    want = 0.0 if n == 0 else min(1.0, counted / n / full)
    got = degradation_index(range_m, isolated, within, full)
    assert got == pytest.approx(want, rel=1e-12, abs=0.0)
    far = np.where(isolated, np.maximum(range_m, within), range_m)
    assert degradation_index(far, isolated, within, full) == 0.0
    if n:
        with pytest.raises(ValueError, match="isolated flags"):
            degradation_index(range_m, isolated[:-1], within, full)
