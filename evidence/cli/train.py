"""``safecase train``: the classifier from simulator data, seeded and deterministic (SR-CLS-2).

The work is :func:`pipeline.training.train.train`; this module reads the options, shows the
progress and reports. The model files go to ``--out`` (``out/classifier`` by default), never
over the packaged model unless that folder is named on purpose.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from evidence.cli.common import ConfigOption, fail, load_config_or_exit
from pipeline.errors import SafecaseError
from pipeline.training.train import TrainOptions, train

DEFAULT_OUT = Path("out/classifier")


def train_command(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Folder for the model files (created).")
    ] = DEFAULT_OUT,
    named_seeds: Annotated[int, typer.Option(min=0, help="Seeds per named scenario.")] = 30,
    encounter_seeds: Annotated[int, typer.Option(min=0, help="random_encounter seeds.")] = 2400,
    drill_seeds: Annotated[int, typer.Option(min=0, help="Reversal drill seeds.")] = 1800,
    test_named_seeds: Annotated[int, typer.Option(min=0, help="Held-out seeds per named.")] = 5,
    test_encounter_seeds: Annotated[int, typer.Option(min=0)] = 80,
    test_drill_seeds: Annotated[int, typer.Option(min=0)] = 60,
    duration: Annotated[float, typer.Option(min=0.5, help="Run length in seconds.")] = 20.0,
    static_keep: Annotated[float, typer.Option(min=0.0, max=1.0)] = 0.2,
    heldout: Annotated[
        Path | None, typer.Option(help="Write the held-out rows here (.npz).")
    ] = None,
    heldout_static_keep: Annotated[float, typer.Option(min=0.0, max=1.0)] = 0.1,
    workers: Annotated[int, typer.Option(min=1, help="Simulation processes.")] = 1,
    cache: Annotated[
        Path | None, typer.Option(help="Folder to keep simulated rows in between runs.")
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Train the track classifier on simulator data (deterministic for given options).

    Example: safecase train --named-seeds 2 --encounter-seeds 10 --drill-seeds 10 -o out/m

    Exit codes: 0 written; 2 bad configuration or options.
    """
    cfg = load_config_or_exit(config)
    options = TrainOptions(
        named_seeds=named_seeds,
        encounter_seeds=encounter_seeds,
        drill_seeds=drill_seeds,
        test_named_seeds=test_named_seeds,
        test_encounter_seeds=test_encounter_seeds,
        test_drill_seeds=test_drill_seeds,
        duration_s=duration,
        static_keep=static_keep,
        heldout_static_keep=heldout_static_keep,
        workers=workers,
        cache=cache,
    )
    with Progress(
        TextColumn("[bold]simulating[/] {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("runs"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        tasks: dict[str, TaskID] = {}

        def progress(plan: str, done: int, total: int) -> None:
            if plan not in tasks:
                tasks[plan] = bar.add_task(plan, total=total)
            bar.update(tasks[plan], completed=done)

        try:
            model = train(cfg, options, out, heldout=heldout, progress=progress, say=typer.echo)
        except SafecaseError as exc:
            fail(str(exc))
    typer.echo(f"wrote {model} sha256 {hashlib.sha256(model.read_bytes()).hexdigest()}")
