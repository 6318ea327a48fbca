"""``safecase run``: the audited runtime on any source, through one loop (:func:`safety.run.run`).

Sources: a simulator scenario in closed loop (the default), a serial scanner (``--device``),
the scenario served by a device emulator on a pty (``--emulate``), or a recorded log
(``--log``: ROS 1 / ROS 2 bags, MCAP, CARMEN, BreezySLAM).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from evidence.cli.availability import compared, report_comparison
from evidence.cli.common import ConfigOption, fail, load_config_or_exit, out, stamp
from evidence.cli.loops import recorded, run_live, run_recorded, stop_on_signals
from pipeline.config import SafecaseConfig, config_hash, overridden
from pipeline.errors import SafecaseError
from pipeline.sources import FrameSource
from pipeline.sources.logs.source import LogSource
from pipeline.sources.logs.stamps import StampRule
from pipeline.sources.serial.source import EmulatedSource, SerialSource
from pipeline.sources.sim.acoustic_scenarios import (
    ACOUSTIC_SCENARIOS,
    hearing_simulation,
)
from pipeline.sources.sim.markings_source import MarkingsSource, markings_beside
from pipeline.sources.sim.rig import sim_source
from pipeline.sources.sim.scenarios import SCENARIOS, make_simulation
from pipeline.sources.sim.simulation import BOUNDED
from safety.availability import Comparison
from safety.run import RunSummary, contact_speeds
from safety.runtime import CycleInput, CycleOutput, Runtime

DEFAULT_DEVICE_SCANS = 100
EMULATORS = ("rplidar", "scip")


def run_command(
    scenario: Annotated[
        str | None,
        typer.Option(help="Simulator scenario (default: sim.scenario); see `safecase sim list`."),
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Scenario seed (default: sim.seed).")] = None,
    duration: Annotated[
        float | None,
        typer.Option(help="Run length in s (default: sim.duration_s; any source)."),
    ] = None,
    device: Annotated[
        str | None,
        typer.Option(help="Read a serial scanner at this pyserial URL (robot standing)."),
    ] = None,
    emulate: Annotated[
        str | None,
        typer.Option(
            help="Serve the scenario's scans from a device emulator (rplidar or scip) on a pty "
            "and read them through the serial driver (robot standing)."
        ),
    ] = None,
    log: Annotated[
        Path | None,
        typer.Option(
            help="Replay a recorded log: ROS 1 bag, ROS 2 bag folder, MCAP, CARMEN or "
            "BreezySLAM file."
        ),
    ] = None,
    scan_topic: Annotated[
        str | None, typer.Option(help="--log bag: the LaserScan topic (default: the only one).")
    ] = None,
    odom_topic: Annotated[
        str | None,
        typer.Option(
            help="--log bag: the nav_msgs/Odometry or tf2_msgs/TFMessage (odom to "
            "base_footprint or base_link) topic giving the robot's pose (default: the only "
            "Odometry topic, else /tf, else none: the robot stands)."
        ),
    ] = None,
    restamp: Annotated[
        float | None,
        typer.Option(help="--log: re-stamp the scans at this rate [Hz] (unusable log stamps)."),
    ] = None,
    scans: Annotated[
        int | None,
        typer.Option(min=1, help="Stop after this many scans (device modes: default 100)."),
    ] = None,
    audit: Annotated[
        Path | None, typer.Option(help="Audit log to write (default: under audit.log_dir).")
    ] = None,
    plot: Annotated[
        bool, typer.Option(help="Simulator: write a PNG of speeds, commands and separations.")
    ] = True,
    mcap: Annotated[
        Path | None,
        typer.Option(
            help="Also record every cycle (scan, clusters, tracks, envelopes, path, costmap, "
            "command, verdicts) in this new MCAP file for Foxglove (docs/foxglove.md)."
        ),
    ] = None,
    measured_clock: Annotated[
        bool,
        typer.Option(help="Charge each cycle its measured time (not reproducible)."),
    ] = False,
    compare: Annotated[
        bool,
        typer.Option(
            "--compare/--no-compare",
            help="Simulator: also run the ground-truth oracle and the Nav2-style baseline on "
            "the same seed; print progress against the oracle and nuisance STOPs, and draw all "
            "three speeds (about three times the run's time).",
        ),
    ] = False,
    markings: Annotated[
        bool,
        typer.Option(
            "--markings/--no-markings",
            help="Simulator: also localise by the apron's painted markings (a 32-ring LiDAR's "
            "ground returns, map matching against drifting odometry) beside the run, and print "
            "the position error with and without it. A localisation aid: the safety chain does "
            "not read it (docs/findings/markings.md).",
        ),
    ] = False,
    config: ConfigOption = None,
) -> None:
    """Run the audited runtime: scan -> clusters -> tracks -> classes -> envelopes -> path
    clearance -> governor -> PROCEED / SLOW / STOP, one audit record per cycle.

    Examples: safecase run --scenario crossing_pedestrian --seed 3;
    safecase run --emulate rplidar --scans 50; safecase run --log walk.bag --odom-topic /odom;
    safecase run --scenario forklift_pass_by --mcap pass.mcap;
    safecase run --scenario pallet_jack_slow --duration 15 --compare

    Exit codes: 0 done, or stopped by Ctrl-C or SIGTERM (the audit log is closed either way);
    1 the simulated robot touched something while moving; 2 bad options, configuration, log,
    or a device that cannot be opened.
    """
    cfg = load_config_or_exit(config)
    given = (("--device", device), ("--emulate", emulate), ("--log", log))
    chosen = [option for option, value in given if value is not None]
    if len(chosen) > 1:
        fail(f"{' and '.join(chosen)}: choose one source")
    if duration is not None and not (math.isfinite(duration) and 0.0 < duration <= 86_400.0):
        fail(f"--duration {duration}: allowed: a number of seconds > 0 and <= 86400")
    if seed is not None and seed < 0:
        fail(f"--seed {seed}: allowed: an integer >= 0")
    if log is None and (scan_topic or odom_topic or restamp is not None):
        fail("--scan-topic, --odom-topic and --restamp apply to --log only")
    if compare and chosen:
        fail(f"--compare applies to simulator runs only, not to {chosen[0]}")
    if markings and (chosen or compare):
        fail("--markings applies to a simulator run without --compare")
    if compare and scans is not None:
        fail("--compare runs the whole scenario: give its length with --duration, not --scans")
    name = scenario or cfg.sim.scenario
    hearing = name in ACOUSTIC_SCENARIOS
    if name not in SCENARIOS and not hearing:
        known = ", ".join([*SCENARIOS, *ACOUSTIC_SCENARIOS])
        fail(f"--scenario {name!r}: unknown; known: {known}")
    if hearing and (chosen or compare or markings):
        fail(f"--scenario {name}: a closed-loop simulator run only (no --compare, --markings)")
    if emulate is not None and emulate not in EMULATORS:
        fail(f"--emulate {emulate!r}: allowed: {', '.join(EMULATORS)}")
    if mcap is not None and (mcap.exists() or not mcap.parent.is_dir()):
        why = "exists" if mcap.exists() else f"no folder {mcap.parent}"
        fail(f"--mcap {mcap}: {why}; allowed: a new file in an existing folder")
    log_dir = Path(cfg.audit.log_dir)
    with stop_on_signals():
        try:
            if device is not None or emulate is not None:
                source = _device_source(cfg, device, emulate, name, seed, scans)
                target = audit or log_dir / f"device-{stamp()}.jsonl"
                run_live(cfg, source, target, scans or DEFAULT_DEVICE_SCANS, duration, mcap)
                return
            if log is not None:
                rule = StampRule(restamp_hz=restamp)
                source = LogSource(log, scan_topic, odom_topic, rule, odometry=True)
                source.check()  # a log that cannot be replayed leaves no audit log behind
                target = audit or log_dir / f"log-{log.name}-{stamp()}.jsonl"
                summary = run_recorded(cfg, source, target, scans, duration, measured_clock, mcap)
                _report(cfg, summary, source)
                recorded(mcap)
                return
            if hearing:
                heard = hearing_simulation(cfg, name, seed or 0, duration or cfg.sim.duration_s)
                target = audit or log_dir / f"{name}-seed{seed or 0}-{stamp()}.jsonl"
                summary = run_recorded(cfg, heard, target, scans, None, measured_clock, mcap)
                _report(cfg, summary, None)
                out.print(heard.summary(), highlight=False)
                _finish(summary, target, None, plot, mcap)
                return
            sim = make_simulation(cfg, name, seed, duration)
            target = audit or log_dir / f"{name}-seed{sim.seed}-{stamp()}.jsonl"
            comparison = None
            aided: MarkingsSource | None = None
            if compare:

                def ours(
                    rt: Runtime, observe: Callable[[CycleInput, CycleOutput], None]
                ) -> RunSummary:
                    source = sim_source(cfg, sim)
                    return run_recorded(
                        cfg, source, target, None, None, measured_clock, mcap, rt, observe
                    )

                comparison = compared(cfg, sim, duration, ours)
                summary = comparison.ours
            elif markings:
                aided = markings_beside(cfg, sim)
                summary = run_recorded(cfg, aided, target, scans, None, measured_clock, mcap)
            else:
                summary = run_recorded(
                    cfg, sim_source(cfg, sim), target, scans, None, measured_clock, mcap
                )
        except (SafecaseError, ValueError, OSError) as exc:
            fail(str(exc))
        _report(cfg, summary, None)
        if aided is not None:
            out.print(aided.summary(), highlight=False)
        _finish(summary, target, comparison, plot, mcap)


def _finish(
    summary: RunSummary,
    target: Path,
    comparison: Comparison | None,
    plot: bool,
    mcap: Path | None,
) -> None:
    """The end of a simulator run: the comparison, the recording, the plot, and exit 1 on a
    contact while moving."""
    if comparison is not None:
        report_comparison(comparison)
    recorded(mcap)
    if plot and summary.sim is not None:
        from safety.run_plot import run_figure

        png = target.with_suffix(".png")
        if comparison is not None:
            figure = run_figure(summary, comparison.others(), comparison.nuisance_times_s())
        else:
            figure = run_figure(summary)
        figure.savefig(png, dpi=110)
        out.print(f"plot: {png}", highlight=False)
    if summary.moving_contacts:
        out.print("[bold red]CONTACT while moving[/]: the governor did not keep the robot safe")
        raise typer.Exit(1)


def _device_source(
    cfg: SafecaseConfig,
    url: str | None,
    emulate: str | None,
    name: str,
    seed: int | None,
    max_scans: int | None,
) -> FrameSource:
    """The serial scanner at ``url``, or the scenario served by an emulated device."""
    period = cfg.track.frame_period_s
    if emulate is None:
        assert url is not None
        return SerialSource(cfg.driver.model_copy(update={"port_url": url}), period)
    # The robot stands (the runtime has no odometry from a serial scanner); the world moves.
    # The scanner is the emulated device's own (an RPLIDAR encodes at most 16.4 m), and the
    # scenario runs long enough to serve every scan asked for.
    lidar = "rplidar_a2" if emulate == "rplidar" else "hokuyo_ust10lx"
    bench = overridden(cfg, {"sim": {"ego_speed_mps": 0.0, "lidar_device": lidar}})
    wanted = max_scans or DEFAULT_DEVICE_SCANS
    # Bounded retention: the device only needs each scan once (a long run keeps no frames).
    sim = make_simulation(bench, name, seed, retention=BOUNDED)
    period_s = sim.lidar.spec.scan_period_s
    if sim.n_scans < wanted + 10:
        sim = make_simulation(bench, name, seed, (wanted + 10) * period_s, retention=BOUNDED)
    driver = cfg.driver.model_copy(update={"protocol": emulate, "port_url": "emulated"})
    return EmulatedSource(driver, period, sim.scans(), 1.0 / period_s)


def _report(cfg: SafecaseConfig, summary: RunSummary, log: LogSource | None) -> None:
    sim = summary.sim
    table = Table(title=f"safecase run: {summary.name}", show_header=False)
    table.add_row("config hash", config_hash(cfg)[:16])
    table.add_row("cycles", str(summary.cycles))
    table.add_row("commands", ", ".join(f"{k} {v}" for k, v in sorted(summary.actions.items())))
    table.add_row(
        "reasons", ", ".join(f"{k} {v}" for k, v in summary.reasons.most_common(6)) or "-"
    )
    if summary.second_scan:
        states = ", ".join(f"{k} {v}" for k, v in summary.second_scan.most_common())
        table.add_row("second scanner", states)
    if log is not None:
        skipped = ", ".join(f"{k} {v}" for k, v in log.skipped.items() if v) or "none"
        table.add_row("scans skipped", skipped)
        table.add_row("odometry", log.odometry_from or "none (the robot stands)")
        rate = log.stamps.restamp_hz
        table.add_row("stamps", "as recorded" if rate is None else f"re-stamped at {rate:g} Hz")
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
    out.print(table)
    out.print(f"verify with: safecase audit verify {summary.audit_path}", highlight=False)
