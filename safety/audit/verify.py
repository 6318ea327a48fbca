"""Verification of an audit log: chain, canonical bytes, record shape, head anchor, signature
(SR-AUD-1).

:func:`verify_log` streams the log once and stops at the first bad record, naming its line and
what is wrong with it:

* a line that is not a JSON record, or whose bytes differ from the record's canonical form, or
  that nests deeper than :data:`MAX_DEPTH` or holds a number beyond 64-bit integers (no record
  safecase writes does): edited;
* a record whose content does not match its hash: changed;
* a record that is a copy of an earlier one: duplicated (inserted);
* a record whose ``prev`` is the hash of an earlier, non-adjacent record: the lines between
  were inserted;
* a record whose ``prev`` is not the previous record's hash: records are missing (deleted:
  its seq jumps ahead), out of order (its seq goes back) or it was replaced (same seq);
* a correctly chained record without the fields its kind always has (or with others): forged
  (re-chained by someone who can compute hashes);
* anything after the close record, a header anywhere but line 1, a first line that is not a
  header: inserted or removed;
* a head anchor that is not byte for byte the canonical form of exactly its known keys: edited;
  the anchor says a record was made durable that the log does not hold: truncated; the
  anchor's signature does not verify, or is missing although the header names a key: the
  anchor or the chain was rewritten.

Outcomes (:class:`AuditStatus`), most severe first: ``tampered`` (any of the above);
``empty`` (no complete record and no anchor: not an audit log); ``unanchored`` (the chain
checks out, but the ``LOG.head`` anchor is missing, so truncation at a record boundary cannot be
excluded; ``require_anchor=False`` accepts that and gives the chain's own verdict);
``incomplete`` (a partial last line or no close record, the chain intact: what a crash leaves);
``intact``.

What each record kind must hold is in :mod:`safety.audit.records`; the head anchor and its
signature are read and checked by :mod:`safety.audit.anchor`.
"""

from __future__ import annotations

import enum
import os
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from safety.audit.anchor import read_anchor, signature_status
from safety.audit.files import file_kind
from safety.audit.log import (
    GENESIS,
    SCHEMA,
    AuditError,
    RecordTooLongError,
    anchor_path,
    iter_lines,
    record_hash,
)
from safety.audit.records import BadRecordError, parse_record, structure_problem

__all__ = ["AuditStatus", "AuditVerification", "iter_records", "verify_log"]


class AuditStatus(enum.Enum):
    """Outcome of :func:`verify_log` (module docstring)."""

    INTACT = "intact"
    INCOMPLETE = "incomplete"
    UNANCHORED = "unanchored"
    EMPTY = "empty"
    TAMPERED = "tampered"


@dataclass
class AuditVerification:
    """What :func:`verify_log` found. ``first_bad_line`` (1-based) and ``problem`` name the
    first bad record (TAMPERED) or the point where the log stops (INCOMPLETE); ``problem`` also
    says why an UNANCHORED or EMPTY log is one."""

    path: Path
    status: AuditStatus = AuditStatus.INTACT
    first_bad_line: int | None = None
    problem: str = ""
    n_records: int = 0
    n_cycles: int = 0
    closed: bool = False
    head_seq: int = -1
    head_hash: str = GENESIS
    header: dict[str, Any] | None = None
    anchor_seq: int | None = None
    signature: str = "absent"
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when the log is intact (closed cleanly, nothing wrong)."""
        return self.status is AuditStatus.INTACT

    def describe(self) -> str:
        """One line: status, records, and the first problem."""
        where = f" at line {self.first_bad_line}" if self.first_bad_line is not None else ""
        what = f": {self.problem}" if self.problem else ""
        return (
            f"{self.status.value.upper()}{where}{what} ({self.n_records} records, "
            f"{self.n_cycles} cycles, head seq {self.head_seq}, signature {self.signature})"
        )


def _link_problem(
    record: dict[str, Any], expected_seq: int, seen: dict[str, tuple[int, int]], number: int
) -> tuple[int, str]:
    """Diagnose a record whose ``prev`` is not the previous record's hash."""
    seq = record["seq"]
    if record["prev"] in seen:
        line, _ = seen[record["prev"]]
        return line + 1, (
            f"line {number} (seq {seq}) links to line {line}: lines {line + 1}..{number - 1} "
            "were inserted"
        )
    if seq > expected_seq:
        return number, f"records seq {expected_seq}..{seq - 1} missing: deleted (or reordered)"
    if seq < expected_seq:
        return number, f"seq {seq} where {expected_seq} was due: records reordered"
    # Either the previous record was replaced (with a hash recomputed for its new content) or
    # this one was (with a wrong link); the earlier line is the first that may be bad.
    return number - 1, f"line {number} does not chain to line {number - 1}: one was replaced"


