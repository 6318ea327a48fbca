"""``safecase run``: the audited runtime on the simulator (closed loop) or a serial scanner."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from pipeline.config import SafecaseConfig, config_hash, overridden
from pipeline.errors import SafecaseError
from pipeline.sim.scenarios import SCENARIOS
from pipeline.types import Scan
from safety.run import RunSummary, contact_speeds, run_device, run_scenario

_out = Console(soft_wrap=True)
_err = Console(stderr=True, soft_wrap=True)

ConfigOption = Annotated[
    Path | None,
    typer.Option("--config", "-c", help="TOML file overriding the built-in configuration."),
]


def _stamp() -> str:
    return datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")


def run_command(
    scenario: Annotated[
        str | None,
        typer.Option(help="Simulator scenario (default: sim.scenario); see `safecase sim list`."),
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Scenario seed (default: sim.seed).")] = None,
    duration: Annotated[
        float | None, typer.Option(help="Run length in s (default: sim.duration_s).")
    ] = None,
    device: Annotated[
        str | None,
        typer.Option(help="Read a serial scanner at this pyserial URL instead (robot standing)."),
    ] = None,
    emulate: Annotated[
        str | None,
        typer.Option(
            help="Serve the scenario's scans from a device emulator (rplidar or scip) on a pty "
            "and read them through the serial driver (robot standing)."
        ),
    ] = None,
    scans: Annotated[
        int | None,
        typer.Option(min=1, help="Device modes: stop after this many scans (default 100)."),
    ] = None,
    audit: Annotated[
        Path | None, typer.Option(help="Audit log to write (default: under audit.log_dir).")
    ] = None,
    plot: Annotated[
        bool, typer.Option(help="Simulator: write a PNG of speeds, commands and separations.")
    ] = True,
    measured_clock: Annotated[
        bool,
        typer.Option(help="Simulator: charge each cycle its measured time (not reproducible)."),
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Run the audited runtime: scan -> clusters -> tracks -> classes -> envelopes -> path
    clearance -> governor -> PROCEED / SLOW / STOP, one audit record per cycle.

    By default the built-in scenario runs in closed loop (the governor drives the simulated
    robot); exit code 1 if the robot touched anything while moving.
    """
    from safety.cli import load_config_or_exit

    cfg = load_config_or_exit(config)
    if duration is not None and duration <= 0:
        _err.print(f"[bold red]error:[/] --duration {duration}: must be > 0 s")
        raise typer.Exit(2)
    name = scenario or cfg.sim.scenario
    if name not in SCENARIOS:
        _err.print(
            f"[bold red]error:[/] --scenario {name!r}: unknown; known: {', '.join(SCENARIOS)}"
        )
        raise typer.Exit(2)
    if emulate is not None and emulate not in ("rplidar", "scip"):
        _err.print(f"[bold red]error:[/] --emulate {emulate!r}: allowed: rplidar, scip")
        raise typer.Exit(2)
    log_dir = Path(cfg.audit.log_dir)
    try:
        if device is not None or emulate is not None:
            target = audit or log_dir / f"device-{_stamp()}.jsonl"
            _device(cfg, device, emulate, name, seed, scans, target)
            return
        target = (
            audit
            or log_dir / f"{name}-seed{seed if seed is not None else cfg.sim.seed}-{_stamp()}.jsonl"
        )
        summary = _simulate(cfg, name, seed, duration, target, measured_clock)
    except SafecaseError as exc:
        _err.print(f"[bold red]error:[/] {exc}")
        raise typer.Exit(2) from None
    _report(cfg, summary)
    if plot and summary.sim is not None:
        from safety.run_plot import run_figure

        png = target.with_suffix(".png")
        run_figure(summary).savefig(png, dpi=110)
        _out.print(f"plot: {png}", highlight=False)
    if summary.moving_contacts:
        _out.print("[bold red]CONTACT while moving[/]: the governor did not keep the robot safe")
        raise typer.Exit(1)


