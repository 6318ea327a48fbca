"""``safecase campaign``: many seeded closed-loop encounters on Dask, and the contact-rate bound.

The work is :func:`safety.campaign.run_campaign` on a cluster from
:func:`pipeline.distributed.open_client`; this module reads the options, shows the progress,
keeps the rows in a JSON Lines file as they arrive (so ``--out`` names a campaign that a second
call resumes) and reports the bound and the availability figures of
:mod:`safety.campaign_stats` (SR-RUN-8).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from evidence.cli.common import ConfigOption, err, fail, load_config_or_exit, out
from evidence.wcet import MIN_FIT_POINTS, fit_gev_maxima
from pipeline.config import SafecaseConfig, overridden
from pipeline.errors import EvidenceError
from pipeline.sources.sim.weather import WEATHER_PRESETS
from safety.campaign import (
    CampaignError,
    CampaignLog,
    CampaignRow,
    Encounter,
    encounter_plan,
    pending,
    run_campaign,
)
from safety.campaign_stats import (
    AVAILABILITY_COLUMNS,
    BOUND_COLUMNS,
    availability_table,
    bound_table,
    closest_figure,
    cpu_block_maxima,
    cpu_ms_summary,
    nuisance_causes,
)

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["campaign_command"]


def campaign_command(
    encounters: Annotated[
        int, typer.Option(min=0, help="Random encounters (random_encounter seeds).")
    ] = 300,
    named_seeds: Annotated[int, typer.Option(min=0, help="Seeds per named scenario.")] = 0,
    airside_seeds: Annotated[
        int,
        typer.Option(
            min=0, help="Seeds per airside scenario (fog, night: set apart) in each --weather."
        ),
    ] = 0,
    weather: Annotated[
        str,
        typer.Option(
            help="Weathers of the airside scenarios, comma-separated: 'own' (the scenario's "
            "own) or presets (" + ", ".join(WEATHER_PRESETS) + ")."
        ),
    ] = "own",
    sensors: Annotated[
        str | None,
        typer.Option(
            help="Simulated sensors beside the LiDAR, comma-separated: thermal, radar, or none "
            "(sets runtime.sim_sensors, so the file's configuration hash records it; default: "
            "as configured)."
        ),
    ] = None,
    duration: Annotated[float, typer.Option(min=0.5, help="Run length in seconds.")] = 15.0,
    first_seed: Annotated[int, typer.Option(min=0, help="First seed of every scenario.")] = 0,
    workers: Annotated[
        int, typer.Option(min=1, help="LocalCluster worker processes (without --scheduler).")
    ] = 2,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Address of a running Dask scheduler (tcp://host:8786) to use."),
    ] = None,
    output: Annotated[
        Path, typer.Option("--out", "-o", help="Campaign file (JSON Lines); resumed if present.")
    ] = Path("out/campaign/campaign.jsonl"),
    plot: Annotated[
        Path | None, typer.Option(help="Write the closest-approach distribution here (PNG).")
    ] = None,
    oracle: Annotated[
        bool,
        typer.Option(
            "--oracle",
            help="Also run the oracle's closed loop of each seed (progress vs oracle; about "
            "1.6 times the CPU of a run without it).",
        ),
    ] = False,
    shadow: Annotated[
        bool,
        typer.Option(
            "--shadow/--no-shadow",
            help="Run the shadow oracle beside each run to count nuisance STOPs (about 40 % of "
            "a run's CPU); --no-shadow for a campaign about the contact rate alone.",
        ),
    ] = True,
    config: ConfigOption = None,
) -> None:
    """Run seeded closed-loop encounters on Dask and bound the rate of contacts while moving.

    Rows go to --out as each run ends; calling again with the same --out resumes (only the
    missing runs are run). The bound is Clopper-Pearson, one-sided 95 % and 99 %. Every run
    counts its nuisance STOPs against a shadow oracle (unless --no-shadow); with --oracle it is
    also compared with the oracle's own closed loop (progress share).

    The airside scenarios (--airside-seeds) run in their own weather or in each --weather
    listed; their rows are reported per scenario@weather. --sensors gives the robot the
    simulated thermal camera and radar (SR-FUS-9).

    Example: safecase campaign --encounters 300 --named-seeds 3 --out out/campaign/c300.jsonl
    Example: safecase campaign --encounters 10000 --duration 12 --no-shadow --out c10k.jsonl
    Example: safecase campaign --encounters 0 --airside-seeds 5 --weather own,clear,night,rain
    --sensors thermal,radar --oracle --duration 12 --out out/campaign/airside.jsonl

    Exit codes: 0 done, no contact while moving and no run failed; 1 a contact while moving or
    a run that raised (each listed); 2 bad options or configuration, a file of another
    configuration, an unreachable scheduler; 130 interrupted (Ctrl-C), the finished runs kept.
    """
    from pipeline.distributed import open_client  # Dask loads only for this command

    cfg = load_config_or_exit(config)
    weathers = _weathers(weather)
    if sensors is not None:
        cfg = overridden(cfg, {"runtime": {"sim_sensors": _sensors(sensors)}})
    plan = encounter_plan(
        encounters,
        named_seeds=named_seeds,
        duration_s=duration,
        first_seed=first_seed,
        airside_seeds=airside_seeds,
        airside_weather=weathers,
    )
    if not plan:
        fail("--encounters 0, --named-seeds 0 and --airside-seeds 0: nothing to run")
    if oracle and not shadow:
        fail("--oracle compares with the shadow oracle's cycles: it cannot run with --no-shadow")
    try:
        log = CampaignLog.open(output, cfg)
    except (CampaignError, OSError) as exc:
        fail(str(exc))
    with log:
        todo = pending(plan, log)
        if len(todo) < len(plan):
            out.print(f"resuming {output}: {len(plan) - len(todo)} of {len(plan)} runs done")
        try:
            if todo:  # a finished campaign is only reported: no cluster
                with open_client(scheduler, workers) as client:
                    out.print(f"Dask dashboard: {client.dashboard_link}", highlight=False)
                    _run(client, cfg, plan, log, len(todo), oracle=oracle, shadow=shadow)
        except OSError as exc:
            fail(str(exc))
        except KeyboardInterrupt:
            # Every finished run is already in the file; the same command resumes from it.
            done = len(plan) - len(pending(plan, log))
            err.print(
                f"interrupted: {done} of {len(plan)} runs are in {output}; "
                "the same command resumes with the rest",
                highlight=False,
                markup=False,
            )
            raise typer.Exit(130) from None
    keys = {e.key for e in plan}
    _report([r for r in log.rows if r.encounter.key in keys], output, plot)


def _names(option: str, value: str, allowed: Sequence[str]) -> list[str]:
    """The comma-separated names of ``value``, each one of ``allowed`` (exit 2 naming the
    first that is not, and what is allowed)."""
    names = [n.strip() for n in value.split(",")]
    for name in names:
        if name not in allowed:
            fail(f"{option}: {name!r} is not one of {', '.join(allowed)}")
    return names


def _weathers(value: str) -> list[str | None]:
    """``--weather``: the airside scenarios' weathers, ``own`` as None (SR-RUN-8)."""
    names = _names("--weather", value, ["own", *WEATHER_PRESETS])
    return [None if n == "own" else n for n in dict.fromkeys(names)]