def _walk(result: AuditVerification, anchor: dict[str, Any] | None) -> tuple[bool, dict[int, str]]:
    """Check every complete line; returns (partial last line seen, anchor-relevant hashes)."""
    prev, expected = GENESIS, 0
    seen: dict[str, tuple[int, int]] = {}
    wanted = {} if anchor is None else {anchor["seq"]: ""}
    partial = False
    for number, raw, terminated in iter_lines(result.path):
        if not terminated:
            if result.closed:
                raise BadRecordError(number, "bytes after the close record: appended")
            partial = True
            result.first_bad_line = number
            result.problem = f"partial last line ({len(raw)} bytes): the writer stopped mid-write"
            break
        if result.closed:
            raise BadRecordError(number, "record after the close record: appended")
        record = parse_record(number, raw)
        body = {k: v for k, v in record.items() if k != "hash"}
        if record_hash(record["prev"], body) != record["hash"]:
            raise BadRecordError(number, "content does not match its hash: changed")
        if record["hash"] in seen:
            raise BadRecordError(number, f"copy of line {seen[record['hash']][0]}: inserted")
        kind = record["kind"]
        if number == 1 and (kind != "header" or record["seq"] != 0 or record["prev"] != GENESIS):
            raise BadRecordError(
                1, "the first record is not the header: header removed or replaced"
            )
        if number > 1 and kind == "header":
            raise BadRecordError(number, "a second header: inserted")
        if record["prev"] != prev:
            raise BadRecordError(*_link_problem(record, expected, seen, number))
        if record["seq"] != expected:
            raise BadRecordError(number, f"seq {record['seq']} where {expected} was due: forged")
        shape = structure_problem(record)
        if shape is not None:
            raise BadRecordError(number, f"{shape}: forged (not a record safecase writes)")
        if kind == "header":
            if record["schema"] != SCHEMA:
                raise BadRecordError(1, f"schema {record['schema'][:40]!r}, expected {SCHEMA}")
            result.header = record
        elif kind == "cycle":
            result.n_cycles += 1
        elif kind == "close":
            if record["n_records"] != expected:
                raise BadRecordError(
                    number, "close record counts the wrong number of records: forged"
                )
            result.closed = True
        else:
            raise BadRecordError(number, f"unknown record kind {kind[:40]!r}: edited")
        if record["seq"] in wanted:
            wanted[record["seq"]] = record["hash"]
        seen[record["hash"]] = (number, record["seq"])
        prev, expected = record["hash"], expected + 1
        result.n_records, result.head_seq, result.head_hash = expected, record["seq"], prev
    return partial, wanted


def _check_anchor(
    result: AuditVerification,
    anchor: dict[str, Any],
    wanted: dict[int, str],
    trusted: Ed25519PublicKey | None,
) -> None:
    assert result.header is not None
    result.anchor_seq = anchor["seq"]
    if anchor["header_hash"] != result.header["hash"]:
        raise BadRecordError(0, "the head anchor belongs to another log")
    if anchor["seq"] > result.head_seq:
        raise BadRecordError(
            result.head_seq + 2,
            f"the anchor says seq {anchor['seq']} was made durable, the log ends at seq "
            f"{result.head_seq}: truncated",
        )
    if wanted.get(anchor["seq"]) != anchor["hash"]:
        raise BadRecordError(
            anchor["seq"] + 1, f"record seq {anchor['seq']} differs from the anchored hash"
        )
    if anchor["closed"] and anchor["seq"] != result.head_seq:
        raise BadRecordError(anchor["seq"] + 2, "records after the anchored close record: appended")
    result.signature = signature_status(anchor, (result.header or {}).get("public_key"), trusted)


