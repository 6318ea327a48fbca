"""Latency statistics and pWCET on distributions whose tail is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from evidence.wcet import (
    exceedance_plot,
    fit_gev,
    fit_gev_maxima,
    fit_gpd,
    iid_checks,
    latency_stats,
    measured_latency_bound,
    pwcet,
)
from pipeline.config import default_config
from pipeline.errors import EvidenceError
from safety.model.stopping import StoppingParams

WCET = ["evidence/wcet.py"]


def test_order_statistics() -> None:
    s = latency_stats(np.arange(1, 101) * 1e-3)
    assert (s.n, s.max_s) == (100, 0.1)
    assert s.p50_s == pytest.approx(0.0505)
    assert s.p99_s == pytest.approx(0.09901)


@pytest.mark.requirement("SR-TIM-1", kind="example", code=WCET)
def test_exponential_tail_is_recovered() -> None:
    # Exponential latencies (the Gumbel domain, xi = 0): P(X > x) = exp(-x / 2 ms), so the
    # latency exceeded once per 1e9 cycles is 2 ms * ln(1e9) = 41.4 ms.
    rng = np.random.default_rng(1)
    samples = rng.exponential(2e-3, 20_000)
    truth = 2e-3 * math.log(1e9)
    gev = fit_gev(samples, block_size=50)
    gpd = fit_gpd(samples, threshold_quantile=0.95)
    assert abs(gev.shape_xi) < 0.15
    assert abs(gpd.shape_xi) < 0.15
    assert 0.6 * truth < gev.pwcet_s < 1.6 * truth
    assert 0.6 * truth < gpd.pwcet_s < 1.6 * truth
    assert gev.fit_ok
    assert gpd.fit_ok
    # The fitted tails give back the exceedance probability they were solved for.
    assert gev.exceedance(gev.pwcet_s) == pytest.approx(1e-9, rel=1e-6)
    assert gpd.exceedance(gpd.pwcet_s) == pytest.approx(1e-9, rel=1e-6)


@pytest.mark.requirement("SR-TIM-1", kind="example", code=WCET)
def test_given_block_maxima_fit_as_the_blocks_they_came_from() -> None:
    """A campaign hands over each run's slowest cycle: fitting those maxima is fitting the
    blocks of the same samples, and calling the blocks shorter than they were (the shortest
    run's length) gives a larger pWCET, never a smaller one."""
    rng = np.random.default_rng(5)
    samples = rng.exponential(2e-3, 12_000)
    maxima = samples.reshape(100, 120).max(axis=1)
    whole = fit_gev(samples, block_size=120)
    given = fit_gev_maxima(maxima, block_size=120)
    assert (given.n_fit, given.block_size) == (100, 120)
    assert given.pwcet_s == whole.pwcet_s
    assert given.shape_xi == whole.shape_xi
    shorter = fit_gev_maxima(maxima, block_size=90)
    assert shorter.pwcet_s > given.pwcet_s
    assert shorter.exceedance(shorter.pwcet_s) == pytest.approx(1e-9, rel=1e-6)


def test_bounded_tail_has_negative_shape_and_stays_below_its_end_point() -> None:
    rng = np.random.default_rng(2)
    samples = 3e-3 + 1e-3 * rng.beta(2.0, 3.0, 20_000)  # never above 4 ms
    report = pwcet(samples)
    assert report.gev.shape_xi < 0
    assert report.gpd.shape_xi < 0
    assert samples.max() <= report.bound_s < 4.3e-3


def test_heavy_tail_is_reported_heavy() -> None:
    rng = np.random.default_rng(3)
    samples = 1e-3 * (1.0 + stats.genpareto.rvs(0.4, size=20_000, random_state=rng))
    gpd = fit_gpd(samples, threshold_quantile=0.9)
    assert 0.25 < gpd.shape_xi < 0.55
    assert gpd.pwcet_s > 1.0  # seconds: a heavy tail extrapolates far


def test_goodness_of_fit_by_monte_carlo_rejects_a_wrong_model() -> None:
    rng = np.random.default_rng(4)
    good = fit_gpd(rng.exponential(1e-3, 4000), gof_mc=99, seed=1)
    assert good.ad_pvalue >= 0.05
    # Excesses from two well-separated populations are not one generalised Pareto tail.
    mixed = np.concatenate([rng.exponential(1e-4, 3800), 5e-3 + rng.uniform(0, 1e-4, 200)])
    bad = fit_gpd(mixed, threshold_quantile=0.9, gof_mc=99, seed=1)
    assert not bad.fit_ok


def test_iid_checks_see_correlation_and_drift() -> None:
    rng = np.random.default_rng(5)
    independent = iid_checks(rng.normal(1.0, 0.1, 4000))
    assert abs(independent.lag1_autocorr) < 0.05
    assert independent.runs_pvalue > 0.01
    assert independent.halves_pvalue > 0.01
    ar = np.empty(4000)
    ar[0] = 0.0
    noise = rng.normal(0.0, 0.1, 4000)
    for i in range(1, 4000):
        ar[i] = 0.9 * ar[i - 1] + noise[i]
    correlated = iid_checks(ar + 5.0)
    assert correlated.lag1_autocorr > 0.8
    assert correlated.runs_pvalue < 1e-6
    drift = iid_checks(np.linspace(1.0, 2.0, 4000) + rng.normal(0, 0.01, 4000))
    assert drift.halves_pvalue < 1e-6


def test_bad_samples_are_named() -> None:
    with pytest.raises(EvidenceError, match=r"\[2\] = nan"):
        latency_stats([1e-3, 2e-3, math.nan])
    with pytest.raises(EvidenceError, match=r"\[0\] = -0.001"):
        latency_stats([-1e-3])
    with pytest.raises(EvidenceError, match="none given"):
        latency_stats([])
    with pytest.raises(EvidenceError, match="expected at least 10 blocks"):
        fit_gev(np.ones(100), block_size=20)
    with pytest.raises(EvidenceError, match="expected at least 10 blocks"):
        fit_gev(np.ones(100), block_size=0)
    with pytest.raises(EvidenceError, match="9 block maxima of 120 cycles"):
        fit_gev_maxima(np.ones(9), block_size=120)
    with pytest.raises(EvidenceError, match=r"all 12 block maxima are 0.03 s; a tail needs spread"):
        fit_gev_maxima(np.full(12, 0.03), block_size=120)
    with pytest.raises(EvidenceError, match="10 block maxima of 0 cycles"):
        fit_gev_maxima(np.ones(10), block_size=0)
    with pytest.raises(EvidenceError, match=r"exceedance_prob = 2"):
        pwcet(np.ones(1000), exceedance_prob=2.0)


@pytest.mark.requirement("SR-TIM-1", kind="example", code=[*WCET, "safety/model/stopping.py"])
def test_bound_feeds_the_stopping_model_seam() -> None:
    rng = np.random.default_rng(6)
    samples = 2e-3 + rng.gamma(4.0, 2e-4, 5000)
    bound, provenance = measured_latency_bound(samples, clock="thread CPU time")
    assert bound >= samples.max()
    assert provenance["perception_latency_s"] == bound
    assert provenance["latency_source"].startswith("measured: pWCET at 1e-09/cycle")
    assert provenance["gev"]["block_size"] == 50
    params = StoppingParams.from_config(
        default_config(),
        perception_latency_s=bound,
        latency_source=provenance["latency_source"],
    )
    assert params.latency_provenance()["perception_latency_source"] == provenance["latency_source"]
    assert params.reaction_s == pytest.approx(bound + 0.1)
    report = pwcet(samples)
    figure = exceedance_plot(samples, report, budget_s=0.08)
    assert len(figure.axes) == 1
