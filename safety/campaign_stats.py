"""What a campaign shows: the contact rate with its exact upper bound, per scenario and overall.

The quantity bounded is the per-run probability ``p`` of a contact while the robot moves (a
passive-safety violation, SR-RUN-1) in encounters drawn as the campaign draws them. Runs are
independent and seeded, so the number of runs with such a contact is binomial; its
Clopper-Pearson upper confidence limit (``scipy.stats.binomtest(...).proportion_ci(method=
"exact")``, two-sided interval, so the one-sided level of its upper end is ``(1 + level) / 2``)
is the largest ``p`` the campaign does not exclude. With no violation in ``n`` runs the
one-sided 95 % bound is ``1 - 0.05 ** (1 / n)``: about ``3 / n`` (the rule of three). A run that
raised counts as a run with a violation: a crash of the safety function is not evidence of
its safety (SR-RUN-8).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from scipy.stats import binomtest

from safety.campaign import CampaignRow

__all__ = [
    "BOUND_COLUMNS",
    "RateBound",
    "bound_table",
    "by_scenario",
    "closest_figure",
    "command_mix",
    "contact_bound",
    "cpu_ms_summary",
    "upper_limit",
]


@dataclass(frozen=True)
class RateBound:
    """Runs, violations among them, the observed rate and its one-sided upper bounds."""

    runs: int
    violations: int
    errors: int
    rate: float
    upper_95: float
    upper_99: float


def upper_limit(violations: int, runs: int, one_sided: float) -> float:
    """Clopper-Pearson one-sided upper limit at level ``one_sided`` of a binomial rate."""
    if runs < 1:
        return 1.0
    two_sided = 2.0 * one_sided - 1.0
    ci = binomtest(violations, runs).proportion_ci(confidence_level=two_sided, method="exact")
    return float(ci.high)


def _violated(row: CampaignRow) -> bool:
    return row.error is not None or bool(row.moving_contacts_mps)


def contact_bound(rows: Sequence[CampaignRow]) -> RateBound:
    """The contact-while-moving rate of ``rows`` with its 95 % and 99 % one-sided upper
    bounds (module docstring; a run that raised counts as a violation)."""
    n = len(rows)
    k = sum(_violated(r) for r in rows)
    return RateBound(
        runs=n,
        violations=k,
        errors=sum(r.error is not None for r in rows),
        rate=k / n if n else 0.0,
        upper_95=upper_limit(k, n, 0.95),
        upper_99=upper_limit(k, n, 0.99),
    )


def by_scenario(rows: Sequence[CampaignRow]) -> dict[str, RateBound]:
    """:func:`contact_bound` of each scenario's rows, scenarios in first-seen order."""
    groups: dict[str, list[CampaignRow]] = {}
    for row in rows:
        groups.setdefault(row.encounter.scenario, []).append(row)
    return {name: contact_bound(group) for name, group in groups.items()}


BOUND_COLUMNS = ("scenario", "runs", "contacts while moving", "runs that raised", "95 %", "99 %")


def bound_table(rows: Sequence[CampaignRow]) -> list[list[str]]:
    """:func:`by_scenario` and the overall bound as table rows (columns :data:`BOUND_COLUMNS`,
    the last row ``all``)."""
    return [
        [
            name,
            str(b.runs),
            str(b.violations - b.errors),
            str(b.errors),
            f"{b.upper_95:.3g}",
            f"{b.upper_99:.3g}",
        ]
        for name, b in {**by_scenario(rows), "all": contact_bound(rows)}.items()
    ]


def cpu_ms_summary(rows: Sequence[CampaignRow]) -> dict[str, float]:
    """The slowest cycles: the largest per-run p99 and max thread CPU time [ms] over the
    campaign, and the median of the runs' p50 (the campaign is the largest latency sample)."""
    timed = [r.cpu_ms for r in rows if r.cpu_ms]
    if not timed:
        return {}
    return {
        "median_p50": float(np.median([t["p50"] for t in timed])),
        "max_p99": max(t["p99"] for t in timed),
        "max": max(t["max"] for t in timed),
    }


def command_mix(rows: Sequence[CampaignRow]) -> Counter[str]:
    """Cycles per command over the campaign."""
    total: Counter[str] = Counter()
    for row in rows:
        total.update(row.commands)
    return total


def closest_figure(rows: Sequence[CampaignRow], title: str = "") -> Figure:
    """The distribution of each run's closest approach [m] (empirical CDF, runs without any
    object left out), with the robot's contact threshold (0 m) marked."""
    closest = np.sort([r.closest_m for r in rows if np.isfinite(r.closest_m)])
    fig = Figure(figsize=(6.4, 3.6))
    ax = fig.add_subplot()
    if closest.size:
        ax.step(closest, np.arange(1, closest.size + 1) / closest.size, where="post")
    ax.axvline(0.0, color="tab:red", linestyle="--", label="contact")
    ax.set_xlabel("closest approach in the run [m]")
    ax.set_ylabel("share of runs at or below")
    ax.set_title(title or f"closest approach, {closest.size} runs")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    return fig
