"""``safecase audit``: verify, show, tail and replay audit logs (SR-AUD-1, SR-AUD-2).

Exit codes (:data:`EXIT`): 0 intact (and, for replay, every command reproduced); 1 tampered, or
not reproduced; 2 usage errors and files that cannot be read (missing, not a regular file, no
permission, a bad key); 3 incomplete (the writer stopped: a crash, or still running); 4
unanchored (the chain checks out but the ``LOG.head`` anchor is missing: truncation cannot be
excluded); 5 empty (no record at all: not an audit log). Every problem is one line, never a
traceback.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from pipeline.errors import SafecaseError
from safety.audit.keys import load_public_key
from safety.audit.verify import AuditStatus, AuditVerification, iter_records, verify_log

EXIT_CODES_HELP = (
    "Exit codes: 0 intact; 1 tampered (the first bad line is named); 2 bad options or a file "
    "that cannot be read (missing, a FIFO, a device, a bad key); 3 incomplete (no close record "
    "or a partial last line: a crash, or still writing); 4 unanchored (LOG.head missing: the "
    "chain checks out, truncation cannot be excluded); 5 empty (not an audit log)."
)

app = typer.Typer(
    help="Verify, inspect and replay hash-chained audit logs.\n\n"
    "Example: safecase audit verify out/audit/run.jsonl --public-key signing.pub\n\n"
    + EXIT_CODES_HELP,
    no_args_is_help=True,
)
_out = Console(soft_wrap=True)
_err = Console(stderr=True, soft_wrap=True)

EXIT = {
    AuditStatus.INTACT: 0,
    AuditStatus.TAMPERED: 1,
    AuditStatus.INCOMPLETE: 3,
    AuditStatus.UNANCHORED: 4,
    AuditStatus.EMPTY: 5,
}
_STYLE = {
    AuditStatus.INTACT: "bold green",
    AuditStatus.INCOMPLETE: "bold yellow",
    AuditStatus.UNANCHORED: "bold yellow",
    AuditStatus.EMPTY: "bold red",
    AuditStatus.TAMPERED: "bold red",
}

LogArgument = Annotated[Path, typer.Argument(help="The audit log (JSON Lines).")]
KeyOption = Annotated[
    Path | None,
    typer.Option(
        "--public-key",
        help="Trusted Ed25519 public key (PEM or base64) that must have signed the head.",
    ),
]
NoAnchorOption = Annotated[
    bool,
    typer.Option(
        "--no-anchor",
        help="Verify the chain alone, without the LOG.head anchor (a copied log: truncation at "
        "a record boundary then reads as incomplete, not unanchored).",
    ),
]


def _fail(message: str) -> typer.Exit:
    _err.print(f"[bold red]error:[/] {escape(message)}", highlight=False)
    return typer.Exit(2)


def _verify(log: Path, key: Path | None, no_anchor: bool) -> AuditVerification:
    try:
        trusted = load_public_key(key) if key is not None else None
        return verify_log(log, trusted_key=trusted, require_anchor=not no_anchor)
    except (OSError, SafecaseError) as exc:
        raise _fail(str(exc)) from None


def _print_verification(result: AuditVerification) -> None:
    _out.print(f"[{_STYLE[result.status]}]{escape(result.describe())}[/]", highlight=False)
    if result.header is not None:
        h = result.header
        _out.print(
            f"config hash {h['config_hash']}, model hash {h['model_hash']}, perception "
            f"latency {h['latency']['perception_latency_s']} s ({h['latency']['latency_source']})",
            highlight=False,
            markup=False,
        )
    for note in result.notes:
        _out.print(f"note: {note}", highlight=False, markup=False)


def _cell(value: Any, width: int = 24) -> str:
    """A table cell of a free-form recorded value, cut to ``width`` characters."""
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def _field(mapping: dict[str, Any], stage: str, key: str) -> str:
    """``mapping[stage][key]`` of a recorded summary, or "-" (summaries are free-form)."""
    part = mapping.get(stage)
    return _cell(part.get(key, "-")) if isinstance(part, dict) else "-"


def _rows(records: Iterable[tuple[int, dict[str, Any]]]) -> Table:
    """Records as a table; their shape was checked by :func:`~safety.audit.verify.iter_records`."""
    table = Table("line", "seq", "stamp s", "scan", "tracks", "action", "speed m/s", "ms", "why")
    for number, rec in records:
        if rec["kind"] != "cycle":
            table.add_row(str(number), str(rec["seq"]), "", "", "", rec["kind"], "", "", "")
            continue
        command = rec["command"]
        total_ms = sum(float(v) for v in rec["timings_s"].values()) * 1e3
        table.add_row(
            str(number),
            str(rec["seq"]),
            f"{float(rec['stamp_s']):.3f}",
            f"#{_field(rec['inputs'], 'scan', 'seq')}",
            _field(rec["inputs"], "tracker", "n_live"),
            _cell(command["action"]),
            f"{float(command['speed_mps']):.3f}",
            f"{total_ms:.2f}",
            "; ".join(command["reasons"])[:120],
        )
    return table


def _records(log: Path, upto: int) -> Iterable[tuple[int, dict[str, Any]]]:
    try:
        yield from iter_records(log, upto)
    except SafecaseError as exc:
        raise _fail(str(exc)) from None


@app.command(
    "verify",
    epilog="Example: safecase audit verify out/audit/run.jsonl --public-key signing.pub\n\n"
    + EXIT_CODES_HELP,
)
def verify(log: LogArgument, key: KeyOption = None, no_anchor: NoAnchorOption = False) -> None:
    """Check the hash chain, every record's shape, the head anchor (byte for byte) and its
    signature; name the first bad record. Without --public-key a signature is checked against the
    key the log names itself, which proves only that nothing changed since whoever signed it."""
    result = _verify(log, key, no_anchor)
    _print_verification(result)
    raise typer.Exit(EXIT[result.status])


@app.command(
    "show",
    epilog="Example: safecase audit show out/audit/run.jsonl --first 100 --limit 20\n\n"
    + EXIT_CODES_HELP,
)
def show(
    log: LogArgument,
    key: KeyOption = None,
    no_anchor: NoAnchorOption = False,
    limit: Annotated[int, typer.Option(help="Show at most this many records.")] = 50,
    first: Annotated[int, typer.Option(help="Start at this line.")] = 1,
) -> None:
    """Verify the log, summarise it and list its records (up to the first bad one) as a table."""
    result = _verify(log, key, no_anchor)
    _print_verification(result)
    counts: dict[str, int] = {}
    shown: list[tuple[int, dict[str, Any]]] = []
    for number, rec in _records(log, result.n_records):
        if rec["kind"] == "cycle":
            action = _cell(rec["command"]["action"])
            counts[action] = counts.get(action, 0) + 1
        if number >= first and len(shown) < limit:
            shown.append((number, rec))
    if result.n_records:
        _out.print(
            "commands: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())),
            highlight=False,
            markup=False,
        )
        _out.print(_rows(shown))
    raise typer.Exit(EXIT[result.status])


@app.command(
    "tail",
    epilog="Example: safecase audit tail out/audit/device-20250101.jsonl -n 5\n\n"
    + EXIT_CODES_HELP
    + " tail reads the chain alone, so never 4; a log still being written reads as incomplete"
    " (3).",
)
def tail(
    log: LogArgument,
    n: Annotated[int, typer.Option("-n", help="How many records.")] = 10,
) -> None:
    """The last records of a log, verified up to there (the chain alone: a live log's anchor
    lags its records)."""
    result = _verify(log, None, no_anchor=True)
    last: deque[tuple[int, dict[str, Any]]] = deque(maxlen=max(n, 1))
    last.extend(_records(log, result.n_records))
    if result.n_records:
        _out.print(_rows(last))
    _print_verification(result)
    raise typer.Exit(EXIT[result.status])


@app.command(
    "replay",
    epilog="Example: safecase audit replay out/audit/run.jsonl\n\n"
    + EXIT_CODES_HELP
    + " Replay also exits 1 when a recorded decision is not reproduced.",
)
def replay_command(
    log: LogArgument, key: KeyOption = None, no_anchor: NoAnchorOption = False
) -> None:
    """Verify the log, then recompute every recorded decision from the recorded inputs and
    compare, bit for bit (SR-AUD-2). A tampered or empty log is not replayed."""
    from safety.audit.replay import replay  # the governor stack: only when replaying

    try:
        trusted = load_public_key(key) if key is not None else None
        report = replay(log, trusted_key=trusted, require_anchor=not no_anchor)
    except (OSError, SafecaseError) as exc:
        raise _fail(str(exc)) from None
    _print_verification(report.verification)
    if report.refused:
        _out.print(f"[bold red]{escape(report.refused)}[/]", highlight=False)
        raise typer.Exit(EXIT[report.verification.status] or 1)
    for m in report.mismatches[:20]:
        _out.print(
            f"[bold red]MISMATCH[/] line {m.line} seq {m.seq} {m.what}: "
            + escape(f"recorded {_cell(repr(m.recorded), 200)}, replayed ")
            + escape(_cell(repr(m.replayed), 200)),
            highlight=False,
        )
    _out.print(f"replayed {report.n_reproduced} of {report.n_cycles} cycles exactly")
    if not report.ok:
        raise typer.Exit(1)
    raise typer.Exit(EXIT[report.verification.status])
