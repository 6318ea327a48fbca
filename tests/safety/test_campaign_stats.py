"""The campaign's tables, timings and figure from rows made by hand (SR-RUN-8, SR-AVL-1,
SR-TIM-1), every cell read whole; the bound itself against its reference is in
``test_campaign.py``."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from scipy.stats import beta

from properties.campaign_rows import campaign_row
from safety.campaign import CampaignRow, failed_row
from safety.campaign_plan import Encounter
from safety.campaign_stats import (
    AVAILABILITY_COLUMNS,
    BOUND_COLUMNS,
    Availability,
    availability,
    availability_table,
    bound_table,
    by_scenario,
    closest_figure,
    command_mix,
    contact_bound,
    cpu_block_maxima,
    cpu_ms_summary,
    upper_limit,
)

CODE = ["safety/campaign_stats.py"]


def _row(scenario: str, seed: int, **changes: object) -> CampaignRow:
    moving = changes.pop("moving", ())
    nuisance = changes.pop("nuisance", 4)
    share = changes.pop("share", None)
    row = campaign_row(
        Encounter(scenario, seed, 5.0),
        moving,  # type: ignore[arg-type]
        nuisance=nuisance,  # type: ignore[arg-type]
        share=share,  # type: ignore[arg-type]
    )
    return replace(row, **changes)  # type: ignore[arg-type]


def _rows() -> list[CampaignRow]:
    return [
        _row("a", 0, closest_m=2.25, share=0.9),
        _row("b", 0, moving=(0.4,), closest_m=0.0),
        _row("a", 1, closest_m=1.0, share=0.5, commands={"PROCEED": 25, "STOP": 25}),
        failed_row(Encounter("c", 0, 5.0), "E: boom"),
        _row("reversing_tug_fog", 0, nuisance=None, closest_m=float("inf")),
    ]


def test_no_run_bounds_nothing_and_one_clean_run_bounds_at_one_minus_alpha() -> None:
    assert upper_limit(0, 0, 0.95) == 1.0
    assert upper_limit(0, 1, 0.95) == pytest.approx(0.95, abs=1e-12)
    assert upper_limit(0, 1, 0.99) == pytest.approx(0.99, abs=1e-12)
    assert upper_limit(1, 1, 0.95) == 1.0
    empty = contact_bound([])
    assert (empty.runs, empty.violations, empty.errors, empty.rate) == (0, 0, 0, 0.0)
    assert (empty.upper_95, empty.upper_99) == (1.0, 1.0)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_the_bound_counts_contacts_while_moving_and_raised_runs_apart() -> None:
    bounds = by_scenario(_rows())
    assert list(bounds) == ["a", "b", "c", "reversing_tug_fog"]
    a, b, c = bounds["a"], bounds["b"], bounds["c"]
    assert (a.runs, a.violations, a.errors, a.rate) == (2, 0, 0, 0.0)
    assert (b.runs, b.violations, b.errors, b.rate) == (1, 1, 0, 1.0)
    assert (c.runs, c.violations, c.errors, c.rate) == (1, 1, 1, 1.0)
    assert a.upper_95 == pytest.approx(1 - 0.05**0.5, abs=1e-12)
    assert a.upper_99 == pytest.approx(1 - 0.01**0.5, abs=1e-12)
    overall = contact_bound(_rows())
    assert (overall.runs, overall.violations, overall.errors, overall.rate) == (5, 2, 1, 0.4)
    contact_at_rest = _row("a", 2, contacts=1)
    assert contact_bound([contact_at_rest]).violations == 0


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_the_bound_table_reads_per_scenario_and_overall() -> None:
    assert BOUND_COLUMNS == (
        "scenario",
        "runs",
        "contacts while moving",
        "runs that raised",
        "closest [m]",
        "95 %",
        "99 %",
    )
    assert bound_table(_rows()) == [
        ["a", "2", "0", "0", "1.00", "0.776", "0.9"],
        ["b", "1", "1", "0", "0.00", "1", "1"],
        ["c", "1", "0", "1", "-", "1", "1"],
        ["reversing_tug_fog", "1", "0", "0", "-", "0.95", "0.99"],
        # Two violations in five runs: the Beta(3, 3) quantiles (the limit's definition).
        [
            "all",
            "5",
            "1",
            "1",
            "0.00",
            f"{beta.ppf(0.95, 3, 3):.3g}",
            f"{beta.ppf(0.99, 3, 3):.3g}",
        ],
    ]
    assert bound_table([]) == [["all", "0", "0", "0", "-", "1", "1"]]


@pytest.mark.requirement("SR-TIM-1", kind="example", code=CODE)
def test_the_slowest_cycles_leave_out_runs_without_timings() -> None:
    rows = [
        _row("a", 0, cpu_ms={"p50": 10.0, "p99": 20.0, "max": 30.0}),
        _row("a", 1, cpu_ms={"p50": 14.0, "p99": 26.0, "max": 41.0}, cycles=44),
        _row("a", 2, cpu_ms={"p50": 30.0, "p99": 25.0, "max": 50.0}),
        failed_row(Encounter("a", 3, 5.0), "E"),
        _row("a", 4, cpu_ms={"p50": 99.0, "p99": 99.0, "max": 99.0}, cycles=0),
    ]
    assert cpu_ms_summary(rows[:3] + rows[3:4]) == {
        "median_p50": 14.0,
        "max_p99": 26.0,
        "max": 50.0,
    }
    assert cpu_ms_summary([rows[3]]) == {}
    maxima, fewest = cpu_block_maxima(rows)
    assert maxima.tolist() == pytest.approx([0.030, 0.041, 0.050], abs=1e-15)
    assert maxima.dtype == np.float64
    assert fewest == 44
    nothing, none = cpu_block_maxima([rows[3]])
    assert (nothing.tolist(), none) == ([], 0)
    # A run of one cycle has timings like any other.
    single, one = cpu_block_maxima(
        [_row("a", 5, cpu_ms={"p50": 1.0, "p99": 1.0, "max": 7.0}, cycles=1)]
    )
    assert (single.tolist(), one) == (pytest.approx([0.007], abs=1e-15), 1)


def test_the_command_mix_sums_every_cycle() -> None:
    assert command_mix(_rows()) == Counter({"PROCEED": 145, "STOP": 55})
    assert command_mix([]) == Counter()


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
def test_availability_counts_only_rows_with_the_shadow() -> None:
    figures = availability(_rows())
    assert figures == Availability(
        runs=3,
        cycles=150,
        stop_cycles=45,
        nuisance_cycles=12,
        oracle_runs=2,
        mean_progress_share=pytest.approx(0.7),  # type: ignore[arg-type]
        worst_progress_share=0.5,
    )
    assert figures.stop_share == pytest.approx(0.3)
    assert figures.nuisance_share == pytest.approx(0.08)
    none = availability([failed_row(Encounter("a", 0, 5.0), "E")])
    assert none == Availability(0, 0, 0, 0, 0, None, None)
    assert (none.stop_share, none.nuisance_share) == (0.0, 0.0)
    no_cycles = Availability(1, 0, 0, 0, 0, None, None)
    # A run that never stopped may have no STOP entry at all.
    never = availability([_row("a", 0, commands={"PROCEED": 40, "SLOW": 10})])
    assert (never.cycles, never.stop_cycles) == (50, 0)
    assert (no_cycles.stop_share, no_cycles.nuisance_share) == (0.0, 0.0)


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
def test_the_availability_table_reads_per_scenario_and_overall() -> None:
    assert AVAILABILITY_COLUMNS == (
        "scenario",
        "runs",
        "STOP",
        "nuisance STOP",
        "oracle runs",
        "progress vs oracle",
        "least",
    )
    assert availability_table(_rows()) == [
        ["a", "2", "35.0 %", "8.0 %", "2", "70.0 %", "50.0 %"],
        ["b", "1", "20.0 %", "8.0 %", "0", "-", "-"],
        ["c", "0", "-", "-", "0", "-", "-"],
        ["reversing_tug_fog", "0", "-", "-", "0", "-", "-"],
        ["all", "3", "30.0 %", "8.0 %", "2", "70.0 %", "50.0 %"],
    ]


def test_the_closest_approach_figure_is_the_empirical_distribution() -> None:
    fig = closest_figure(_rows())
    (ax,) = fig.axes
    (step, contact) = ax.get_lines()
    # The failed run and the run without objects (closest inf) are left out.
    assert np.asarray(step.get_xdata()).tolist() == [0.0, 1.0, 2.25]
    assert np.asarray(step.get_ydata()).tolist() == pytest.approx([1 / 3, 2 / 3, 1.0], abs=1e-15)
    assert step.get_drawstyle() == "steps-post"
    assert np.asarray(contact.get_xdata()).tolist() == [0.0, 0.0]
    assert (contact.get_linestyle(), contact.get_color()) == ("--", "tab:red")
    assert contact.get_label() == "contact"
    assert ax.get_title() == "closest approach, 3 runs"
    assert ax.get_xlabel() == "closest approach in the run [m]"
    assert ax.get_ylabel() == "share of runs at or below"
    assert tuple(fig.get_size_inches()) == pytest.approx((6.4, 3.6))
    grid = ax.get_xgridlines() + ax.get_ygridlines()
    assert all(line.get_visible() and line.get_alpha() == 0.3 for line in grid)
    # The legend sits in the lower right corner of the axes wherever the curve rises (here at
    # its right edge, where matplotlib's "best" place would not put it).
    far = closest_figure([_row("a", i, closest_m=2.9 + 0.05 * i) for i in range(3)])
    FigureCanvasAgg(far)
    far.canvas.draw()
    (far_ax,) = far.axes
    legend = far_ax.get_legend()
    assert legend is not None
    legend_box, axes_box = legend.get_window_extent(), far_ax.get_window_extent()
    assert legend_box.x1 > axes_box.x1 - 0.1 * axes_box.width
    assert legend_box.y0 < axes_box.y0 + 0.1 * axes_box.height
    assert closest_figure(_rows(), "mine").axes[0].get_title() == "mine"
    empty = closest_figure([failed_row(Encounter("a", 0, 5.0), "E")])
    assert [line.get_label() for line in empty.axes[0].get_lines()] == ["contact"]
    assert empty.axes[0].get_title() == "closest approach, 0 runs"
