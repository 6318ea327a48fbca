"""Verification of an audit log: chain, canonical bytes, head anchor, signature (SR-AUD-1).

:func:`verify_log` streams the log once and stops at the first bad record, naming its line and
what is wrong with it:

* a line that is not a JSON record, or whose bytes differ from the record's canonical form:
  edited;
* a record whose content does not match its hash: changed;
* a record that is a copy of an earlier one: duplicated (inserted);
* a record whose ``prev`` is the hash of an earlier, non-adjacent record: the lines between
  were inserted;
* a record whose ``prev`` is not the previous record's hash: records are missing (deleted:
  its seq jumps ahead), out of order (its seq goes back) or it was replaced (same seq);
* anything after the close record, a header anywhere but line 1, a first line that is not a
  header: inserted or removed;
* the head anchor says a record was made durable that the log does not hold: truncated; the
  anchor's signature does not verify, or is missing although the header names a key: the
  anchor or the chain was rewritten.

A partial last line (no newline) or a missing close record with an intact chain is reported as
``incomplete``: what a crash mid-write leaves, distinct from tampering.
"""

from __future__ import annotations

import base64
import enum
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from safety.audit.log import (
    GENESIS,
    SCHEMA,
    AuditError,
    anchor_message,
    anchor_path,
    canonical_json,
    iter_lines,
    record_hash,
)

__all__ = ["AuditStatus", "AuditVerification", "verify_log"]


class AuditStatus(enum.Enum):
    """Outcome of :func:`verify_log`."""

    INTACT = "intact"
    INCOMPLETE = "incomplete"
    TAMPERED = "tampered"


@dataclass
class AuditVerification:
    """What :func:`verify_log` found. ``first_bad_line`` (1-based) and ``problem`` name the
    first bad record (TAMPERED) or the point where the log stops (INCOMPLETE)."""

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


class _BadRecordError(Exception):
    def __init__(self, line: int, problem: str) -> None:
        super().__init__(problem)
        self.line = line
        self.problem = problem


_KEYS = {"kind": str, "seq": int, "prev": str, "hash": str}


