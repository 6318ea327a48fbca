"""``safecase audit``: verify, show, tail and replay audit logs (SR-AUD-1, SR-AUD-2).

Exit codes: 0 intact (and, for replay, every command reproduced); 1 tampered or not
reproduced; 3 incomplete (the writer stopped: a crash, or still running); 2 usage errors.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Iterable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from pipeline.errors import SafecaseError
from safety.audit.keys import load_public_key
from safety.audit.log import AuditError, iter_lines
from safety.audit.verify import AuditStatus, AuditVerification, verify_log

app = typer.Typer(help="Verify, inspect and replay hash-chained audit logs.", no_args_is_help=True)
_out = Console(soft_wrap=True)
_err = Console(stderr=True, soft_wrap=True)

EXIT = {AuditStatus.INTACT: 0, AuditStatus.TAMPERED: 1, AuditStatus.INCOMPLETE: 3}

LogArgument = Annotated[Path, typer.Argument(help="The audit log (JSON Lines).")]
KeyOption = Annotated[
    Path | None,
    typer.Option("--key", help="Trusted Ed25519 public key (PEM or base64) that signed the head."),
]
NoAnchorOption = Annotated[
    bool,
    typer.Option("--no-anchor", help="Verify without the LOG.head anchor (copied log)."),
]


def _verify(log: Path, key: Path | None, no_anchor: bool) -> AuditVerification:
    try:
        trusted = load_public_key(key) if key is not None else None
        return verify_log(log, trusted_key=trusted, require_anchor=not no_anchor)
    except (OSError, SafecaseError) as exc:
        _err.print(f"[bold red]error:[/] {exc}", highlight=False)
        raise typer.Exit(2) from None


def _print_verification(result: AuditVerification) -> None:
    style = {"intact": "bold green", "incomplete": "bold yellow", "tampered": "bold red"}
    _out.print(f"[{style[result.status.value]}]{result.describe()}[/]", highlight=False)
    if result.header is not None:
        h = result.header
        _out.print(
            f"config hash {h['config_hash']}, model hash {h['model_hash']}, perception "
            f"latency {h['latency']['perception_latency_s']} s ({h['latency']['latency_source']})",
            highlight=False,
        )
    for note in result.notes:
        _out.print(f"note: {note}", highlight=False)


@app.command("verify")
def verify(log: LogArgument, key: KeyOption = None, no_anchor: NoAnchorOption = False) -> None:
    """Check the hash chain, the head anchor and its signature; name the first bad record."""
    result = _verify(log, key, no_anchor)
    _print_verification(result)
    raise typer.Exit(EXIT[result.status])


def _rows(records: Iterable[tuple[int, dict[str, Any]]]) -> Table:
    table = Table("line", "seq", "stamp s", "scan", "tracks", "action", "speed m/s", "ms", "why")
    for number, rec in records:
        if rec["kind"] != "cycle":
            table.add_row(str(number), str(rec["seq"]), "", "", "", rec["kind"], "", "", "")
            continue
        scan = rec["inputs"].get("scan") or {}
        tracker = rec["inputs"].get("tracker") or {}
        command = rec["command"]
        total_ms = sum(float(v) for v in rec["timings_s"].values()) * 1e3
        table.add_row(
            str(number),
            str(rec["seq"]),
            f"{float(rec['stamp_s']):.3f}",
            f"#{scan.get('seq', '-')}",
            str(tracker.get("n_live", "-")),
            command["action"],
            f"{command['speed_mps']:.3f}",
            f"{total_ms:.2f}",
            "; ".join(command["reasons"])[:120],
        )
    return table


def _records(log: Path, upto: int) -> Iterable[tuple[int, dict[str, Any]]]:
    for number, raw, terminated in iter_lines(log):
        if number > upto or not terminated:
            return
        yield number, json.loads(raw)


@app.command("show")
def show(
    log: LogArgument,
    key: KeyOption = None,
    no_anchor: NoAnchorOption = False,
    limit: Annotated[int, typer.Option(help="Show at most this many records.")] = 50,
    first: Annotated[int, typer.Option(help="Start at this line.")] = 1,
) -> None:
    """Verify the log, summarise it and list its records as a table."""
    result = _verify(log, key, no_anchor)
    _print_verification(result)
    counts: dict[str, int] = {}
    shown: list[tuple[int, dict[str, Any]]] = []
    for number, rec in _records(log, result.n_records):
        if rec["kind"] == "cycle":
            counts[rec["command"]["action"]] = counts.get(rec["command"]["action"], 0) + 1
        if number >= first and len(shown) < limit:
            shown.append((number, rec))
    _out.print(
        "commands: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), highlight=False
    )
    _out.print(_rows(shown))
    raise typer.Exit(EXIT[result.status])


@app.command("tail")
def tail(
    log: LogArgument,
    n: Annotated[int, typer.Option("-n", help="How many records.")] = 10,
) -> None:
    """The last records of a log (verified up to there; a live log reads as incomplete)."""
    result = _verify(log, None, no_anchor=True)
    last: deque[tuple[int, dict[str, Any]]] = deque(maxlen=max(n, 1))
    last.extend(_records(log, result.n_records))
    _out.print(_rows(last))
    _print_verification(result)
    raise typer.Exit(EXIT[result.status])


@app.command("replay")
def replay_command(
    log: LogArgument, key: KeyOption = None, no_anchor: NoAnchorOption = False
) -> None:
    """Recompute every recorded decision from the recorded inputs and compare (SR-AUD-2)."""
    from safety.audit.replay import replay  # the governor stack: only when replaying

    try:
        trusted = load_public_key(key) if key is not None else None
        report = replay(log, trusted_key=trusted, require_anchor=not no_anchor)
    except (OSError, AuditError, SafecaseError) as exc:
        _err.print(f"[bold red]error:[/] {exc}", highlight=False)
        raise typer.Exit(2) from None
    _print_verification(report.verification)
    if report.refused:
        _out.print(f"[bold red]{report.refused}[/]", highlight=False)
        raise typer.Exit(1)
    for m in report.mismatches[:20]:
        _out.print(
            f"[bold red]MISMATCH[/] line {m.line} seq {m.seq} {m.what}: recorded {m.recorded!r}, "
            f"replayed {m.replayed!r}",
            highlight=False,
        )
    _out.print(f"replayed {report.n_reproduced} of {report.n_cycles} cycles exactly")
    if not report.ok:
        raise typer.Exit(1)
    raise typer.Exit(EXIT[report.verification.status])
