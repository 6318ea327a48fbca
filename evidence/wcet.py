"""Latency statistics and probabilistic WCET by extreme value theory (SR-TIM-1).

From per-cycle latency samples [s]: p50 / p99 / max, and the latency exceeded with a given
small probability per cycle (the pWCET, default 1e-9: about once in 30 years at 10 Hz), two
ways, both with scipy.stats:

* **block maxima + GEV**: the maxima of consecutive blocks of ``block_size`` cycles are fitted
  by a generalised extreme value distribution (maximum likelihood, several starting points, the
  best likelihood kept); a per-cycle probability ``p`` is a per-block probability
  ``1 - (1 - p)^B``;
* **peaks over threshold + GPD**: the excesses over the ``threshold_quantile`` quantile are
  fitted by a generalised Pareto distribution; ``P(X > x) = rate * GPD.sf(x - u)``.

Goodness of fit: Kolmogorov-Smirnov against the fitted distribution (optimistic, since the
parameters were estimated from the same data) and, with ``gof_mc > 0``, scipy's
``goodness_of_fit`` (Anderson-Darling with the parameters re-fitted on every Monte Carlo
sample, which gives an honest p-value). EVT assumes independent, identically distributed
cycles; :func:`iid_checks` reports the lag-1 autocorrelation, a runs test above/below the
median and a two-sample KS test between the halves, so the evidence shows how far that holds.

:func:`measured_latency_bound` turns samples into the value and provenance that the stopping
model's latency seam takes (``StoppingParams.from_config(config, perception_latency_s=...,
latency_source=...)``): the largest of both pWCET estimates and the observed maximum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.errors import EvidenceError
from pipeline.jsoncodec import jsonable

# scipy.stats is imported in the functions that use it: importing it takes about half a second,
# which every safecase command (this module is on the CLI's import path) would pay.

__all__ = [
    "MIN_FIT_POINTS",
    "IidChecks",
    "LatencyStats",
    "PwcetReport",
    "TailFit",
    "exceedance_plot",
    "fit_gev",
    "fit_gev_maxima",
    "fit_gpd",
    "iid_checks",
    "latency_stats",
    "measured_latency_bound",
    "pwcet",
]

FloatArray = npt.NDArray[np.float64]
MIN_FIT_POINTS = 10


def _samples(values: npt.ArrayLike) -> FloatArray:
    array = np.asarray(values, dtype=np.float64).ravel()
    if array.size == 0:
        raise EvidenceError("latency samples: none given; expected durations in seconds")
    bad = ~(np.isfinite(array) & (array >= 0.0))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise EvidenceError(
            f"latency samples: [{i}] = {float(array[i])!r} ({int(bad.sum())} bad); expected finite "
            "durations >= 0 s"
        )
    return array


@dataclass(frozen=True, slots=True)
class LatencyStats:
    """Order statistics of latency samples [s]."""

    n: int
    p50_s: float
    p99_s: float
    max_s: float
    mean_s: float


def latency_stats(samples: npt.ArrayLike) -> LatencyStats:
    """p50, p99, max and mean of ``samples`` [s] (SR-TIM-1)."""
    x = _samples(samples)
    p50, p99 = np.percentile(x, [50, 99])
    return LatencyStats(int(x.size), float(p50), float(p99), float(x.max()), float(x.mean()))


@dataclass(frozen=True, slots=True)
class TailFit:
    """A fitted tail model and its pWCET at ``exceedance_prob`` per cycle.

    ``shape_xi`` is the EVT shape in the usual sign convention (xi > 0 heavy tail, xi < 0 a
    finite upper end point; scipy's ``c`` is ``-xi`` for the GEV, ``+xi`` for the GPD).
    ``block_size`` (GEV) or ``threshold_s`` and ``rate`` (GPD, exceedances per cycle) locate the
    tail. ``ks_pvalue`` is optimistic (estimated parameters); ``ad_pvalue`` (NaN unless
    computed) is the Monte Carlo Anderson-Darling p-value with re-fitting.
    """

    method: str
    shape_xi: float
    loc: float
    scale: float
    n_fit: int
    pwcet_s: float
    exceedance_prob: float
    ks_statistic: float
    ks_pvalue: float
    ad_pvalue: float = math.nan
    block_size: int = 0
    threshold_s: float = math.nan
    rate: float = math.nan

    def exceedance(self, latency_s: npt.ArrayLike) -> FloatArray:
        """Per-cycle probability that a cycle takes longer than ``latency_s`` (model tail)."""
        from scipy import stats

        x = np.asarray(latency_s, dtype=np.float64)
        if self.method == "gev":
            per_block = stats.genextreme.sf(x, -self.shape_xi, self.loc, self.scale)
            return np.asarray(-np.expm1(np.log1p(-per_block) / self.block_size))
        tail = self.rate * stats.genpareto.sf(x - self.threshold_s, self.shape_xi, 0.0, self.scale)
        return np.asarray(np.where(x >= self.threshold_s, tail, np.nan))

    @property
    def fit_ok(self) -> bool:
        """False when a goodness-of-fit test rejects the model at the 5 % level."""
        return self.ks_pvalue >= 0.05 and not self.ad_pvalue < 0.05


def _best_fit(
    dist: Any, data: FloatArray, starts: list[tuple[float, dict[str, float]]]
) -> tuple[float, ...]:
    """Maximum likelihood from several starting points ``(shape, keywords)``; the best finite
    likelihood wins (scipy's optimiser alone can stop in a poor local optimum)."""
    best: tuple[float, tuple[float, ...]] | None = None
    for shape, keywords in starts:
        try:
            with np.errstate(all="ignore"):
                params = tuple(float(p) for p in dist.fit(data, shape, **keywords))
                nll = float(dist.nnlf(params, data))
        except (ValueError, RuntimeError, FloatingPointError):
            continue
        if math.isfinite(nll) and (best is None or nll < best[0]):
            best = (nll, params)
    if best is None:
        raise EvidenceError(f"{dist.name} fit failed from every starting point")
    return best[1]


def _ad_pvalue(dist: Any, data: FloatArray, gof_mc: int, seed: int, **known: float) -> float:
    from scipy import stats

    if gof_mc <= 0:
        return math.nan
    with np.errstate(all="ignore"):
        result = stats.goodness_of_fit(
            dist,
            data,
            known_params=known or None,
            statistic="ad",
            n_mc_samples=gof_mc,
            rng=np.random.default_rng(seed),
        )
    return float(result.pvalue)


def fit_gev(
    samples: npt.ArrayLike,
    *,
    block_size: int = 50,
    exceedance_prob: float = 1e-9,
    gof_mc: int = 0,
    seed: int = 0,
) -> TailFit:
    """GEV fit of block maxima and its pWCET [s] at ``exceedance_prob`` per cycle."""
    x = _samples(samples)
    n_blocks = x.size // block_size if block_size >= 1 else 0
    if n_blocks < MIN_FIT_POINTS:
        raise EvidenceError(
            f"GEV: {x.size} samples make {n_blocks} blocks of {block_size}; expected at least "
            f"{MIN_FIT_POINTS} blocks"
        )
    maxima = x[: n_blocks * block_size].reshape(n_blocks, block_size).max(axis=1)
    return fit_gev_maxima(
        maxima, block_size=block_size, exceedance_prob=exceedance_prob, gof_mc=gof_mc, seed=seed
    )


def fit_gev_maxima(
    maxima_s: npt.ArrayLike,
    *,
    block_size: int,
    exceedance_prob: float = 1e-9,
    gof_mc: int = 0,
    seed: int = 0,
) -> TailFit:
    """GEV fit of given block maxima [s], each the largest of ``block_size`` or more cycles
    (a closed-loop campaign's runs: one block per run, the largest cycle of each), and its
    pWCET [s] at ``exceedance_prob`` per cycle (SR-TIM-1, SR-RUN-8).

    Blocks of unequal length are read as blocks of the shortest (``block_size``): a longer
    block's maximum is stochastically larger, so the fitted tail only grows, and the per-block
    probability ``1 - (1 - p)^B`` is smallest at the smallest B, which takes the fitted
    distribution further into its tail: both err on the safe side.
    """
    from scipy import stats

    maxima = _samples(maxima_s)
    if block_size < 1 or maxima.size < MIN_FIT_POINTS:
        raise EvidenceError(
            f"GEV: {maxima.size} block maxima of {block_size} cycles; expected at least "
            f"{MIN_FIT_POINTS} blocks of at least one cycle"
        )
    if np.ptp(maxima) == 0.0:
        raise EvidenceError(
            f"GEV: all {maxima.size} block maxima are {float(maxima[0])!r} s; a tail needs spread"
        )
    gumbel_loc, gumbel_scale = stats.gumbel_r.fit(maxima)
    guess = {"loc": float(gumbel_loc), "scale": float(gumbel_scale)}
    starts = [(c, guess) for c in (0.0, 0.2, -0.2, 0.5, -0.5)]
    c, loc, scale = _best_fit(stats.genextreme, maxima, starts)
    per_block = -math.expm1(block_size * math.log1p(-exceedance_prob))
    ks = stats.kstest(maxima, "genextreme", (c, loc, scale))
    return TailFit(
        method="gev",
        shape_xi=-c,
        loc=loc,
        scale=scale,
        n_fit=int(maxima.size),
        pwcet_s=float(stats.genextreme.isf(per_block, c, loc, scale)),
        exceedance_prob=exceedance_prob,
        ks_statistic=float(ks.statistic),
        ks_pvalue=float(ks.pvalue),
        ad_pvalue=_ad_pvalue(stats.genextreme, maxima, gof_mc, seed),
        block_size=block_size,
    )


def fit_gpd(
    samples: npt.ArrayLike,
    *,
    threshold_quantile: float = 0.95,
    exceedance_prob: float = 1e-9,
    gof_mc: int = 0,
    seed: int = 0,
) -> TailFit:
    """GPD fit of the excesses over a high quantile and its pWCET [s] per cycle."""
    from scipy import stats

    x = _samples(samples)
    u = float(np.quantile(x, threshold_quantile))
    excess = x[x > u] - u
    if excess.size < MIN_FIT_POINTS:
        raise EvidenceError(
            f"GPD: {excess.size} samples above the {threshold_quantile} quantile; expected at "
            f"least {MIN_FIT_POINTS}"
        )
    rate = excess.size / x.size
    if exceedance_prob >= rate:
        raise EvidenceError(f"GPD: exceedance_prob {exceedance_prob} not below the rate {rate}")
    starts = [(c, {"floc": 0.0}) for c in (0.0, 0.2, -0.2)]
    c, _, scale = _best_fit(stats.genpareto, excess, starts)
    ks = stats.kstest(excess, "genpareto", (c, 0.0, scale))
    return TailFit(
        method="gpd",
        shape_xi=c,
        loc=0.0,
        scale=scale,
        n_fit=int(excess.size),
        pwcet_s=u + float(stats.genpareto.isf(exceedance_prob / rate, c, 0.0, scale)),
        exceedance_prob=exceedance_prob,
        ks_statistic=float(ks.statistic),
        ks_pvalue=float(ks.pvalue),
        ad_pvalue=_ad_pvalue(stats.genpareto, excess, gof_mc, seed, loc=0.0),
        threshold_s=u,
        rate=rate,
    )


@dataclass(frozen=True, slots=True)
class IidChecks:
    """How far the samples look independent and identically distributed (EVT's premise).

    ``lag1_autocorr``: correlation of consecutive samples; ``runs_pvalue``: Wald-Wolfowitz runs
    test above/below the median (small: clustered in time); ``halves_pvalue``: two-sample KS
    between the first and second half (small: the distribution drifted).
    """

    lag1_autocorr: float
    runs_z: float
    runs_pvalue: float
    halves_pvalue: float


def iid_checks(samples: npt.ArrayLike) -> IidChecks:
    """Independence and stationarity indicators of ``samples`` (reported, not enforced)."""
    from scipy import stats

    x = _samples(samples)
    if x.size < 4:
        raise EvidenceError(f"iid checks: {x.size} samples; expected at least 4")
    d = x - x.mean()
    denom = float(np.dot(d, d))
    lag1 = float(np.dot(d[:-1], d[1:]) / denom) if denom > 0 else 0.0
    above = x[x != np.median(x)] > np.median(x)
    n1, n2 = int(above.sum()), int((~above).sum())
    runs = 1 + int(np.count_nonzero(above[1:] != above[:-1])) if above.size else 0
    n = n1 + n2
    if n1 and n2:
        mean = 2.0 * n1 * n2 / n + 1.0
        var = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1.0))
        z = (runs - mean) / math.sqrt(var) if var > 0 else 0.0
    else:
        z = 0.0
    half = x.size // 2
    return IidChecks(
        lag1_autocorr=lag1,
        runs_z=float(z),
        runs_pvalue=float(2.0 * stats.norm.sf(abs(z))),
        halves_pvalue=float(stats.ks_2samp(x[:half], x[half:]).pvalue),
    )


