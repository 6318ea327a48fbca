"""``safecase run --compare``: the oracle and the Nav2-style baseline beside our run (SR-AVL-1).

Our run is the audited run ``safecase run`` always makes, with the shadow oracle deciding on
its frames; then the oracle (the runtime fed the simulator's ground truth) and the baseline
(:class:`safety.baseline.Nav2Baseline`) each run the same scenario and seed in their own
simulation (:mod:`safety.availability`). The summary says how far we got against the oracle,
the nuisance STOPs (we stop, the oracle in that situation would not) and, per role, progress,
STOP cycles, contacts and the closest approach.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from evidence.cli.common import err, out
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import Simulation
from safety.availability import Comparison, Shadow, run_baseline, run_oracle
from safety.run import RunSummary, site_map
from safety.runtime import CycleInput, CycleOutput, Runtime

__all__ = ["ROLES", "compared", "report_comparison", "scan_progress"]

ROLES = ("ours", "oracle", "baseline")

# Runs our audited run given (runtime, observe callback) and returns its summary.
OursRunner = Callable[[Runtime, Callable[[CycleInput, CycleOutput], None]], RunSummary]


def compared(
    cfg: SafecaseConfig, sim: Simulation, duration_s: float | None, run_ours: OursRunner
) -> Comparison:
    """Our run (through ``run_ours``, audited by the caller) with its shadow oracle, then the
    oracle's and the baseline's runs of the same scenario and seed."""
    model = Classifier.from_config(cfg.classify)
    shadow = Shadow.for_simulation(cfg, sim, model)
    ours = Runtime(cfg, classifier=model, static_map=site_map(cfg, sim))
    summary = run_ours(ours, shadow.observer(ours))
    others: dict[str, RunSummary] = {}
    for role in ("oracle", "baseline"):
        other = make_simulation(cfg, sim.name, sim.seed, duration_s)
        with _bar(f"{sim.name} {role}", other.n_scans) as tick:
            if role == "oracle":
                others[role] = run_oracle(cfg, other, model, progress=tick)
            else:
                others[role] = run_baseline(cfg, other, progress=tick)
    period = sim.lidar.spec.scan_period_s
    return Comparison(
        sim.name, sim.seed, summary, others["oracle"], others["baseline"], shadow, period
    )


def scan_progress(label: str) -> Progress:
    """A transient progress bar on stderr counting the scans of a run named ``label``."""
    return Progress(
        TextColumn(f"[bold]{label}[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("scans"),
        TimeElapsedColumn(),
        console=err,
        transient=True,
    )


@contextlib.contextmanager
def _bar(label: str, total: int) -> Iterator[Callable[[int, int], None]]:
    """A transient progress bar on stderr; yields the ``progress(done, total)`` callback."""
    with scan_progress(label) as bar:
        task = bar.add_task(label, total=total)

        def tick(done: int, of: int) -> None:
            bar.update(task, completed=done, total=of)

        yield tick


def report_comparison(comparison: Comparison) -> None:
    """Progress against the oracle, nuisance STOPs, and the three runs side by side."""
    c = comparison
    metrics = c.metrics()
    ours, best = metrics["ours"], metrics["oracle"]
    common = min(ours.duration_s, best.duration_s)
    episodes = c.nuisance_episodes_s()
    causes = ", ".join(f"{k} {v}" for k, v in c.nuisance_causes().most_common(4)) or "-"
    table = Table(title=f"against the oracle: {c.name} seed {c.seed}", show_header=False)
    table.add_row(
        "progress vs oracle",
        f"{c.progress_share():.0%} over the {common:.1f} s both ran "
        f"(baseline {c.progress_share('baseline'):.0%})",
    )
    goal = c.time_to_goal_share()
    table.add_row(
        "time to goal vs oracle", "not reached by both" if goal is None else f"{goal:.0%}"
    )
    table.add_row(
        "nuisance STOPs",
        f"{c.nuisance_cycles} cycles, {c.nuisance_share:.1%} of {ours.duration_s:.1f} s"
        + (f", {len(episodes)} episodes, longest {max(episodes):.1f} s" if episodes else "")
        + f" (set by: {causes})",
    )
    lost = c.speed_given_up_m()
    table.add_row(
        "speed given up vs oracle",
        ", ".join(f"{k} {v:.2f} m" for k, v in list(lost.items())[:4]) or "none",
    )
    out.print(table)
    side = Table(title="ours / oracle / baseline (same seed)")
    for column in ("", "progress [m]", "in [s]", "STOP cycles", "contacts [m/s]", "closest [m]"):
        side.add_column(column)
    for role in ROLES:
        m = metrics[role]
        side.add_row(
            role,
            f"{m.progress_m:.1f}",
            f"{m.duration_s:.1f}",
            str(m.actions.get("STOP", 0)),
            " ".join(f"{v:.2f}" for v in m.contact_speeds_mps) or "none",
            f"{m.closest_m:.2f}",
        )
    out.print(side)
