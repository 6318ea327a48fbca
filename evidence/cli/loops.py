"""The loops of ``safecase run`` around :func:`safety.run.run_audited`: a live source printing a
line per cycle, a simulator or log with a progress bar, and the stop request both read after
every cycle (SR-RUN-4)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Generator, Iterator
from pathlib import Path

from evidence.cli.availability import scan_progress
from evidence.cli.common import out
from pipeline.config import SafecaseConfig
from pipeline.sources import FrameSource
from pipeline.sources.logs.source import LogSource
from pipeline.sources.sim.source import SimSource, SimSourceBeside
from safety.run import RunSummary, run_audited
from safety.runtime import CycleInput, CycleOutput, Runtime

Observer = Callable[[CycleInput, CycleOutput], None]


def recorded(mcap: Path | None) -> None:
    if mcap is not None:
        out.print(f"recording: {mcap} (open it in Foxglove)", highlight=False)


def _generator(outputs: Iterator[CycleOutput]) -> Generator[CycleOutput, None, None]:
    """``outputs`` as the generator it is, so a stop can close it (and the audit log)."""
    assert isinstance(outputs, Generator)
    return outputs


# Set by SIGINT and SIGTERM: a stop request the run loops read after every cycle.
_STOP = threading.Event()


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """SIGINT (Ctrl-C) and SIGTERM (what service managers send) stop the run: the current
    cycle's record is written, the audit log closed and the summary printed. The handler raises
    KeyboardInterrupt and also sets :data:`_STOP`, which the loops check after each cycle: an
    exception raised while the interpreter runs a finaliser is dropped ("Exception ignored"),
    and the request must not be dropped with it."""

    def interrupt(signum: int, frame: object) -> None:
        _STOP.set()
        raise KeyboardInterrupt(f"signal {signum}")

    _STOP.clear()
    previous = {s: signal.signal(s, interrupt) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def stop_requested() -> None:
    """Raise KeyboardInterrupt when a stop was requested (see :func:`stop_on_signals`)."""
    if _STOP.is_set():
        raise KeyboardInterrupt("stop requested")


def _drive(
    outputs: Generator[CycleOutput, None, None],
    summary: RunSummary,
    each: Callable[[CycleOutput], object],
) -> None:
    """Every cycle of ``outputs`` into ``summary``, then ``each`` (its line, the progress bar),
    until the run ends or a stop is requested; a stop closes ``outputs`` (and so the audit log)
    before the caller prints the summary."""
    try:
        for o in outputs:
            summary.add(o)
            each(o)
            stop_requested()
    except KeyboardInterrupt:
        outputs.close()
        out.print("stopped on request", highlight=False)


# Which reason a cycle's line shows first: the link, then the other monitors, then a failed
# stage, then the governor (the first that any of the cycle's reasons starts with).
_REASON_ORDER = ("driver:", "scan_freshness:", "clock:", "deadline:", "operating_domain:", "")


def _why(reasons: tuple[str, ...]) -> str:
    """The reason worth a line: the scanner link's before the others (``_REASON_ORDER``)."""
    for prefix in _REASON_ORDER:
        found = [r for r in reasons if r.startswith(prefix) and not r.startswith("governor:")]
        if found:
            return f" ({found[0]})"
    return f" ({reasons[0]})" if reasons else ""


def run_live(
    cfg: SafecaseConfig,
    source: FrameSource,
    target: Path,
    max_scans: int,
    duration_s: float | None,
    mcap: Path | None,
) -> None:
    """A live source: one line per cycle, then the command mix (also when stopped)."""
    summary = RunSummary(source.name, audit_path=target)
    outputs = _generator(
        run_audited(
            cfg,
            source,
            audit_path=target,
            max_scans=max_scans,
            duration_s=duration_s,
            recording=mcap,
        )
    )

    def line(o: CycleOutput) -> None:
        c = o.command
        out.print(
            f"{summary.cycles:5d} {c.action.value:7s} {c.speed_mps:5.2f} m/s{_why(c.reasons)}",
            highlight=False,
            markup=False,
        )

    _drive(outputs, summary, line)
    out.print(
        f"{summary.cycles} cycles: "
        + ", ".join(f"{k} {v}" for k, v in sorted(summary.actions.items())),
        highlight=False,
    )
    out.print(f"audit log: {target} (verify: safecase audit verify {target})", highlight=False)
    recorded(mcap)


def run_recorded(
    cfg: SafecaseConfig,
    source: SimSource | SimSourceBeside | LogSource,
    target: Path,
    max_scans: int | None,
    duration_s: float | None,
    measured_clock: bool,
    mcap: Path | None,
    runtime: Runtime | None = None,
    observe: Observer | None = None,
) -> RunSummary:
    """The simulator or a log, with a progress bar; the summary holds the simulator's verdict.
    ``runtime`` and ``observe`` are :func:`safety.run.run_audited`'s."""
    summary = RunSummary(source.name, audit_path=target)
    total = source.n_frames if isinstance(source, SimSource | SimSourceBeside) else None
    with scan_progress(source.name) as bar:
        task = bar.add_task("run", total=total)
        outputs = _generator(
            run_audited(
                cfg,
                source,
                audit_path=target,
                max_scans=max_scans,
                duration_s=duration_s,
                measured_clock=measured_clock,
                recording=mcap,
                runtime=runtime,
                observe=observe,
            )
        )
        _drive(outputs, summary, lambda _: bar.update(task, completed=summary.cycles))
    if not isinstance(source, LogSource):
        summary.sim = source.result()
    return summary