def _parse(number: int, raw: bytes) -> dict[str, Any]:
    try:
        record = json.loads(raw.decode("ascii"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _BadRecordError(number, f"not a JSON record ({exc}): edited") from None
    if not isinstance(record, dict):
        raise _BadRecordError(number, "not a JSON object: edited")
    for key, kind in _KEYS.items():
        if not isinstance(record.get(key), kind) or isinstance(record.get(key), bool):
            raise _BadRecordError(number, f"field {key!r} missing or not a {kind.__name__}: edited")
    try:
        canonical = canonical_json(record)
    except ValueError:
        canonical = b""
    if canonical != raw:
        raise _BadRecordError(number, "bytes differ from the record's canonical form: edited")
    return record


def _read_anchor(log: Path) -> dict[str, Any] | None:
    path = anchor_path(log)
    if not path.exists():
        return None
    try:
        anchor = json.loads(path.read_bytes())
        if not isinstance(anchor, dict) or anchor.get("schema") != SCHEMA:
            raise ValueError("not a safecase-audit/1 anchor")
        for key, kind in (("seq", int), ("hash", str), ("header_hash", str), ("closed", bool)):
            if not isinstance(anchor.get(key), kind):
                raise ValueError(f"field {key!r} missing")
    except ValueError as exc:
        raise _BadRecordError(0, f"head anchor {path.name} unreadable ({exc}): edited") from None
    return anchor


def _check_signature(
    result: AuditVerification, anchor: dict[str, Any], trusted: Ed25519PublicKey | None
) -> None:
    header_key = (result.header or {}).get("public_key")
    signature, public = anchor.get("signature"), anchor.get("public_key")
    if signature is None:
        if header_key is not None:
            raise _BadRecordError(0, "the header names a signing key but the anchor is not signed")
        if trusted is not None:
            raise _BadRecordError(0, "a trusted key was given but the anchor is not signed")
        result.signature = "absent"
        return
    if public != header_key:
        raise _BadRecordError(0, "the anchor is signed with a key other than the header's")
    try:
        key = Ed25519PublicKey.from_public_bytes(base64.b64decode(str(public)))
        key.verify(
            base64.b64decode(str(signature)),
            anchor_message(anchor["header_hash"], anchor["seq"], anchor["hash"], anchor["closed"]),
        )
    except (InvalidSignature, ValueError):
        raise _BadRecordError(
            0, "the anchor's signature does not verify: anchor or chain rewritten"
        ) from None
    if trusted is not None:
        if trusted.public_bytes_raw() != key.public_bytes_raw():
            raise _BadRecordError(0, "the anchor is signed, but not by the trusted key")
        result.signature = "valid (trusted key)"
    else:
        result.signature = "valid (key in the header; pass a trusted key to check who signed)"


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
                raise _BadRecordError(number, "bytes after the close record: appended")
            partial = True
            result.first_bad_line = number
            result.problem = f"partial last line ({len(raw)} bytes): the writer stopped mid-write"
            break
        if result.closed:
            raise _BadRecordError(number, "record after the close record: appended")
        record = _parse(number, raw)
        body = {k: v for k, v in record.items() if k != "hash"}
        if record_hash(record["prev"], body) != record["hash"]:
            raise _BadRecordError(number, "content does not match its hash: changed")
        if record["hash"] in seen:
            raise _BadRecordError(number, f"copy of line {seen[record['hash']][0]}: inserted")
        kind = record["kind"]
        if number == 1 and (kind != "header" or record["seq"] != 0 or record["prev"] != GENESIS):
            raise _BadRecordError(
                1, "the first record is not the header: header removed or replaced"
            )
        if number > 1 and kind == "header":
            raise _BadRecordError(number, "a second header: inserted")
        if record["prev"] != prev:
            raise _BadRecordError(*_link_problem(record, expected, seen, number))
        if record["seq"] != expected:
            raise _BadRecordError(number, f"seq {record['seq']} where {expected} was due: forged")
        if kind == "header":
            if record.get("schema") != SCHEMA:
                raise _BadRecordError(1, f"schema {record.get('schema')!r}, expected {SCHEMA}")
            result.header = record
        elif kind == "cycle":
            result.n_cycles += 1
        elif kind == "close":
            if record.get("n_records") != expected:
                raise _BadRecordError(
                    number, "close record counts the wrong number of records: forged"
                )
            result.closed = True
        else:
            raise _BadRecordError(number, f"unknown record kind {kind!r}: edited")
        if record["seq"] in wanted:
            wanted[record["seq"]] = record["hash"]
        seen[record["hash"]] = (number, record["seq"])
        prev, expected = record["hash"], expected + 1
        result.n_records, result.head_seq, result.head_hash = expected, record["seq"], prev
    return partial, wanted


def verify_log(
    path: Path | str,
    *,
    trusted_key: Ed25519PublicKey | None = None,
    require_anchor: bool = True,
) -> AuditVerification:
    """Verify the audit log at ``path`` and its head anchor (SR-AUD-1).

    ``trusted_key`` additionally checks who signed the anchor. ``require_anchor=False``
    verifies a log copied without its ``.head`` file (truncation at a record boundary then
    looks like a crash). Raises :class:`~safety.audit.log.AuditError` only when the file cannot be
    read at all.
    """
    log = Path(path)
    result = AuditVerification(path=log)
    if not log.is_file():
        raise AuditError(f"audit log {log}: no such file")
    try:
        anchor = _read_anchor(log)
        if anchor is None and require_anchor:
            raise _BadRecordError(0, f"head anchor {anchor_path(log).name} missing: removed")
        partial, wanted = _walk(result, anchor)
        if result.header is None:
            if anchor is not None:
                raise _BadRecordError(
                    1, "empty log, but the anchor says records were written: truncated"
                )
            result.status = AuditStatus.INCOMPLETE
            result.problem = result.problem or "empty log: the writer stopped before the header"
            return result
        if anchor is not None:
            result.anchor_seq = anchor["seq"]
            if anchor["header_hash"] != result.header["hash"]:
                raise _BadRecordError(0, "the head anchor belongs to another log")
            if anchor["seq"] > result.head_seq:
                raise _BadRecordError(
                    result.head_seq + 2,
                    f"the anchor says seq {anchor['seq']} was made durable, the log ends at seq "
                    f"{result.head_seq}: truncated",
                )
            if wanted.get(anchor["seq"]) != anchor["hash"]:
                raise _BadRecordError(
                    anchor["seq"] + 1, f"record seq {anchor['seq']} differs from the anchored hash"
                )
            if anchor["closed"] and anchor["seq"] != result.head_seq:
                raise _BadRecordError(
                    anchor["seq"] + 2, "records after the anchored close record: appended"
                )
            _check_signature(result, anchor, trusted_key)
        else:
            result.notes.append("no head anchor checked: truncation at a record boundary shows")
            result.notes.append("as an incomplete log, not as tampering")
    except _BadRecordError as bad:
        result.status = AuditStatus.TAMPERED
        result.first_bad_line = bad.line if bad.line > 0 else None
        result.problem = bad.problem if bad.line > 0 else f"{bad.problem} (anchor)"
        return result
    if partial:
        result.status = AuditStatus.INCOMPLETE
    elif not result.closed:
        result.status = AuditStatus.INCOMPLETE
        result.problem = (
            f"no close record after seq {result.head_seq}: the writer stopped (crash) or is "
            "still writing"
        )
    return result