def _stopped(result: AuditVerification, partial: bool) -> str:
    """Why the log is incomplete ("" when it is closed and whole)."""
    if partial:
        return result.problem
    if not result.closed:
        return (
            f"no close record after seq {result.head_seq}: the writer stopped (crash) or is "
            "still writing"
        )
    return ""


def verify_log(
    path: Path | str,
    *,
    trusted_key: Ed25519PublicKey | None = None,
    require_anchor: bool = True,
) -> AuditVerification:
    """Verify the audit log at ``path`` and its head anchor (SR-AUD-1; outcomes: module
    docstring).

    ``trusted_key`` additionally checks who signed the anchor. ``require_anchor=False``
    verifies a log copied without its ``.head`` file as a chain alone (truncation at a record
    boundary then looks like a crash) instead of calling it UNANCHORED. Raises
    :class:`~safety.audit.log.AuditError` only when the log or its anchor cannot be read at all
    (missing, not a regular file, no permission).
    """
    log = Path(path)
    result = AuditVerification(path=log)
    try:
        mode = os.stat(log).st_mode
    except FileNotFoundError:
        raise AuditError(f"audit log {log}: no such file") from None
    except OSError as exc:
        raise AuditError(f"audit log {log}: cannot read ({exc.strerror})") from None
    if not stat.S_ISREG(mode):
        raise AuditError(f"audit log {log}: not a regular file ({file_kind(mode)})")
    try:
        anchor = read_anchor(log)
        partial, wanted = _walk(result, anchor)
        if result.header is None:
            if anchor is not None:
                raise BadRecordError(
                    1, "empty log, but the anchor says records were written: truncated"
                )
            result.status = AuditStatus.EMPTY
            result.first_bad_line = None
            result.problem = (
                "no complete record (a line without its newline): not an audit log"
                if partial
                else "empty file: not an audit log"
            )
            return result
        if anchor is not None:
            _check_anchor(result, anchor, wanted, trusted_key)
    except BadRecordError as bad:
        result.status = AuditStatus.TAMPERED
        result.first_bad_line = bad.line if bad.line > 0 else None
        result.problem = bad.problem if bad.line > 0 else f"{bad.problem} (anchor)"
        return result
    except RecordTooLongError as long:
        result.status = AuditStatus.TAMPERED
        result.first_bad_line = long.line
        result.problem = "longer than any record: edited"
        return result
    stopped = _stopped(result, partial)
    if anchor is None:
        if result.header.get("public_key") is not None:
            result.signature = "not checked (no anchor)"
        if require_anchor:
            result.status = AuditStatus.UNANCHORED
            result.first_bad_line = None
            result.problem = (
                f"head anchor {anchor_path(log).name} missing: the chain checks out, but "
                "truncation at a record boundary cannot be excluded"
                + (f"; and incomplete: {stopped}" if stopped else "")
            )
            return result
        result.notes.append("no head anchor checked: truncation at a record boundary shows")
        result.notes.append("as an incomplete log, not as tampering")
    if stopped:
        result.status = AuditStatus.INCOMPLETE
        result.problem = stopped
    return result


def iter_records(path: Path | str, upto: int) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(line number, record)`` for the complete lines 1..``upto`` of a log :func:`verify_log`
    has verified up to there, each parsed and checked again (the file may have changed since).

    Raises :class:`~safety.audit.log.AuditError` naming the line when one no longer checks.
    """
    log = Path(path)
    try:
        for number, raw, terminated in iter_lines(log):
            if number > upto or not terminated:
                return
            record = parse_record(number, raw)
            shape = structure_problem(record)
            if shape is not None:
                raise BadRecordError(number, shape)
            yield number, record
    except (BadRecordError, RecordTooLongError) as bad:
        raise AuditError(
            f"audit log {log} line {bad.line}: changed since it was verified ({bad})"
        ) from None
