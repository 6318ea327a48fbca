"""``safecase mcap``: look at and check a run's MCAP recording (SR-RUN-7).

``show`` draws one cycle of the file with matplotlib (what Foxglove's 3-D panel shows);
``check`` compares the recording with the run's audit log record by record.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from evidence.cli.common import fail, out

app = typer.Typer(
    help="Look at and check a run's MCAP recording (safecase run --mcap FILE).\n\n"
    "Example: safecase mcap show pass.mcap --at 3.0 --out pass.png\n\n"
    "Exit codes: 0 done (check: the recording agrees with the audit log); 1 check: they "
    "disagree; 2 a file that cannot be read or bad options.",
    no_args_is_help=True,
)
McapArgument = Annotated[Path, typer.Argument(help="An MCAP file written by safecase run --mcap.")]


def _readable(path: Path) -> None:
    if not path.is_file():
        fail(f"{path}: no such file")


@app.command()
def show(
    mcap: McapArgument,
    at: Annotated[
        float | None, typer.Option(help="The cycle nearest this time [s] (default: the last).")
    ] = None,
    output: Annotated[Path | None, typer.Option("--out", help="PNG to write.")] = None,
) -> None:
    """Draw one cycle of the recording: scan, clusters, tracks, envelopes by margin tier,
    path, costmap and the command (odom frame).

    Example: safecase mcap show pass.mcap --at 3.0 --out pass.png

    Exit codes: 0 written; 2 a file that cannot be read or holds no cycle.
    """
    from safety.foxglove_view import cycle_figure, read_cycle

    _readable(mcap)
    try:
        cycle = read_cycle(mcap, at)
    except Exception as exc:  # rosbags raises many types; all mean "not a recording"
        fail(f"{mcap}: not a readable recording ({type(exc).__name__}: {exc})")
    target = output or mcap.with_suffix(".png")
    cycle_figure(cycle).savefig(target, dpi=110)
    out.print(f"cycle at {cycle['stamp_s']:.3f} s: {target}", highlight=False)


@app.command()
def check(
    mcap: McapArgument,
    audit: Annotated[Path, typer.Option(help="The run's audit log.")],
) -> None:
    """Check the recording against the run's audit log: the same cycles, record by record.

    Example: safecase mcap check pass.mcap --audit out/audit/pass.jsonl

    Exit codes: 0 they agree; 1 they disagree (each difference named); 2 a file that cannot
    be read.
    """
    from safety.foxglove_view import compare_with_audit

    _readable(mcap)
    _readable(audit)
    try:
        problems = compare_with_audit(mcap, audit)
    except Exception as exc:  # rosbags raises many types; all mean "not a recording"
        fail(f"{mcap}: not a readable recording ({type(exc).__name__}: {exc})")
    for problem in problems:
        out.print(problem, highlight=False, markup=False)
    if problems:
        raise typer.Exit(1)
    out.print(f"{mcap}: every cycle agrees with {audit}", highlight=False)
