"""The ``safecase`` command line run as a real subprocess, for tests of the CLI."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

__all__ = ["SAFECASE", "run_safecase"]

SAFECASE = [sys.executable, "-m", "evidence.cli"]


def run_safecase(
    *args: str, cwd: Path | None = None, timeout_s: float = 300.0
) -> subprocess.CompletedProcess[str]:
    """Run ``safecase ARGS`` (no display, wide console) and capture its output."""
    env = dict(os.environ, MPLBACKEND="Agg", COLUMNS="200")
    return subprocess.run(
        [*SAFECASE, *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=timeout_s,
        check=False,
    )