def _sensors(value: str) -> list[str]:
    """``--sensors``: the value of ``runtime.sim_sensors`` (``none``: none, SR-FUS-9), in one
    order whatever the order given, so that the same sensors give the same configuration
    hash."""
    sensors = ("thermal", "radar")
    names = _names("--sensors", value, [*sensors, "none"])
    if "none" in names and len(names) > 1:
        fail(f"--sensors: 'none' stands alone, got {value!r}")
    return [n for n in sensors if n in names]


def _run(
    client: Client,
    cfg: SafecaseConfig,
    plan: list[Encounter],
    log: CampaignLog,
    todo: int,
    *,
    oracle: bool,
    shadow: bool,
) -> None:
    with Progress(
        TextColumn("[bold]encounters[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task("runs", total=todo)
        run_campaign(
            client,
            cfg,
            plan,
            log,
            on_row=lambda _row: bar.advance(task),
            oracle=oracle,
            shadow=shadow,
        )


def _report(rows: list[CampaignRow], output: Path, plot: Path | None) -> None:
    title = f"{len(rows)} runs ({output}); one-sided upper bounds of the rate"
    out.print(_table(title, BOUND_COLUMNS, bound_table(rows)))
    _report_availability(rows)
    cpu = cpu_ms_summary(rows)
    if cpu:
        out.print(
            f"cycle CPU: median p50 {cpu['median_p50']:.1f} ms, worst p99 {cpu['max_p99']:.1f} "
            f"ms, slowest cycle {cpu['max']:.1f} ms",
            highlight=False,
        )
    _report_pwcet(rows)
    if plot is not None:
        closest_figure(rows).savefig(plot, dpi=110)
        out.print(f"closest-approach plot: {plot}", highlight=False)
    bad = [r for r in rows if r.error is not None or r.moving_contacts_mps]
    for row in bad:
        what = row.error or f"contact while moving at {max(row.moving_contacts_mps):.3f} m/s"
        out.print(f"{row.encounter.key}: {what}", highlight=False, markup=False)
    if bad:
        raise typer.Exit(1)


def _table(title: str, columns: Sequence[str], lines: list[list[str]]) -> Table:
    """A table of ``lines`` under ``columns``, the first the scenario; no cell is cut short
    (on a narrow console the headers wrap instead)."""
    table = Table(title=title)
    for i, column in enumerate(columns):
        width = max((len(line[i]) for line in lines), default=0)
        table.add_column(escape(column), justify="right" if i else "left", min_width=width)
    for line in lines:
        table.add_row(*(escape(cell) for cell in line))
    return table


def _report_pwcet(rows: list[CampaignRow]) -> None:
    """The cycle's pWCET at 1e-9 per cycle from the runs' slowest cycles (SR-TIM-1)."""
    maxima, cycles = cpu_block_maxima(rows)
    if maxima.size < MIN_FIT_POINTS:
        out.print(
            f"cycle CPU pWCET: needs the slowest cycle of at least {MIN_FIT_POINTS} timed runs "
            f"(have {maxima.size})",
            highlight=False,
        )
        return
    try:
        fit = fit_gev_maxima(maxima, block_size=cycles)
    except EvidenceError as exc:
        out.print(f"cycle CPU pWCET: no fit ({exc})", highlight=False, markup=False)
        return
    verdict = "fits" if fit.fit_ok else "REJECTED by the KS test at 5 %"
    slowest = float(maxima.max())
    out.print(
        f"cycle CPU pWCET at 1e-9 per cycle: bound {max(fit.pwcet_s, slowest) * 1e3:.1f} ms, the "
        f"larger of the GEV's {fit.pwcet_s * 1e3:.1f} ms and the slowest cycle "
        f"{slowest * 1e3:.1f} ms (GEV of the slowest cycle of {fit.n_fit} runs, blocks of "
        f"{cycles} cycles or more; shape {fit.shape_xi:+.3f}, KS p = {fit.ks_pvalue:.2g}: "
        f"{verdict})",
        highlight=False,
    )


def _report_availability(rows: list[CampaignRow]) -> None:
    title = (
        "availability: STOP and nuisance STOP (the shadow oracle would go on) as shares of "
        "cycles; our progress over the oracle's, mean and least over runs with --oracle"
    )
    out.print(_table(title, AVAILABILITY_COLUMNS, availability_table(rows)))
    causes = nuisance_causes(rows)
    if causes:
        listed = ", ".join(f"{cause} {n}" for cause, n in causes.most_common())
        out.print(f"nuisance STOP cycles set by: {listed}", highlight=False, markup=False)
