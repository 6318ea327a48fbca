"""Freshness, staleness and fusion (SR-FUS-1..4).

SR-FUS-1: z3 proves, about :func:`safety.model.freshness.is_fresh` itself, that whatever the stamps,
the decision time, the maximum age, the skew bound and the rounding guard, a detection the
guard admits is at most ``max_age`` old in true time whenever its stamp is off by at most the
skew; and that it admits everything fresher than ``max_age - 2 skew - guard`` (it is not
vacuous). A guard without the skew term is refuted (the harness can fail). The runtime
:func:`pipeline.fusion.fuse` is then checked over random detection streams in exact rational
arithmetic, with ages concentrated on the threshold (a few ulps either side), epoch-sized
stamps and non-finite values.
SR-FUS-2: the monitors turn any stale scan or backwards clock into STOP with the reason.
SR-FUS-3: a fresh thermal detection outside every track's gate becomes a pedestrian whose
confidence selects the most cautious tier. SR-FUS-4: the Doppler update equals filterpy.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
import z3
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig
from pipeline.fusion import doppler_update, fuse
from pipeline.types import Action, Command, RadarDetections, ThermalDetections
from properties.fusion_cases import ages, epoch, make_tracks, spd_matrix
from properties.smt import Obligation, ProofVerdict, prove, to_z3
from safety.model.freshness import FRESHNESS_GUARD_S, is_fresh
from safety.model.governor import Governor
from safety.model.monitors import Observation, combine, run_monitors
from safety.model.stopping import StoppingParams, Tier

FUSION = ["pipeline/fusion.py"]
MONITORS = ["safety/model/monitors.py", "pipeline/fusion.py"]


def _guard_domain() -> tuple[tuple[z3.ArithRef, ...], list[z3.BoolRef]]:
    now, stamp, true, max_age, skew, guard = z3.Reals(
        "now_s stamp_s true_capture_s max_age_s skew_s guard_s"
    )
    hyps = [
        max_age > 0,
        skew >= 0,
        guard >= 0,
        stamp - true <= skew,  # the stated clock assumption: |stamp - true capture| <= skew
        true - stamp <= skew,
    ]
    return (now, stamp, true, max_age, skew, guard), hyps


def freshness_sound_obligation(guard_fn: Any = is_fresh) -> Obligation:
    """Admitted by the guard => true age <= max_age, for every value of every variable."""
    (now, stamp, true, max_age, skew, guard), hyps = _guard_domain()
    return Obligation(
        name="SR-FUS-1 freshness guard is sound",
        statement=(
            "for all decision times now, stamps s, true capture times t, max_age > 0, skew >= 0, "
            "guard >= 0 with |s - t| <= skew: is_fresh(now, s, max_age, skew, guard) implies "
            "now - t <= max_age (no detection older than max_age is ever fused)"
        ),
        hypotheses=tuple(hyps),
        goal=z3.Implies(guard_fn(now, stamp, max_age, skew, guard), now - true <= max_age),
        variables=(now, stamp, true, max_age, skew, guard),
    )


def freshness_live_obligation() -> Obligation:
    """The guard admits every detection truly fresher than max_age - 2 skew - guard."""
    (now, stamp, true, max_age, skew, guard), hyps = _guard_domain()
    return Obligation(
        name="SR-FUS-1 freshness guard is not vacuous",
        statement=(
            "under the same assumptions, 0 <= now - t <= max_age - 2 skew - guard implies "
            "is_fresh(now, s, max_age, skew, guard)"
        ),
        hypotheses=(*hyps, now - true >= 0, now - true <= max_age - 2 * skew - guard),
        goal=is_fresh(now, stamp, max_age, skew, guard),
        variables=(now, stamp, true, max_age, skew, guard),
    )


@pytest.mark.requirement("SR-FUS-1", kind="proof", code=MONITORS)
def test_freshness_guard_proofs(safecase_config: SafecaseConfig, evidence: Recorder) -> None:
    sound = prove(freshness_sound_obligation())
    live = prove(freshness_live_obligation())
    sound.attach(required=True)
    live.attach(required=True)
    # The configured instance (thermal, radar and scan maximum ages with their skews).
    f, m = safecase_config.fusion, safecase_config.monitors
    (now, stamp, true, max_age, skew, guard), hyps = _guard_domain()
    for name, age_s, skew_s in (
        ("thermal", f.thermal_max_age_s, f.clock_skew_s),
        ("radar", f.radar_max_age_s, f.clock_skew_s),
        ("scan", m.scan_max_age_s, m.clock_skew_s),
    ):
        pinned = [max_age == to_z3(age_s), skew == to_z3(skew_s), guard == to_z3(FRESHNESS_GUARD_S)]
        result = prove(
            Obligation(
                name=f"SR-FUS-1 {name} guard at the configured values",
                statement=(
                    f"{name}: max age {age_s} s, skew {skew_s} s, guard {FRESHNESS_GUARD_S} s: "
                    "admitted implies true age <= max age"
                ),
                hypotheses=(*hyps, *pinned),
                goal=z3.Implies(is_fresh(now, stamp, max_age, skew, guard), now - true <= max_age),
            )
        )
        result.attach(required=True)
        assert result.proved, result.describe_model()
    evidence.note(
        "Assumption (stated in the obligations): every sensor's stamp differs from the decision "
        "clock's reading at the true capture time by at most the configured clock_skew_s."
    )
    assert sound.proved, sound.describe_model()
    assert live.proved, live.describe_model()


@pytest.mark.requirement("SR-FUS-1", kind="proof", code=FUSION)
def test_guard_without_skew_term_is_refuted() -> None:
    def naive(now: Any, stamp: Any, max_age: Any, skew: Any, guard: Any) -> Any:
        return now - stamp <= max_age  # trusts the stamp: wrong when clocks disagree

    result = prove(freshness_sound_obligation(naive))
    result.attach(required=False)
    assert result.verdict is ProofVerdict.REFUTED
    model = result.model_floats()
    assert model["now_s"] - model["true_capture_s"] > model["max_age_s"]


@st.composite
def thermal_stream(draw: st.DrawFn, config: SafecaseConfig) -> list[dict[str, Any]]:
    f = config.fusion
    start = draw(epoch())
    cycles = []
    now = start
    for _ in range(draw(st.integers(1, 4))):
        now += draw(st.floats(0.0, 0.2))
        n = draw(st.integers(0, 6))
        age = [draw(ages(f.thermal_max_age_s, f.clock_skew_s)) for _ in range(n)]
        xy = draw(st.lists(st.tuples(st.floats(-8, 8), st.floats(-8, 8)), min_size=n, max_size=n))
        radar_age = [draw(ages(f.radar_max_age_s, f.clock_skew_s)) for _ in range(n)]
        cycles.append({"now": now, "age": age, "xy": xy, "radar_age": radar_age})
    return cycles


def _exact_age(now: float, stamp: float) -> Fraction:
    return Fraction(now) - Fraction(stamp)


@pytest.mark.requirement("SR-FUS-1", kind="property", code=FUSION)
@settings(max_examples=examples(300))
@given(data=st.data())
def test_fuse_never_uses_a_stale_detection(safecase_config: SafecaseConfig, data: Any) -> None:
    f = safecase_config.fusion
    limit_thermal = Fraction(f.thermal_max_age_s) - Fraction(f.clock_skew_s)
    limit_radar = Fraction(f.radar_max_age_s) - Fraction(f.clock_skew_s)
    rec = current()
    tracks_xy = data.draw(st.lists(st.tuples(st.floats(-8, 8), st.floats(-8, 8)), max_size=5))
    for cycle in data.draw(thermal_stream(safecase_config)):
        now = cycle["now"]
        n = len(cycle["age"])
        stamps = np.array([now - a if math.isfinite(a) else a for a in cycle["age"]])
        xy = np.array(cycle["xy"], dtype=np.float64).reshape(n, 2)
        tracks = make_tracks(now, np.array(tracks_xy).reshape(-1, 2))
        radar_stamps = np.array([now - a if math.isfinite(a) else a for a in cycle["radar_age"]])
        radar = RadarDetections(
            radar_stamps, np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0]), np.zeros(n)
        )
        thermal = ThermalDetections(stamps, xy[:, 0], xy[:, 1], np.full(n, 0.9))
        fused = fuse(
            now, tracks, safecase_config.fusion, guard=is_fresh, thermal=thermal, radar=radar
        )
        used = [*fused.thermal_index[fused.thermal_index >= 0], *fused.pedestrian_index]
        assert len(used) == len(set(used))
        for i in used:
            assert _exact_age(now, float(stamps[i])) <= limit_thermal, (now, stamps[i])
            assert _exact_age(now, float(stamps[i])) >= -Fraction(f.clock_skew_s)
        for i in fused.radar_index[fused.radar_index >= 0]:
            assert _exact_age(now, float(radar_stamps[i])) <= limit_radar
        # Not vacuous: everything comfortably fresh was used (matched or a pedestrian).
        for i in range(n):
            if math.isfinite(stamps[i]):
                age = _exact_age(now, float(stamps[i]))
                if -Fraction(f.clock_skew_s) <= age <= limit_thermal - Fraction(2, 10**9):
                    assert i in used, (now, stamps[i])
                rec.count("thermal ages", "stale" if age > limit_thermal else "fresh or future")
        c = fused.counts
        rec.count("thermal outcome", "matched", c.n_thermal_matched)
        rec.count("thermal outcome", "pedestrian", c.n_thermal_only)
        rec.count("thermal outcome", "stale", c.n_thermal_stale)
        rec.count("thermal outcome", "future", c.n_thermal_future)
        rec.count("thermal outcome", "invalid", c.n_thermal_invalid)
        rec.count("cycles", "LiDAR-only fallback" if c.lidar_only else "fused")


monitor_cfg: st.SearchStrategy[dict[str, Any]] = st.builds(
    dict,
    age=st.floats(-0.5, 1.0),
    jump=st.floats(-0.5, 0.5),
    scan_jump=st.floats(-0.5, 0.5),
    governor=st.sampled_from(["PROCEED", "SLOW", "STOP"]),
)


@pytest.mark.requirement("SR-FUS-2", kind="property", code=MONITORS)
@settings(max_examples=examples(300))
@given(now=epoch(), case=monitor_cfg, ulps=st.integers(-2, 2))
def test_stale_scan_or_backwards_clock_stops(
    safecase_config: SafecaseConfig, now: float, case: dict[str, Any], ulps: int
) -> None:
    m = safecase_config.monitors
    age = case["age"] if ulps == 0 else m.scan_max_age_s - m.clock_skew_s + ulps * 1e-12
    stamp = now - age
    obs = Observation(
        now_s=now,
        previous_now_s=now + case["jump"],
        scan_stamp_s=stamp,
        previous_scan_stamp_s=stamp + case["scan_jump"],
        cycle_duration_s=0.0,
    )
    governor = {
        "PROCEED": Command(Action.PROCEED, 1.0, now),
        "SLOW": Command(Action.SLOW, 0.4, now, ("obstacle ahead",)),
        "STOP": Command(Action.STOP, 0.0, now, ("obstacle close",)),
    }[case["governor"]]
    command = combine(governor, run_monitors(obs, m), stamp_s=now, min_moving_mps=0.05)
    exact_age = _exact_age(now, stamp)
    stale = exact_age > Fraction(m.scan_max_age_s) - Fraction(m.clock_skew_s)
    future = exact_age < -Fraction(m.clock_skew_s)
    # With a zero tolerance the monitors compare exactly; with a positive one, float rounding of
    # (previous - tolerance) is allowed at the boundary (1e-6 s covers epoch-sized stamps).
    slack = Fraction(0) if m.max_clock_jump_back_s == 0 else Fraction(1, 10**6)
    limit = Fraction(m.max_clock_jump_back_s) + slack
    jumped = Fraction(now + case["jump"]) - Fraction(now) > limit
    stamps_back = Fraction(stamp + case["scan_jump"]) - Fraction(stamp) > limit
    text = " | ".join(command.reasons)
    if stale or future or jumped or stamps_back:
        assert command.action is Action.STOP, command
    if stale or future:
        assert "stale scan" in text, command
    if jumped:
        assert "clock jumped back" in text, command
    elif stamps_back:
        assert "scan stamps went back" in text, command
    if not (stale or future or jumped or stamps_back) and governor.action is Action.PROCEED:
        fresh_enough = exact_age <= Fraction(m.scan_max_age_s) - Fraction(
            m.clock_skew_s
        ) - Fraction(2, 10**9)
        if fresh_enough:
            assert command == governor, command  # no spurious objection
    current().count("final action", command.action.value)
    current().count("cases", "stale" if stale else "future" if future else "fresh")
    current().count("clock", "jumped back" if jumped else "monotone")


@pytest.mark.requirement("SR-FUS-3", kind="property", code=[*FUSION, "safety/model/governor.py"])
@settings(max_examples=examples(200))
@given(
    tracks_xy=st.lists(st.tuples(st.floats(-6, 6), st.floats(-6, 6)), max_size=6),
    people=st.lists(st.tuples(st.floats(-10, 10), st.floats(-10, 10)), min_size=1, max_size=4),
    age_frac=st.floats(0.0, 1.0),
    base=st.floats(0.0, 1.0),
    distance=st.floats(0.0, 5.0),
)
def test_unmatched_fresh_thermal_becomes_cautious_pedestrian(
    safecase_config: SafecaseConfig,
    tracks_xy: list[tuple[float, float]],
    people: list[tuple[float, float]],
    age_frac: float,
    base: float,
    distance: float,
) -> None:
    f = safecase_config.fusion
    now = 100.0
    txy = np.array(tracks_xy, dtype=np.float64).reshape(-1, 2)
    pxy = np.array(people, dtype=np.float64)
    if txy.shape[0]:
        gap = np.hypot(pxy[:, None, 0] - txy[None, :, 0], pxy[:, None, 1] - txy[None, :, 1])
        outside = gap.min(axis=1) > f.gate_m
    else:
        outside = np.ones(pxy.shape[0], dtype=bool)
    stamp = now - age_frac * (f.thermal_max_age_s - f.clock_skew_s - 2e-9)
    thermal = ThermalDetections(
        np.full(pxy.shape[0], stamp), pxy[:, 0], pxy[:, 1], np.full(pxy.shape[0], 0.95)
    )
    tracks = make_tracks(now, txy)
    fused = fuse(
        now,
        tracks,
        safecase_config.fusion,
        guard=is_fresh,
        confidence=np.full(tracks.n, base),
        thermal=thermal,
    )
    assert set(np.flatnonzero(outside)) <= set(fused.pedestrian_index.tolist())
    assert fused.counts.n_thermal_matched + fused.counts.n_thermal_only == pxy.shape[0]
    matched = fused.thermal_index >= 0
    assert np.allclose(fused.confidence[matched], min(base + f.confidence_boost, 1.0))
    params = StoppingParams.from_config(safecase_config)
    governor = Governor.from_config(safecase_config)
    for conf in fused.pedestrian_confidence:
        assert conf < safecase_config.classify.medium_confidence_min
        # The most cautious tier (the largest margin), and the governor treats the pedestrian
        # exactly like an obstacle of unknown class closing in at walking speed.
        assert params.margin_for(conf, False) == params.margin_m(Tier.NEAR_REVERSAL)
        assert params.margin_m(Tier.NEAR_REVERSAL) == max(params.margins_m)
        walking = [params.person_speed_mps]
        pedestrian = governor.command(now, [distance], walking, [conf])
        assert pedestrian == governor.command(now, [distance], walking)
    current().count("pedestrians per example", str(fused.n_pedestrians))


@pytest.mark.requirement("SR-FUS-4", kind="cross-check", code=FUSION)
@settings(max_examples=examples(200))
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), std=st.floats(0.01, 2.0))
def test_doppler_update_matches_filterpy(seed: int, n: int, std: float) -> None:
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 5.0, (n, 4))
    p = np.stack([spd_matrix(rng, rng.uniform(0.05, 3.0)) for _ in range(n)])
    bearing = rng.uniform(-math.pi, math.pi, n)
    z = rng.normal(0.0, 2.0, n)
    ours_x, ours_p = doppler_update(x, p, bearing, z, std)
    for i in range(n):
        kf = KalmanFilter(dim_x=4, dim_z=1)
        kf.x = x[i].reshape(4, 1).copy()
        kf.P = p[i].copy()
        kf.H = np.array([[0.0, 0.0, math.cos(bearing[i]), math.sin(bearing[i])]])
        kf.R = np.array([[std * std]])
        kf.update(np.array([[z[i]]]))
        scale = max(1.0, float(np.abs(p[i]).max()))
        assert np.allclose(ours_x[i], kf.x.ravel(), rtol=0.0, atol=1e-9 * scale)
        assert np.allclose(ours_p[i], kf.P, rtol=0.0, atol=1e-9 * scale)
        assert np.all(np.linalg.eigvalsh(ours_p[i]) > 0.0)
