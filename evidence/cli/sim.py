"""``safecase sim``: list the scenarios, picture one, write a labelled dataset (SR-SIM-*) or
a scenario's map (SR-AVL-8)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from evidence.cli.common import ConfigOption, load_config_or_exit
from pipeline.config import SafecaseConfig
from pipeline.sources.sim.scenarios import SCENARIOS, ScenarioError

app = typer.Typer(help="Scenario simulator: list, picture, datasets.", no_args_is_help=True)
_out = Console(soft_wrap=True)
_err = Console(stderr=True, soft_wrap=True)


def _config(path: Path | None) -> SafecaseConfig:
    return load_config_or_exit(path)


def _check_names(names: list[str]) -> None:
    unknown = [n for n in names if n not in SCENARIOS]
    if unknown:
        _err.print(
            f"[bold red]error:[/] unknown scenario(s) {', '.join(unknown)}; "
            f"known: {', '.join(SCENARIOS)}",
            highlight=False,
        )
        raise typer.Exit(2)


@app.command("list")
def list_scenarios() -> None:
    """List the named scenarios.

    Example: safecase sim list

    Exit codes: 0.
    """
    table = Table("scenario", "environment", "what happens")
    for info in SCENARIOS.values():
        table.add_row(info.name, info.environment, info.description)
    _out.print(table)


@app.command("show")
def show(
    name: Annotated[str, typer.Argument(help="Scenario name (see `safecase sim list`).")],
    out: Annotated[Path | None, typer.Option("--out", "-o", help="PNG file to write.")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed (default: sim.seed).")] = None,
    duration: Annotated[
        float | None, typer.Option(help="Run length in s (default: sim.duration_s).")
    ] = None,
    at: Annotated[
        float | None, typer.Option(help="Time of the scan drawn (default: the closest call).")
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Run a scenario at the configured constant speed and draw it (scene, trajectories, a
    scan, speeds with forklift states, separations) into a PNG.

    Example: safecase sim show crossing_pedestrian --seed 3 -o crossing.png

    Exit codes: 0 drawn; 2 unknown scenario, bad option or configuration.
    """
    from pipeline.sources.sim.ego import ConstantSpeed
    from pipeline.sources.sim.plot import scene_figure
    from pipeline.sources.sim.scenarios import make_simulation

    _check_names([name])
    cfg = _config(config)
    if duration is not None and duration <= 0:
        _err.print(f"[bold red]error:[/] --duration {duration}: must be > 0 s")
        raise typer.Exit(2)
    try:
        sim = make_simulation(cfg, name, seed, duration)
    except ScenarioError as exc:
        _err.print(f"[bold red]error:[/] {exc}")
        raise typer.Exit(2) from None
    result = sim.run(ConstantSpeed(cfg.sim.ego_speed_mps))
    target = out or Path(f"out/sim/{name}_seed{sim.seed}.png")
    target.parent.mkdir(parents=True, exist_ok=True)
    fig = scene_figure(result, at)
    fig.savefig(target, dpi=110)
    contact = (
        "no contact"
        if not result.contact
        else (
            "CONTACT with "
            + ", ".join(
                o.name
                for o, t in zip(result.world.objects, result.contact_time_s, strict=True)
                if t == t
            )
        )
    )
    _out.print(
        f"{name} seed {sim.seed}: {len(result.frames)} scans, {contact}; wrote {target}",
        highlight=False,
    )


@app.command("dataset")
def dataset(
    out: Annotated[Path, typer.Option("--out", "-o", help=".npz file to write.")],
    scenarios: Annotated[
        str, typer.Option(help="Comma-separated scenario names, or 'all' (the named ones).")
    ] = "all",
    seeds: Annotated[int, typer.Option(min=1, help="Seeds 0..N-1 of every scenario.")] = 1,
    first_seed: Annotated[int, typer.Option(min=0, help="First seed.")] = 0,
    duration: Annotated[
        float | None, typer.Option(help="Run length in s (default: sim.duration_s).")
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Write labelled scans and per-object ground truth (format: pipeline.sources.sim.dataset).

    Example: safecase sim dataset -o data.npz --scenarios crossing_pedestrian --seeds 3

    Exit codes: 0 written; 2 unknown scenario, bad option or configuration.
    """
    from pipeline.sources.sim.dataset import write_dataset

    names = (
        [n for n in SCENARIOS if n != "random_encounter"]
        if scenarios == "all"
        else [n.strip() for n in scenarios.split(",") if n.strip()]
    )
    _check_names(names)
    if duration is not None and duration <= 0:
        _err.print(f"[bold red]error:[/] --duration {duration}: must be > 0 s")
        raise typer.Exit(2)
    cfg = _config(config)
    meta = write_dataset(out, cfg, names, range(first_seed, first_seed + seeds), duration)
    frames = sum(r["frames"] for r in meta["runs"])
    _out.print(f"wrote {out}: {len(meta['runs'])} runs, {frames} frames", highlight=False)


@app.command("map")
def write_map(
    name: Annotated[str, typer.Argument(help="Scenario name (see `safecase sim list`).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Nav2 map YAML file to write.")],
    seed: Annotated[int | None, typer.Option(help="Seed (default: sim.seed).")] = None,
    config: ConfigOption = None,
) -> None:
    """Write the scenario's fixed structure as a Nav2 map_server map (YAML and PGM beside it):
    the map the runtime is given in simulation (map.resolution_m, map.tolerance_m; SR-AVL-8),
    and the format `map.file` reads on a robot.

    Example: safecase sim map crossing_pedestrian -o out/maps/crossing.yaml

    Exit codes: 0 written; 2 unknown scenario, bad option or configuration.
    """
    from pipeline.sources.sim.scenarios import make_simulation
    from pipeline.static_map import StaticMap

    _check_names([name])
    cfg = _config(config)
    sim = make_simulation(cfg, name, seed)
    section = cfg.map
    smap = StaticMap.from_parts(
        list(sim.world.structure.outline.parts()), section.resolution_m, section.tolerance_m
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    written = smap.write_nav2(out)
    rows, cols = smap.occupied.shape
    _out.print(
        f"wrote {written} and {written.with_suffix('.pgm').name}: {cols} x {rows} cells of "
        f"{smap.resolution_m} m, {int(smap.occupied.sum())} occupied",
        highlight=False,
    )