@dataclass(frozen=True, slots=True)
class PwcetReport:
    """Statistics, both tail fits and the resulting bound (the largest of the two pWCETs and
    the observed maximum) for one set of samples."""

    stats: LatencyStats
    gev: TailFit
    gpd: TailFit
    iid: IidChecks
    exceedance_prob: float
    bound_s: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form (non-finite floats as text: :mod:`pipeline.jsoncodec`)."""
        data: dict[str, Any] = jsonable(
            {
                "stats": self.stats,
                "gev": self.gev,
                "gpd": self.gpd,
                "iid": self.iid,
                "exceedance_prob": self.exceedance_prob,
                "bound_s": self.bound_s,
            }
        )
        return data


def pwcet(
    samples: npt.ArrayLike,
    *,
    exceedance_prob: float = 1e-9,
    block_size: int = 50,
    threshold_quantile: float = 0.95,
    gof_mc: int = 0,
    seed: int = 0,
) -> PwcetReport:
    """Statistics, GEV and GPD pWCET at ``exceedance_prob`` per cycle, and the bound [s]."""
    if not 0.0 < exceedance_prob < 1.0:
        raise EvidenceError(f"exceedance_prob = {exceedance_prob!r}: expected a value in (0, 1)")
    x = _samples(samples)
    gev = fit_gev(
        x, block_size=block_size, exceedance_prob=exceedance_prob, gof_mc=gof_mc, seed=seed
    )
    gpd = fit_gpd(
        x,
        threshold_quantile=threshold_quantile,
        exceedance_prob=exceedance_prob,
        gof_mc=gof_mc,
        seed=seed,
    )
    summary = latency_stats(x)
    bound = max(gev.pwcet_s, gpd.pwcet_s, summary.max_s)
    return PwcetReport(summary, gev, gpd, iid_checks(x), exceedance_prob, float(bound))


def measured_latency_bound(
    samples: npt.ArrayLike,
    *,
    what: str = "scan-to-decision latency",
    clock: str = "wall clock",
    exceedance_prob: float = 1e-9,
    **options: Any,
) -> tuple[float, dict[str, Any]]:
    """A latency bound [s] from ``samples`` and its provenance, for the stopping model's seam.

    Returns ``(bound_s, provenance)``; pass them on as ``StoppingParams.from_config(config,
    perception_latency_s=bound_s, latency_source=provenance["latency_source"])``. The bound is
    the largest of the GEV and GPD pWCET at ``exceedance_prob`` per cycle and the observed
    maximum; the provenance holds the statistics, both fits with their goodness of fit, the
    i.i.d. checks and ``fit_ok`` (False when a goodness-of-fit test rejects a model).
    """
    report = pwcet(samples, exceedance_prob=exceedance_prob, **options)
    s = report.stats
    source = (
        f"measured: pWCET at {exceedance_prob:g}/cycle of the {what} ({clock}; max of GEV "
        f"block maxima B={report.gev.block_size}, GPD over the "
        f"{options.get('threshold_quantile', 0.95):g} quantile and the observed maximum), "
        f"n={s.n}, p99={s.p99_s * 1e3:.3f} ms, max={s.max_s * 1e3:.3f} ms"
    )
    provenance = {
        "perception_latency_s": report.bound_s,
        "latency_source": source,
        "what": what,
        "clock": clock,
        "fit_ok": report.gev.fit_ok and report.gpd.fit_ok,
        **report.as_dict(),
    }
    return report.bound_s, provenance


def exceedance_plot(
    samples: npt.ArrayLike,
    report: PwcetReport,
    *,
    budget_s: float | None = None,
    title: str = "latency exceedance",
) -> Any:
    """Empirical per-cycle exceedance of ``samples`` with both fitted tails (log-log), the
    p99, the pWCET bound and (when given) the latency budget of the stopping proof."""
    import matplotlib.pyplot as plt

    x = np.sort(_samples(samples))
    n = x.size
    empirical = 1.0 - np.arange(1, n + 1) / (n + 1.0)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    ax.loglog(x * 1e3, empirical, ".", ms=3, color="0.3", label=f"measured (n={n})")
    top = max(report.bound_s, budget_s or 0.0) * 1.1
    for fit, style in ((report.gev, "-"), (report.gpd, "--")):
        start = fit.threshold_s if fit.method == "gpd" else float(np.median(x))
        grid = np.geomspace(max(start, x[0]), max(top, fit.pwcet_s), 400)
        with np.errstate(all="ignore"):
            curve = fit.exceedance(grid)
        ok = np.isfinite(curve) & (curve > 0)
        ax.loglog(
            grid[ok] * 1e3,
            curve[ok],
            style,
            label=(
                f"{fit.method.upper()} (xi={fit.shape_xi:+.2f}): pWCET {fit.pwcet_s * 1e3:.3g} ms"
            ),
        )
    ax.axhline(report.exceedance_prob, color="k", lw=0.8, ls=":")
    ax.axvline(report.stats.p99_s * 1e3, color="tab:green", lw=0.8, label="p99")
    ax.axvline(report.bound_s * 1e3, color="tab:red", lw=1.0, label="bound")
    if budget_s is not None:
        ax.axvline(budget_s * 1e3, color="tab:purple", lw=1.5, ls="-.", label="proof's budget")
    ax.set_xlim(x[0] * 1e3 * 0.8, top * 1e3)
    ax.set_ylim(report.exceedance_prob / 10, 1.0)
    ax.set_xlabel("latency [ms]")
    ax.set_ylabel("P(latency > x) per cycle")
    ax.set_title(title)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return fig
