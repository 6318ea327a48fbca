"""A picture of an availability campaign: progress against the oracle and nuisance STOP time per
run, ours beside the Nav2-style baseline (SR-AVL-1..4)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from safety.availability import Campaign

__all__ = ["NUISANCE_TARGET", "PROGRESS_TARGET", "campaign_figure"]

PROGRESS_TARGET = 0.9
"""Our progress over the oracle's that the campaign aims at (SR-AVL-2)."""
NUISANCE_TARGET = 0.02
"""The nuisance STOP time over driving time the campaign aims at, at most (SR-AVL-3)."""


def campaign_figure(campaign: Campaign) -> Figure:
    """Two panels, one bar group per run (scenario and seed): progress as a share of the
    oracle's (ours, baseline) with the 90 % target; below, our nuisance STOP time as a share of
    the run's driving time with the 2 % target."""
    runs = list(campaign.comparisons)
    labels = [f"{c.name}\n{c.seed}" for c in runs]
    x = np.arange(len(runs), dtype=np.float64)
    ours = [c.progress_share() for c in runs]
    baseline = [c.progress_share("baseline") for c in runs]
    nuisance = [c.nuisance_share for c in runs]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(max(8.0, 0.55 * len(runs) + 3), 6.5))
    top.bar(x - 0.2, ours, width=0.4, color="tab:blue", label="ours")
    top.bar(x + 0.2, baseline, width=0.4, color="tab:purple", label="Nav2-style baseline")
    top.axhline(1.0, color="tab:green", linewidth=1, label="oracle")
    top.axhline(PROGRESS_TARGET, color="tab:red", linestyle="--", linewidth=1, label="target")
    top.set_ylabel("progress / oracle's")
    top.set_title(
        f"{len(runs)} runs: ours {campaign.total_progress_share():.0%} of the oracle's progress, "
        f"baseline {campaign.total_progress_share('baseline'):.0%}"
    )
    top.set_xticks(x, labels, fontsize=6, rotation=90)
    top.legend(loc="upper right", fontsize=7)
    bottom.bar(x, nuisance, width=0.6, color="tab:orange")
    bottom.axhline(NUISANCE_TARGET, color="tab:red", linestyle="--", linewidth=1, label="target")
    bottom.set_ylabel("nuisance STOP time / driving time")
    bottom.set_title(f"ours: {campaign.nuisance_share():.1%} over the campaign")
    bottom.set_xticks(x, labels, fontsize=6, rotation=90)
    bottom.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    return fig