def _simulate(
    cfg: SafecaseConfig,
    name: str,
    seed: int | None,
    duration: float | None,
    target: Path,
    measured_clock: bool,
) -> RunSummary:
    with Progress(
        TextColumn(f"[bold]{name}[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("scans"),
        TimeElapsedColumn(),
        console=_err,
        transient=True,
    ) as bar:
        task = bar.add_task("run", total=None)

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        return run_scenario(
            cfg,
            name,
            seed,
            duration,
            audit_path=target,
            progress=progress,
            measured_clock=measured_clock,
        )


def _report(cfg: SafecaseConfig, summary: RunSummary) -> None:
    sim = summary.sim
    table = Table(title=f"safecase run: {summary.name}", show_header=False)
    table.add_row("config hash", config_hash(cfg)[:16])
    table.add_row("cycles", str(summary.cycles))
    table.add_row("commands", ", ".join(f"{k} {v}" for k, v in sorted(summary.actions.items())))
    table.add_row(
        "reasons", ", ".join(f"{k} {v}" for k, v in summary.reasons.most_common(6)) or "-"
    )
    if sim is not None:
        speeds = contact_speeds(sim)
        contact = (
            "none"
            if not speeds.size
            else ", ".join(f"{v:.2f} m/s" for v in speeds) + " (robot speed at contact)"
        )
        table.add_row("contacts", contact)
        table.add_row(
            "closest approach", f"{float(np.min(sim.min_separation_m, initial=np.inf)):.2f} m"
        )
        table.add_row(
            "progress",
            f"{sim.ego_log['arc_m'][-1]:.1f} of {sim.ego_spec.route.length_m:.1f} m in "
            f"{sim.ego_log['t_s'][-1]:.1f} s",
        )
    cycle = np.asarray(summary.cpu_s) * 1e3
    if cycle.size:
        table.add_row(
            "cycle CPU time",
            f"p50 {np.median(cycle):.1f} ms, p99 {np.percentile(cycle, 99):.1f} ms",
        )
    table.add_row("audit log", str(summary.audit_path))
    _out.print(table)
    _out.print(f"verify with: safecase audit verify {summary.audit_path}", highlight=False)


def _device(
    cfg: SafecaseConfig,
    url: str | None,
    emulate: str | None,
    name: str,
    seed: int | None,
    max_scans: int | None,
    target: Path,
) -> None:
    with _scanner(cfg, url, emulate, name, seed) as (port, run_cfg):
        counts: dict[str, int] = {}
        n = 0
        for out in run_device(run_cfg, port, audit_path=target, max_scans=max_scans or 100):
            c = out.command
            counts[c.action.value] = counts.get(c.action.value, 0) + 1
            n += 1
            why = f" ({c.reasons[0]})" if c.reasons else ""
            _out.print(
                f"{n:5d} {c.action.value:7s} {c.speed_mps:5.2f} m/s{why}",
                highlight=False,
                markup=False,
            )
    _out.print(
        f"{n} cycles: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())),
        highlight=False,
    )
    _out.print(f"audit log: {target} (verify: safecase audit verify {target})", highlight=False)


@contextlib.contextmanager
def _scanner(
    cfg: SafecaseConfig, url: str | None, emulate: str | None, name: str, seed: int | None
) -> Iterator[tuple[str, SafecaseConfig]]:
    """The port to read, and the configuration to read it with (the emulated device's)."""
    if emulate is None:
        assert url is not None
        yield url, cfg
        return
    from pipeline.drivers.devices import RplidarDevice, ScipDevice
    from pipeline.drivers.emulator import Emulator
    from pipeline.sim.scenarios import make_simulation

    protocol: Literal["rplidar", "scip"] = "rplidar" if emulate == "rplidar" else "scip"
    # The robot stands (the runtime has no odometry from a serial scanner); the world moves.
    # The scanner is the emulated device's own (an RPLIDAR encodes at most 16.4 m).
    lidar = "rplidar_a2" if protocol == "rplidar" else "hokuyo_ust10lx"
    bench = overridden(
        cfg,
        {
            "sim": {"ego_speed_mps": 0.0, "lidar_device": lidar},
            "driver": {"protocol": protocol},
        },
    )
    sim = make_simulation(bench, name, seed)
    source: Iterator[Scan] = sim.scans()
    device = RplidarDevice() if protocol == "rplidar" else ScipDevice()
    rate = 1.0 / sim.lidar.spec.scan_period_s
    with Emulator(device, source, realtime=True, rate_hz=rate) as emu:
        yield emu.path, bench
