"""A picture of one closed-loop run: speeds and commands over time, separations (SR-RUN-1);
with the oracle's and the baseline's runs on the same seed, their speeds too (SR-AVL-1)."""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from pipeline.sources.sim.simulation import SimResult
from safety.run import RunSummary, contact_speeds

# Colours of the other runs' speeds, by role.
_OTHERS = {"oracle": "tab:green", "baseline": "tab:purple"}


def run_figure(
    summary: RunSummary,
    others: Mapping[str, SimResult] | None = None,
    nuisance_t_s: tuple[float, ...] = (),
) -> Figure:
    """Two panels: the robot's speed and the command in force [m/s] over time, with the
    stopping commands shaded; below, the distance from the robot to every object [m].

    ``others`` adds the speed of other runs of the same scenario and seed by role (the oracle,
    the baseline: :mod:`safety.availability`); ``nuisance_t_s`` marks the decision times of
    nuisance STOPs (we stop, the oracle in that situation would not)."""
    sim = summary.sim
    if sim is None:
        raise ValueError("run_figure: the run has no simulation result")
    log = sim.ego_log
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    top.step(log["t_s"], log["command_mps"], where="post", color="tab:orange", label="command")
    top.plot(log["t_s"], log["speed_mps"], color="tab:blue", label="robot speed")
    for role, other in (others or {}).items():
        olog = other.ego_log
        colour = _OTHERS.get(role, "tab:gray")
        top.plot(olog["t_s"], olog["speed_mps"], color=colour, linewidth=1.2, label=f"{role} speed")
    if nuisance_t_s:
        top.plot(
            nuisance_t_s,
            [1.02] * len(nuisance_t_s),
            "v",
            color="tab:red",
            markersize=4,
            transform=top.get_xaxis_transform(),
            clip_on=False,  # above the axes, where no speed is drawn
            label="nuisance STOP",
        )
    stopped = log["command_mps"] == 0.0
    top.fill_between(
        log["t_s"],
        0,
        1,
        where=stopped,
        step="post",
        color="tab:red",
        alpha=0.12,
        transform=top.get_xaxis_transform(),
        label="STOP in force",
    )
    top.set_ylabel("m/s")
    top.set_title(
        f"{sim.name} seed {sim.seed}: {summary.cycles} cycles, "
        + ", ".join(f"{k} {v}" for k, v in sorted(summary.actions.items()))
    )
    top.legend(loc="upper right", fontsize=8)
    for i, obj in enumerate(sim.world.objects):
        bottom.plot(sim.separation_t_s, sim.separation_m[:, i], label=obj.name)
    for t, v in zip(
        sim.contact_time_s[np.isfinite(sim.contact_time_s)], contact_speeds(sim), strict=True
    ):
        bottom.axvline(t, color="red", linestyle="--", linewidth=1)
        bottom.annotate(f"contact at {v:.2f} m/s", (t, 0), color="red", fontsize=8)
    bottom.set_ylim(bottom=0)
    bottom.set_ylabel("separation [m]")
    bottom.set_xlabel("time [s]")
    if sim.world.objects:
        bottom.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig
