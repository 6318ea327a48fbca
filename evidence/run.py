"""Run the certification suite in-process with a progress display (``safecase certify``).

pytest's own terminal output is switched off; a rich progress bar shows how far the suite is,
and failures and collection errors are printed as they happen, so a long certify run is
readable. The evidence plugin writes the signed bundle at the end of the session.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from evidence.catalogue import default_catalogue_path
from evidence.model import Bundle
from evidence.plugin import STATE
from evidence.safety_case import default_hazards_path

__all__ = ["CertificationResult", "run_certification"]


@dataclass(slots=True)
class CertificationResult:
    """The pytest exit code and the bundle the session produced (None if none was)."""

    exit_code: int
    bundle: Bundle | None


class _ProgressPlugin:
    """Shows a progress bar and prints failures; remembers the session's bundle."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.progress = Progress(
            TextColumn("[bold]certify"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TextColumn("{task.fields[current]}", style="dim"),
            console=console,
            transient=False,
        )
        self.task = self.progress.add_task("tests", total=None, current="collecting")
        self.failed: list[str] = []

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.progress.update(self.task, total=len(session.items), current="")
        self.progress.start()

    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        if report.failed:
            self.console.print(f"[bold red]collection error[/] {report.nodeid}")
            self.console.print(str(report.longreprtext), markup=False, highlight=False)

    def pytest_runtest_logstart(self, nodeid: str, location: Any) -> None:
        self.progress.update(self.task, current=nodeid[-70:])

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.failed:
            self.failed.append(report.nodeid)
            last = str(report.longreprtext).strip().splitlines()
            self.progress.console.print(
                # Escaped: a parametrised node ID such as test_x[high] is not rich markup.
                f"[bold red]FAILED[/] {escape(report.nodeid)} ({report.when}): "
                f"{escape(last[-1]) if last else ''}",
                highlight=False,
            )
        if report.when == "teardown":
            self.progress.advance(self.task)

    def pytest_configure(self, config: pytest.Config) -> None:
        self.config: pytest.Config | None = config

    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        self.progress.stop()

    def result_bundle(self) -> Bundle | None:
        """The bundle the evidence plugin assembled, once the session has ended."""
        config = getattr(self, "config", None)
        state = config.stash.get(STATE, None) if config is not None else None
        return state.bundle if state is not None else None


def run_certification(
    *,
    root: Path,
    bundle_dir: Path,
    config_path: Path | None,
    profile: str,
    key: Path | None,
    select: str | None,
    benchmarks: bool,
    console: Console,
) -> CertificationResult:
    """Run properties/ and tests/ under ``profile`` and write the bundle to ``bundle_dir``."""
    bundle_dir.mkdir(parents=True, exist_ok=True)
    targets = [str(root / "properties"), str(root / "tests")]
    args = [
        *targets,
        f"--rootdir={root}",
        "-p",
        "no:terminal",
        "-p",
        "no:cacheprovider",
        f"--hypothesis-profile={profile}",
        f"--safecase-out={bundle_dir}",
        "--safecase-enforce",
        # safecase certifies itself: its catalogue, hazard log and runtime provenance, whatever
        # ini file the tree has (docs/plugin.md)
        f"--safecase-requirements={default_catalogue_path()}",
        f"--safecase-hazards={default_hazards_path()}",
        "-o",
        "safecase_runtime=true",
        f"--benchmark-json={bundle_dir / 'benchmarks.json'}",
    ]
    if not benchmarks:
        args.append("--benchmark-disable")
    if config_path is not None:
        args.append(f"--safecase-config={config_path}")
    if key is not None:
        args.append(f"--safecase-key={key}")
    if select:
        args += ["-k", select]
    # As under `python -m pytest` (make test): the tree's root on sys.path, so processes the
    # suite spawns can import what its tests define (a console script's sys.path[0] is bin/).
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    plugin = _ProgressPlugin(console)
    code = pytest.main(args, plugins=[plugin])
    return CertificationResult(exit_code=int(code), bundle=plugin.result_bundle())
