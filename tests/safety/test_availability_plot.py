"""The picture of an availability campaign (SR-AVL-1..4), read from the figure's artists, on a
campaign of constant-speed runs with a shadow whose rows are written by hand."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.colors import to_hex
from matplotlib.patches import Rectangle

from pipeline.config import SafecaseConfig
from pipeline.sources.sim.ego import ConstantSpeed
from pipeline.sources.sim.scenarios import make_simulation
from properties.figures import in_upper_right
from safety.availability import Campaign, Comparison, Shadow
from safety.availability_plot import NUISANCE_TARGET, PROGRESS_TARGET, campaign_figure
from safety.run import RunSummary
from safety.runtime import Runtime

CODE = ["safety/availability_plot.py"]


def _comparison(
    config: SafecaseConfig, runtime: Runtime, seed: int, speeds: tuple[float, float, float]
) -> Comparison:
    """Ours, the oracle and the baseline driving at constant speeds; our shadow says we stopped
    for nothing in ``seed`` of the 20 cycles."""
    ours, oracle, baseline = (
        RunSummary(
            "crossing_pedestrian",
            sim=make_simulation(config, seed=seed, duration_s=2.0, name="crossing_pedestrian").run(
                ConstantSpeed(v)
            ),
        )
        for v in speeds
    )
    rows = [
        (0.1 * i, "STOP" if i < seed else "PROCEED", 0.0, "PROCEED", 1.0, "zone:CONE")
        for i in range(20)
    ]
    return Comparison(
        "crossing_pedestrian", seed, ours, oracle, baseline, Shadow(runtime, rows), 0.1
    )


def _placed(bars: list[Rectangle]) -> list[float]:
    """Each bar's left edge and width, in turn."""
    return [v for b in bars for v in (b.get_x(), b.get_width())]


def _legend(ax: Axes) -> list[str]:
    legend = ax.get_legend()
    assert legend is not None
    return [t.get_text() for t in legend.get_texts()]


def _bars(ax: Axes) -> list[Rectangle]:
    return [p for p in ax.patches if isinstance(p, Rectangle)]


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
def test_each_run_has_its_bars_and_the_targets_their_lines(safecase_config: SafecaseConfig) -> None:
    assert (PROGRESS_TARGET, NUISANCE_TARGET) == (0.9, 0.02)
    runtime = Runtime(safecase_config)
    campaign = Campaign(
        [
            _comparison(safecase_config, runtime, 1, (0.5, 1.0, 0.25)),
            _comparison(safecase_config, runtime, 3, (0.8, 1.0, 0.9)),
        ]
    )
    runs = campaign.comparisons
    fig = campaign_figure(campaign)
    assert tuple(fig.get_size_inches()) == (8.0, 6.5)
    top, bottom = fig.axes
    ours, baseline = _bars(top)[:2], _bars(top)[2:]
    assert [b.get_height() for b in ours] == [c.progress_share() for c in runs]
    assert [b.get_height() for b in baseline] == [c.progress_share("baseline") for c in runs]
    assert _placed(ours) == pytest.approx([-0.4, 0.4, 0.6, 0.4])
    assert _placed(baseline) == pytest.approx([0.0, 0.4, 1.0, 0.4])
    assert [c.get_label() for c in top.containers] == ["ours", "Nav2-style baseline"]
    assert {to_hex(b.get_facecolor()) for b in ours} == {to_hex("tab:blue")}
    assert {to_hex(b.get_facecolor()) for b in baseline} == {to_hex("tab:purple")}
    assert _legend(top) == ["oracle", "target", "ours", "Nav2-style baseline"]
    # Both start at 1 m/s and slow to their speeds: distinct shares, so the order is checked.
    assert 0.5 < runs[0].progress_share() < runs[1].progress_share() < 1.0
    oracle, target = top.get_lines()
    assert np.asarray(oracle.get_ydata()).tolist() == [1.0, 1.0]
    assert (oracle.get_color(), oracle.get_label()) == ("tab:green", "oracle")
    assert np.asarray(target.get_ydata()).tolist() == [0.9, 0.9]
    assert (target.get_color(), target.get_linestyle(), target.get_label()) == (
        "tab:red",
        "--",
        "target",
    )
    share = campaign.total_progress_share()
    base = campaign.total_progress_share("baseline")
    assert (
        top.get_title() == f"2 runs: ours {share:.0%} of the oracle's progress, baseline {base:.0%}"
    )
    assert top.get_ylabel() == "progress / oracle's"
    assert [t.get_text() for t in top.get_xticklabels()] == [
        "crossing_pedestrian\n1",
        "crossing_pedestrian\n3",
    ]
    nuisance = _bars(bottom)
    # One and three nuisance cycles of 0.1 s over each run's 2 s.
    assert [b.get_height() for b in nuisance] == [c.nuisance_share for c in runs]
    assert [b.get_height() for b in nuisance] == pytest.approx([0.05, 0.15], rel=0.01)
    assert _placed(nuisance) == pytest.approx([-0.3, 0.6, 0.7, 0.6])
    assert {to_hex(b.get_facecolor()) for b in nuisance} == {to_hex("tab:orange")}
    assert _legend(bottom) == ["target"]
    (limit,) = bottom.get_lines()
    assert np.asarray(limit.get_ydata()).tolist() == [0.02, 0.02]
    assert (limit.get_color(), limit.get_linestyle()) == ("tab:red", "--")
    assert bottom.get_title() == f"ours: {campaign.nuisance_share():.1%} over the campaign"
    assert bottom.get_title() == "ours: 10.0% over the campaign"
    assert bottom.get_ylabel() == "nuisance STOP time / driving time"
    assert [t.get_text() for t in bottom.get_xticklabels()] == [
        "crossing_pedestrian\n1",
        "crossing_pedestrian\n3",
    ]
    assert Counter(c.nuisance_cycles for c in runs) == Counter({1: 1, 3: 1})


def test_a_long_campaign_widens_the_figure(safecase_config: SafecaseConfig) -> None:
    runtime = Runtime(safecase_config)
    one = _comparison(safecase_config, runtime, 0, (0.5, 1.0, 0.5))
    fig = campaign_figure(Campaign([one] * 12))
    assert tuple(fig.get_size_inches()) == pytest.approx((0.55 * 12 + 3, 6.5))


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
def test_the_figure_is_laid_out_for_reading(safecase_config: SafecaseConfig) -> None:
    """What a reader of docs/ sees beyond the bars: run labels turned upright in small type,
    the legends in the upper right corner in small type, the reference lines drawn thin."""
    runtime = Runtime(safecase_config)
    # three runs whose bars fill the upper right, where the best place would not put a legend
    campaign = Campaign(
        [_comparison(safecase_config, runtime, s, (1.0, 1.0, 1.0)) for s in (0, 6, 12)]
    )
    fig = campaign_figure(campaign)
    fig.canvas.draw()
    for ax in fig.axes:
        for label in ax.get_xticklabels():
            assert (label.get_fontsize(), label.get_rotation()) == (6.0, 90.0)
        legend = ax.get_legend()
        assert legend is not None
        assert {text.get_fontsize() for text in legend.get_texts()} == {7.0}
        assert in_upper_right(ax)
        assert {line.get_linewidth() for line in ax.get_lines()} == {1.0}
