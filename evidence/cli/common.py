"""What every ``safecase`` command shares: consoles, the ``--config`` option, one-line errors.

A user's mistake (a bad configuration value, an unreadable file, a bad option) ends with one
line per problem and exit code 2, never a traceback (SR-CFG-1).
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Annotated, NoReturn

import typer
from rich.console import Console
from rich.markup import escape

from pipeline.compat import UTC
from pipeline.config import SafecaseConfig, load_config
from pipeline.errors import ConfigError

__all__ = ["ConfigOption", "err", "fail", "load_config_or_exit", "out", "stamp"]

out = Console(soft_wrap=True)
err = Console(stderr=True, soft_wrap=True)

ConfigOption = Annotated[
    Path | None,
    typer.Option("--config", "-c", help="TOML file overriding the built-in configuration."),
]


def fail(message: str, code: int = 2) -> NoReturn:
    """Print ``error: message`` on stderr (no markup read from it) and exit with ``code``."""
    err.print(f"[bold red]error:[/] {escape(message)}", highlight=False)
    raise typer.Exit(code)


def load_config_or_exit(path: Path | None) -> SafecaseConfig:
    """Load the configuration; on error print one line per problem and exit 2 (SR-CFG-1)."""
    try:
        return load_config(path)
    except ConfigError as exc:
        for line in exc.lines:
            err.print(f"[bold red]config error:[/] {escape(line)}", highlight=False)
        raise typer.Exit(2) from None


def stamp() -> str:
    """The current UTC time as a file-name stamp (``20260101T120000Z``)."""
    return datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
