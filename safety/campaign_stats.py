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

Availability (SR-AVL-1, SR-RUN-8), over the rows that carry the shadow oracle's figures: the
STOP share of cycles, the nuisance share of cycles (a STOP the oracle would not have commanded
in the same situation, so never more than the STOP share), what set our command in those
cycles, and the mean and least of our progress over the oracle's closed loop where the oracle
ran (``safecase campaign --oracle``).

Both are given per scenario and overall; an airside scenario set in another weather than its
own is its own line, ``scenario@weather``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipeline.types import FloatArray
from safety.campaign import CampaignRow

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "AVAILABILITY_COLUMNS",
    "BOUND_COLUMNS",
    "Availability",
    "RateBound",
    "availability",
    "availability_table",
    "bound_table",
    "by_scenario",
    "closest_figure",
    "command_mix",
    "contact_bound",
    "cpu_block_maxima",
    "cpu_ms_summary",
    "nuisance_causes",
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
    # scipy.stats and matplotlib are imported where used: together they cost every `safecase`
    # command a second and a half at start.
    from scipy.stats import binomtest

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
    """:func:`contact_bound` of each scenario's rows, scenarios in first-seen order (an airside
    scenario in another weather than its own apart, as ``scenario@weather``)."""
    return {name: contact_bound(group) for name, group in _groups(rows).items()}


def _groups(rows: Sequence[CampaignRow]) -> dict[str, list[CampaignRow]]:
    """Each scenario's rows by :attr:`~safety.campaign_plan.Encounter.label` (``scenario`` or
    ``scenario@weather``: fog and clear air are not pooled), in first-seen order."""
    groups: dict[str, list[CampaignRow]] = {}
    for row in rows:
        groups.setdefault(row.encounter.label, []).append(row)
    return groups


BOUND_COLUMNS = (
    "scenario",
    "runs",
    "contacts while moving",
    "runs that raised",
    "closest [m]",
    "95 %",
    "99 %",
)


def bound_table(rows: Sequence[CampaignRow]) -> list[list[str]]:
    """:func:`by_scenario` and the overall bound as table rows (columns :data:`BOUND_COLUMNS`:
    with the least closest approach of the group's runs [m], ``-`` without any object; the last
    row ``all``)."""
    groups = {**_groups(rows), "all": list(rows)}
    table = []
    for name, group in groups.items():
        b = contact_bound(group)
        closest = min((r.closest_m for r in group), default=float("inf"))
        table.append(
            [
                name,
                str(b.runs),
                str(b.violations - b.errors),
                str(b.errors),
                f"{closest:.2f}" if np.isfinite(closest) else "-",
                f"{b.upper_95:.3g}",
                f"{b.upper_99:.3g}",
            ]
        )
    return table


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


def cpu_block_maxima(rows: Sequence[CampaignRow]) -> tuple[FloatArray, int]:
    """Each timed run's slowest cycle [s] of thread CPU time, and the fewest cycles any of those
    runs had: block maxima for the extreme-value fit of the cycle time (SR-TIM-1; the
    campaign is the largest latency sample). Runs without timings (failed rows) are left out;
    no timed run gives an empty array and 0."""
    timed = [r for r in rows if r.cpu_ms and r.cycles > 0]
    maxima = np.array([r.cpu_ms["max"] for r in timed], dtype=np.float64) * 1e-3
    return maxima, min((r.cycles for r in timed), default=0)


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
    from matplotlib.figure import Figure

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


@dataclass(frozen=True)
class Availability:
    """Availability over a set of rows (module docstring): ``runs`` rows with the shadow's
    figures, their ``cycles``, STOP and nuisance STOP cycles among them; ``oracle_runs`` of
    them also ran the oracle's closed loop, with the mean and least progress share."""

    runs: int
    cycles: int
    stop_cycles: int
    nuisance_cycles: int
    oracle_runs: int
    mean_progress_share: float | None
    worst_progress_share: float | None

    @property
    def stop_share(self) -> float:
        """STOP cycles over all cycles (0 without cycles)."""
        return self.stop_cycles / self.cycles if self.cycles else 0.0

    @property
    def nuisance_share(self) -> float:
        """Nuisance STOP cycles over all cycles (0 without cycles)."""
        return self.nuisance_cycles / self.cycles if self.cycles else 0.0


def _shadowed(rows: Sequence[CampaignRow]) -> list[CampaignRow]:
    return [r for r in rows if r.nuisance_cycles is not None]


def availability(rows: Sequence[CampaignRow]) -> Availability:
    """The availability figures of ``rows`` (rows without the shadow's figures left out)."""
    seen = _shadowed(rows)
    shares = [r.progress_share for r in seen if r.progress_share is not None]
    return Availability(
        runs=len(seen),
        cycles=sum(r.cycles for r in seen),
        stop_cycles=sum(r.commands.get("STOP", 0) for r in seen),
        nuisance_cycles=sum(r.nuisance_cycles or 0 for r in seen),
        oracle_runs=len(shares),
        mean_progress_share=float(np.mean(shares)) if shares else None,
        worst_progress_share=min(shares) if shares else None,
    )


def nuisance_causes(rows: Sequence[CampaignRow]) -> Counter[str]:
    """What set our command in the nuisance STOP cycles, over the campaign."""
    total: Counter[str] = Counter()
    for row in rows:
        total.update(row.nuisance_causes)
    return total


AVAILABILITY_COLUMNS = (
    "scenario",
    "runs",
    "STOP",
    "nuisance STOP",
    "oracle runs",
    "progress vs oracle",
    "least",
)


def availability_table(rows: Sequence[CampaignRow]) -> list[list[str]]:
    """:func:`availability` per scenario and overall as table rows (columns
    :data:`AVAILABILITY_COLUMNS`: runs with the shadow's figures, STOP and nuisance STOP
    cycles as shares of all cycles, runs with the oracle, the mean and least progress share;
    in %, ``-`` where no run had the shadow or the oracle; the last row ``all``)."""
    groups = {**_groups(rows), "all": list(rows)}

    def pct(value: float | None) -> str:
        return "-" if value is None else f"{100.0 * value:.1f} %"

    table = []
    for name, group in groups.items():
        a = availability(group)
        table.append(
            [
                name,
                str(a.runs),
                pct(a.stop_share if a.cycles else None),
                pct(a.nuisance_share if a.cycles else None),
                str(a.oracle_runs),
                pct(a.mean_progress_share),
                pct(a.worst_progress_share),
            ]
        )
    return table
