"""``safecase nav2``: prove or refute a Nav2 collision monitor's zones, export proved ones.

Requirements: SR-NAV-1 to SR-NAV-4.

``check`` exits 0 when every claim is PROVED, 1 when any is REFUTED, 2 on bad input (one line
naming the key, the value and what is allowed) and 3 when any is UNKNOWN (never a pass).
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from evidence.cli.common import ConfigOption, fail, load_config_or_exit, out
from safety.model.stopping import ClosingClass
from safety.nav2 import (
    LATENCIES,
    Nav2ParamsError,
    Overrides,
    Report,
    Verdict,
    check,
    load_params,
)
from safety.nav2.export import export_yaml

app = typer.Typer(
    help="Nav2 collision monitor zones: prove them against the stopping model, export proved ones.",
    no_args_is_help=True,
)

CLASSES = tuple(c.value for c in ClosingClass)
_STYLE = {Verdict.PROVED: "green", Verdict.REFUTED: "bold red", Verdict.UNKNOWN: "yellow"}


def _limit(option: str, value: float | None) -> Fraction | None:
    if value is None:
        return None
    if not (math.isfinite(value) and 0.0 <= value <= 100.0):
        fail(f"--{option} {value}: allowed: a number in [0, 100]")
    return Fraction(repr(value))


def _g(value: Fraction | float | None) -> str:
    return "-" if value is None else f"{float(value):.4g}"


def _print(report: Report) -> None:
    p = report.params
    zones = len(p.zones)
    out.print(
        f"nav2 check {escape(p.name)}: {zones} zone{'s' * (zones != 1)}, base frame "
        f"{escape(p.base_frame_id)}",
        highlight=False,
    )
    for line in report.assumptions():
        out.print(f"  {escape(line)}", highlight=False)
    table = Table()
    for column in ("zone", "action", "travel", "speeds m/s", "needs m", "zone gives", "verdict"):
        table.add_column(column, no_wrap=column in ("zone", "verdict", "speeds m/s"))
    for f in report.findings:
        verdict = "no claim" if f.verdict is None else f"[{_STYLE[f.verdict]}]{f.verdict.value}[/]"
        speeds = "-" if f.low_mps is None else f"{_g(f.low_mps)} .. {_g(f.high_mps)}"
        needed = (
            "-"
            if f.needed_m is None and f.low_mps is None
            else ("unbounded" if f.needed_m is None else _g(f.needed_m))
        )
        table.add_row(escape(f.label), f.action, f.travel, speeds, needed, escape(f.gives), verdict)
    out.print(table)
    for f in report.findings:
        text = "; ".join(t for t in (f"in use for {f.why}" if f.why else "", f.detail) if t)
        travel = "" if f.travel == "-" else f" ({f.travel})"
        if text:
            out.print(f"{escape(f.label)}{travel}: {escape(text)}", highlight=False)
    final = report.verdict
    out.print(
        f"verdict: [{_STYLE[final]}]{final.value}[/] (exit {report.exit_code})", highlight=False
    )


@app.command("check")
def check_command(
    params: Annotated[Path, typer.Argument(help="Nav2 parameter YAML with a collision_monitor.")],
    config: ConfigOption = None,
    latency: Annotated[
        str,
        typer.Option(
            help="Reaction time: nav2 = the largest source_timeout + the monitor's period; "
            "project = stopping.perception_latency_s + stopping.control_cycle_s."
        ),
    ] = "nav2",
    obstacle: Annotated[
        str, typer.Option(help=f"Obstacle class: {' | '.join(CLASSES)} (its closing speed).")
    ] = "static",
    max_speed: Annotated[
        float | None,
        typer.Option(
            help="Forward speed limit [m/s] (default: the file, else stopping.robot_max_speed_mps)."
        ),
    ] = None,
    max_reverse_speed: Annotated[
        float | None, typer.Option(help="Reverse speed limit [m/s] (default: the file, else 0).")
    ] = None,
    max_lateral_speed: Annotated[
        float | None, typer.Option(help="Sideways speed limit [m/s] (default: the file, else 0).")
    ] = None,
    max_yaw_rate: Annotated[
        float | None,
        typer.Option(
            help="Yaw-rate limit [rad/s] (default: the file, else geometry.max_yaw_rate_radps)."
        ),
    ] = None,
    control_period: Annotated[
        float | None,
        typer.Option(
            help="Period of the monitor [s] for --latency nav2 (default: "
            "the file's controller or smoother frequency, else "
            "stopping.control_cycle_s)."
        ),
    ] = None,
) -> None:
    """Prove or refute, with z3 and the stopping model, that each stop zone of a Nav2
    collision monitor covers the robot's stopping distance at every speed it is used for; give
    the counterexample and the largest safe speed of each refuted zone (docs/nav2.md).

    Example: safecase nav2 check examples/nav2/tutorial.yaml --config examples/nav2/small-robot.toml

    Exit codes: 0 every zone PROVED; 1 some zone REFUTED; 2 bad parameter file, option or
    configuration; 3 some zone UNKNOWN (a shape set at run time, or z3 undecided: never a pass).
    """
    if latency not in LATENCIES:
        fail(f"--latency {latency!r}: allowed: {' | '.join(LATENCIES)}")
    if obstacle not in CLASSES:
        fail(f"--obstacle {obstacle!r}: allowed: {' | '.join(CLASSES)}")
    overrides = Overrides(
        _limit("max-speed", max_speed),
        _limit("max-reverse-speed", max_reverse_speed),
        _limit("max-lateral-speed", max_lateral_speed),
        _limit("max-yaw-rate", max_yaw_rate),
        _limit("control-period", control_period),
    )
    if overrides.control_period_s == 0:
        fail("--control-period 0.0: allowed: a number in (0, 100]")
    cfg = load_config_or_exit(config)
    try:
        nav2 = load_params(params)
    except Nav2ParamsError as exc:
        fail(str(exc))
    report = check(nav2, cfg, latency=latency, closing=ClosingClass(obstacle), overrides=overrides)
    _print(report)
    raise typer.Exit(report.exit_code)


@app.command("export")
def export_command(
    config: ConfigOption = None,
    out_path: Annotated[
        Path | None, typer.Option("--out", "-o", help="YAML file to write (default: stdout).")
    ] = None,
    obstacle: Annotated[
        str, typer.Option(help=f"Obstacle class: {' | '.join(CLASSES)} (its closing speed).")
    ] = "static",
) -> None:
    """Write the governor's proved, speed-dependent stop zones as a Nav2 collision_monitor
    configuration (one velocity_polygon, a band per margin tier); `safecase nav2 check` proves
    every zone of it.

    Example: safecase nav2 export --out examples/nav2/exported.yaml

    Exit codes: 0 written; 2 bad option, configuration or output path.
    """
    if obstacle not in CLASSES:
        fail(f"--obstacle {obstacle!r}: allowed: {' | '.join(CLASSES)}")
    cfg = load_config_or_exit(config)
    # The configuration is valid, so its perception latency is > 0 (monitors.scan_max_age_s > 0
    # must not exceed it): Nav2 can enforce it as source_timeout.
    text = export_yaml(cfg, ClosingClass(obstacle))
    if out_path is None:
        typer.echo(text, nl=False)
        return
    try:
        out_path.parent.mkdir(parents=True, exist_ok=True)
        out_path.write_text(text)
    except OSError as exc:
        fail(f"--out {out_path}: cannot write: {exc.strerror}")
    out.print(f"wrote {out_path}", highlight=False)
