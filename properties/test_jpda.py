"""JPDA where gates overlap, the Hungarian cascade elsewhere (SR-TRK-8): Stone Soup as oracle,
covariance and work bounds, track-management invariants, and the A/B against the
Hungarian-only tracker on ray-cast apron scenarios."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.stateful import run_state_machine_as_test

from evidence.profiles import by_profile, certifying, examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig, TrackSection, default_config, overridden
from pipeline.track import kalman
from pipeline.track.associate import gated_costs
from pipeline.track.jpda import JpdaAssociator, SoftAssociation, pda_update, track_clusters
from pipeline.track.tracker import Tracker
from pipeline.types import FloatArray
from properties.ahead import ahead
from properties.airside_runs import airside_frames, motmetrics_counts, score_chain, timed
from properties.oracles.jpda import stonesoup_jpda
from properties.test_tracking import TrackerMachine

CODE = ["pipeline/track/jpda.py"]
CODE_TRACKER = ["pipeline/track/jpda.py", "pipeline/track/tracker.py"]
DENSE = ("dolly_train_close", "adjacent_ulds", "walker_crowd", "apron_clutter")


def _jpda_config(**track: float | int | str) -> TrackSection:
    return overridden(
        default_config(), {"track": {"association": "jpda", "gate_euclidean_m": 50.0, **track}}
    ).track


def _tracks(rng: np.random.Generator, k: int) -> tuple[FloatArray, FloatArray]:
    """``k`` predicted tracks close together with random SPD covariances."""
    x = np.zeros((k, 4))
    x[:, :2] = rng.uniform(0.0, 1.5, (k, 2))
    x[:, 2:] = rng.normal(0.0, 1.0, (k, 2))
    a = rng.normal(0.0, 0.3, (k, 4, 4))
    p = a @ np.swapaxes(a, 1, 2) + np.eye(4) * float(rng.uniform(0.01, 0.2))
    return x, p


def _soft(
    cfg: TrackSection, x: FloatArray, p: FloatArray, z: FloatArray
) -> tuple[JpdaAssociator, FloatArray, SoftAssociation]:
    s, s_inv = kalman.innovation(p, cfg.measurement_std_m)
    cost = gated_costs(x[:, :2], s_inv, z, cfg.gate_euclidean_m, cfg.gate_mahalanobis_chi2)
    det = s[:, 0, 0] * s[:, 1, 1] - s[:, 0, 1] * s[:, 1, 0]
    assoc = JpdaAssociator(cfg)
    k = x.shape[0]
    groups = [np.ones(k, dtype=bool), np.zeros(k, dtype=bool)]
    soft = assoc.associate_soft(cost, groups, -math.log(2.0 * math.pi) - 0.5 * np.log(det))
    return assoc, cost, soft


@pytest.mark.requirement("SR-TRK-8", kind="cross-check", code=CODE)
@settings(max_examples=examples(40), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.integers(2, 4),
    d=st.integers(1, 5),
    far=st.integers(0, 30),
    pd=st.floats(0.5, 0.99),
)
def test_jpda_equals_stone_soup_on_random_gated_clusters(
    seed: int, k: int, d: int, far: int, pd: float
) -> None:
    """Association probabilities and posterior states (the update without the growth cap)
    equal Stone Soup's ``JPDA`` + ``PDAHypothesiser`` + ``PDAUpdater`` within 1e-9, cluster by
    cluster; ``far`` detections outside every gate set the learned clutter density."""
    rng = np.random.default_rng(seed)
    cfg = _jpda_config(jpda_detection_prob=pd)
    x, p = _tracks(rng, k)
    z = np.concatenate([rng.uniform(-0.5, 2.0, (d, 2)), rng.uniform(200.0, 300.0, (far, 2))])
    assoc, cost, soft = _soft(cfg, x, p, z)
    near_gate = np.isfinite(cost) & (np.abs(cost - cfg.gate_mahalanobis_chi2) < 1e-6)
    if near_gate.any():
        current().count("clusters", "skipped: a pair on the gate's edge")
        return
    assert assoc.last is not None
    label, _ = track_clusters(np.isfinite(cost), np.ones(k, dtype=bool))
    for cluster in np.unique(label[soft.pda]):
        rows = np.flatnonzero(label == cluster)
        beta, x_ref, p_ref = stonesoup_jpda(
            x[rows],
            p[rows],
            z,
            cfg.measurement_std_m,
            pd,
            cfg.gate_mahalanobis_chi2,
            assoc.last.clutter_density_per_m2,
        )
        ours = soft.beta[rows]
        assert np.max(np.abs(beta - ours)) <= 1e-9
        x_new, p_new, _ = pda_update(x[rows], p[rows], z, ours, cfg.measurement_std_m, False)
        scale_x = np.sqrt(np.max(np.diagonal(p[rows], axis1=1, axis2=2)))
        assert np.max(np.abs(x_new - x_ref)) <= 1e-9 * scale_x
        assert np.max(np.abs(p_new - p_ref)) <= 1e-9 * np.max(np.abs(p[rows]))
        current().count("clusters", f"{rows.shape[0]} tracks compared")
    if not soft.pda.any():
        current().count("clusters", "no shared detection (cascade)")


@pytest.mark.requirement("SR-TRK-8", kind="property", code=CODE)
@settings(max_examples=examples(100), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), d=st.integers(1, 6))
def test_pda_covariances_stay_symmetric_positive_definite_and_never_grow(
    seed: int, n: int, d: int
) -> None:
    """Whatever the weights and innovations, the capped update's covariance is exactly
    symmetric, positive definite, and no larger in trace than the prediction's; where the cap
    does not act it is the uncapped (Stone Soup) update."""
    rng = np.random.default_rng(seed)
    x, p = _tracks(rng, n)
    z = rng.normal(0.0, float(rng.choice([0.1, 1.0, 5.0])), (d, 2))
    beta = rng.dirichlet(np.ones(d + 1), n)
    std = float(rng.choice([0.01, 0.05, 0.3]))
    x_c, p_c, capped = pda_update(x, p, z, beta, std, True)
    x_u, p_u, _ = pda_update(x, p, z, beta, std, False)
    assert np.array_equal(p_c, np.swapaxes(p_c, 1, 2))
    np.linalg.cholesky(p_c)
    assert np.all(np.trace(p_c, axis1=1, axis2=2) <= np.trace(p, axis1=1, axis2=2) * (1 + 1e-12))
    assert np.array_equal(x_c, x_u)
    assert np.array_equal(p_c[~capped], p_u[~capped])
    current().count("updates", "cap acted", int(capped.sum()))
    current().count("updates", "cap idle", int((~capped).sum()))


@pytest.mark.requirement("SR-TRK-8", "SR-TIM-3", kind="property", code=CODE)
@settings(max_examples=examples(100), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.integers(1, 7),
    d=st.integers(0, 8),
    cap=st.sampled_from([1, 4, 16, 64, 2048]),
)
def test_joint_events_are_bounded_and_over_cap_clusters_fall_back(
    seed: int, k: int, d: int, cap: int
) -> None:
    """A cluster is enumerated only when its bound ``prod(1 + m_i)`` is within
    ``track.jpda_max_hypotheses``, else assigned by the cascade and counted; the bookkeeping
    stays one-to-one, each JPDA track's probabilities sum to 1 and no detection's to more."""
    rng = np.random.default_rng(seed)
    cfg = _jpda_config(jpda_max_hypotheses=cap)
    x, p = _tracks(rng, k)
    z = rng.uniform(-0.5, 2.0, (d, 2))
    assoc, cost, soft = _soft(cfg, x, p, z)
    counts = assoc.last
    assert counts is not None
    feasible = np.isfinite(cost)
    label, _ = track_clusters(feasible, np.ones(k, dtype=bool))
    shared = [c for c in np.unique(label[label >= 0]) if np.count_nonzero(label == c) >= 2]
    bounds = [int(np.prod(feasible[label == c].sum(axis=1) + 1)) for c in shared]
    assert counts.n_clusters == len(shared)
    assert counts.n_fallback == sum(b > cap for b in bounds)
    assert counts.max_hypotheses == max(bounds, default=0)
    pda = soft.pda
    for c, b in zip(shared, bounds, strict=True):
        assert bool(np.all(pda[label == c])) == (b <= cap)
    match = soft.match
    used = match[match >= 0]
    assert np.unique(used).shape[0] == used.shape[0]
    assert np.all(feasible[np.flatnonzero(match >= 0), used])
    beta = soft.beta
    assert np.allclose(beta[pda].sum(axis=1), 1.0, atol=1e-12)
    assert np.all(beta[:, 1:].sum(axis=0) <= 1.0 + 1e-12)
    current().count("clusters", "enumerated", counts.n_jpda)
    current().count("clusters", "fell back (over the cap)", counts.n_fallback)


class JpdaTrackerMachine(TrackerMachine):
    """The track-management state machine of SR-TRK-4 with JPDA association."""

    def __init__(self) -> None:
        super().__init__()
        cfg = overridden(
            default_config(),
            {"track": {**self.config.model_dump(), "association": "jpda"}},
        ).track
        self.config = cfg
        self.tracker = Tracker(cfg)
        self.twin = Tracker(cfg)


@pytest.mark.requirement("SR-TRK-8", "SR-TRK-4", kind="property", code=CODE_TRACKER)
def test_tracker_invariants_hold_with_jpda() -> None:
    """No detection is any track's bookkeeping detection twice, IDs are never reused, the caps
    hold, re-identified tracks keep ID and history, the tracker is deterministic and every
    covariance stays symmetric positive definite, with JPDA updates (the machine's duplicate
    detections and clutter make gates overlap)."""
    run_state_machine_as_test(
        JpdaTrackerMachine,
        settings=settings(max_examples=examples(30), stateful_step_count=30, deadline=None),
    )


def _ms(values: np.ndarray) -> float:
    return float(np.median(values))


@pytest.mark.requirement("SR-TRK-8", kind="campaign", code=CODE_TRACKER)
@ahead
def test_jpda_against_hungarian_on_ray_cast_scenarios(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    """The same ray-cast frames tracked with the Hungarian cascade and with JPDA where gates
    overlap: dolly trains with gaps under 0.5 m, adjacent containers, a crowd of walkers and
    clutter. CLEAR-MOT counts are checked against py-motmetrics on every run."""
    certify = certifying()
    seeds = range(by_profile(ci=1, certify=5, full=10))
    duration = 20.0 if certify else 8.0
    base = overridden(safecase_config, {"track": {"association": "hungarian"}})
    jpda = overridden(safecase_config, {"track": {"association": "jpda"}})
    rows = []
    total_jpda = 0
    for name in DENSE:
        sums: dict[str, np.ndarray] = {}
        walls: dict[str, list[float]] = {"hungarian": [], "jpda": []}
        extra = np.zeros(3)
        for seed in seeds:
            frames = airside_frames(safecase_config, name, seed, duration)
            for label, cfg in (("hungarian", base), ("jpda", jpda)):
                score = score_chain(cfg, frames)
                q = score.quality
                ref = motmetrics_counts(score.truths, score.hypotheses)
                assert ref["num_switches"] == q.id_switches
                assert ref["num_fragmentations"] == q.fragmentations
                assert ref["num_misses"] == q.n_misses
                assert ref["num_false_positives"] == q.n_false_positives
                assert ref["mota"] == pytest.approx(q.mota, abs=1e-12)
                row = np.array(
                    [
                        q.id_switches,
                        q.fragmentations,
                        q.n_misses,
                        q.n_false_positives,
                        q.n_truth,
                        q.gospa_mean_m * q.n_frames,
                        q.n_frames,
                        q.n_hypothesis_ids,
                    ]
                )
                sums[label] = sums.get(label, np.zeros_like(row)) + row
                walls[label].extend(score.track_wall_s.tolist())
                if label == "jpda":
                    extra += [
                        score.jpda_enumerated,
                        score.jpda_fallbacks,
                        score.jpda_max_hypotheses > 0,
                    ]
                    total_jpda += score.jpda_enumerated
        for label in ("hungarian", "jpda"):
            s = sums[label]
            mota = 1.0 - (s[2] + s[3] + s[0]) / s[4]
            rows.append(
                [
                    name,
                    label,
                    int(s[0]),
                    int(s[1]),
                    f"{mota:.3f}",
                    f"{s[5] / s[6]:.3f}",
                    int(s[7]),
                    timed(_ms(np.array(walls[label]))),
                    f"{_ms(np.array(walls[label])) / _ms(np.array(walls['hungarian'])):.2f}",
                    int(extra[0]) if label == "jpda" else "-",
                    int(extra[1]) if label == "jpda" else "-",
                ]
            )
    evidence.table(
        "association A/B on ray-cast apron scenarios",
        [
            "scenario",
            "association",
            "ID switches",
            "fragmentations",
            "MOTA",
            "mean GOSPA m (c=2, p=2)",
            "track IDs",
            "track stage p50 ms",
            "time vs Hungarian",
            "JPDA clusters",
            "fallbacks (over cap)",
        ],
        rows,
        caption=f"{len(seeds)} seed(s) x {duration:.0f} s per scenario, robot standing, 1080-beam "
        "scanner; truth: objects with at least cluster.min_points returns at the centroid of "
        "their returns; tracks on static structure are not scored; counts equal py-motmetrics'",
    )
    assert total_jpda > 0, "JPDA never engaged: the A/B compared nothing"
