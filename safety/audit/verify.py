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
"""

from __future__ import annotations

import base64
import binascii
import enum
import json
import math
import os
import re
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from safety.audit.files import FileReadError, file_kind, read_small_file
from safety.audit.keys import public_key_fingerprint
from safety.audit.log import (
    ANCHOR_KEYS,
    GENESIS,
    SCHEMA,
    AuditError,
    RecordTooLongError,
    anchor_bytes,
    anchor_message,
    anchor_path,
    canonical_json,
    iter_lines,
    record_hash,
)

__all__ = [
    "MAX_ANCHOR_BYTES",
    "MAX_DEPTH",
    "AuditStatus",
    "AuditVerification",
    "iter_records",
    "verify_log",
]

# An anchor is about 400 bytes signed.
MAX_ANCHOR_BYTES = 4096
# The deepest nesting of a record the writer produces is below 10 (configuration -> section ->
# value; inputs -> stage summary -> counters).
MAX_DEPTH = 64
_INT_LIMIT = 2**63
_HEX64 = re.compile(r"[0-9a-f]{64}")
_NONFINITE = frozenset(("nan", "inf", "-inf"))


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


class _BadRecordError(Exception):
    def __init__(self, line: int, problem: str) -> None:
        super().__init__(problem)
        self.line = line
        self.problem = problem


_KEYS = {"kind": str, "seq": int, "prev": str, "hash": str}


def _why(exc: BaseException) -> str:
    """A short reason for a JSON decoding failure (never the whole offending text)."""
    if isinstance(exc, RecursionError):
        return "nested too deeply"
    if isinstance(exc, json.JSONDecodeError):
        return f"{exc.msg} at column {exc.colno}"
    return str(exc).split(";", 1)[0][:100]


def _shape_problem(value: Any) -> str | None:
    """Nesting deeper than :data:`MAX_DEPTH` or a number no record holds (iterative: a hostile
    record must not exhaust the stack)."""
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            if depth > MAX_DEPTH:
                return f"nested deeper than {MAX_DEPTH} levels"
            children = item.values() if isinstance(item, dict) else item
            stack.extend((child, depth + 1) for child in children)
        elif isinstance(item, bool):
            continue
        elif isinstance(item, int) and not -_INT_LIMIT <= item < _INT_LIMIT:
            return "an integer beyond 64 bits"
        elif isinstance(item, float) and not math.isfinite(item):
            return "a number beyond the floating-point range"
    return None


def _parse(number: int, raw: bytes) -> dict[str, Any]:
    try:
        record = json.loads(raw.decode("ascii"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise _BadRecordError(number, f"not a JSON record ({_why(exc)}): edited") from None
    if not isinstance(record, dict):
        raise _BadRecordError(number, "not a JSON object: edited")
    for key, kind in _KEYS.items():
        if not isinstance(record.get(key), kind) or isinstance(record.get(key), bool):
            raise _BadRecordError(number, f"field {key!r} missing or not a {kind.__name__}: edited")
    shape = _shape_problem(record)
    if shape is not None:
        raise _BadRecordError(number, f"{shape}: edited")
    try:
        canonical = canonical_json(record)
    except (ValueError, RecursionError):
        canonical = b""
    if canonical != raw:
        raise _BadRecordError(number, "bytes differ from the record's canonical form: edited")
    return record


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _is_float_json(value: Any) -> bool:
    """A float as :func:`pipeline.jsoncodec.float_to_json` writes it."""
    return _is_number(value) or value in _NONFINITE


def _is_text_list(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(v, str) for v in value)


def _strict_b64(value: Any, size: int) -> bytes | None:
    """The ``size`` bytes ``value`` encodes when it is their one base64 spelling, else None."""
    if not isinstance(value, str):
        return None
    try:
        raw = base64.b64decode(value, validate=True)
    except (binascii.Error, ValueError):
        return None
    if len(raw) != size or base64.b64encode(raw).decode("ascii") != value:
        return None
    return raw


def _command_problem(value: Any) -> str | None:
    if not isinstance(value, dict) or set(value) != {"action", "speed_mps", "stamp_s", "reasons"}:
        return "not a command"
    if not isinstance(value["action"], str) or not _is_number(value["speed_mps"]):
        return "a command without its action or speed"
    if not _is_float_json(value["stamp_s"]) or not _is_text_list(value["reasons"]):
        return "a command without its stamp or reasons"
    return None


def _verdict_ok(value: Any) -> bool:
    return (
        isinstance(value, dict)
        and set(value) == {"monitor", "action", "speed_limit_mps", "reason"}
        and isinstance(value["monitor"], str)
        and isinstance(value["action"], str)
        and (value["speed_limit_mps"] is None or _is_number(value["speed_limit_mps"]))
        and isinstance(value["reason"], str)
    )


_BASE = frozenset(_KEYS)
_BODIES = {
    "header": frozenset(
        {
            "schema",
            "created_utc",
            "config_hash",
            "config",
            "model_hash",
            "latency",
            "software",
            "public_key",
        }
    ),
    "cycle": frozenset(
        {
            "stamp_s",
            "inputs",
            "observation",
            "governor_inputs",
            "governor_command",
            "verdicts",
            "command",
            "timings_s",
        }
    ),
    "close": frozenset({"n_records"}),
}


def _header_problem(r: dict[str, Any]) -> str | None:
    latency = r["latency"]
    if not isinstance(r["schema"], str) or not isinstance(r["created_utc"], str):
        return "a header without its schema or creation time"
    if not isinstance(r["config_hash"], str) or not _HEX64.fullmatch(r["config_hash"]):
        return "a header without a configuration hash"
    if not isinstance(r["config"], dict) or not isinstance(r["software"], dict):
        return "a header without its configuration or software versions"
    if r["model_hash"] is not None and not isinstance(r["model_hash"], str):
        return "a header whose model hash is not text"
    if (
        not isinstance(latency, dict)
        or set(latency) != {"perception_latency_s", "latency_source"}
        or not _is_number(latency["perception_latency_s"])
        or not isinstance(latency["latency_source"], str)
    ):
        return "a header without its latency bound"
    if r["public_key"] is not None and _strict_b64(r["public_key"], 32) is None:
        return "a header whose public key is not 32 bytes of base64"
    return None


def _cycle_problem(r: dict[str, Any]) -> str | None:
    if not _is_float_json(r["stamp_s"]):
        return "a cycle without its stamp"
    if not isinstance(r["inputs"], dict) or not isinstance(r["observation"], dict):
        return "a cycle without its inputs or observation"
    if r["governor_inputs"] is not None and not isinstance(r["governor_inputs"], dict):
        return "a cycle whose governor inputs are not a mapping"
    problem = _command_problem(r["command"])
    if problem is None and r["governor_command"] is not None:
        problem = _command_problem(r["governor_command"])
    if problem is not None:
        return f"a cycle with {problem}"
    if not isinstance(r["verdicts"], list) or not all(_verdict_ok(v) for v in r["verdicts"]):
        return "a cycle whose verdicts are not verdicts"
    timings = r["timings_s"]
    if not isinstance(timings, dict) or not all(_is_float_json(v) for v in timings.values()):
        return "a cycle whose timings are not numbers"
    return None


def _structure_problem(record: dict[str, Any]) -> str | None:
    """Why ``record`` is not what the writer writes for its kind (None: it is)."""
    kind = record["kind"]
    if kind not in _BODIES:
        return None  # reported as an unknown kind
    keys = set(record) - _BASE
    expected = _BODIES[kind]
    if keys != expected:
        missing, extra = sorted(expected - keys), sorted(keys - expected)
        parts = ([f"without {', '.join(missing)}"] if missing else []) + (
            [f"with unknown {', '.join(extra)}"] if extra else []
        )
        return f"a {kind} record {' and '.join(parts)}"
    if kind == "header":
        return _header_problem(record)
    if kind == "cycle":
        return _cycle_problem(record)
    if not isinstance(record["n_records"], int) or isinstance(record["n_records"], bool):
        return "a close record whose count is not a number"
    return None


def _read_anchor(log: Path) -> dict[str, Any] | None:
    """The anchor beside ``log`` (None when there is none), checked byte for byte."""
    path = anchor_path(log)
    if not os.path.lexists(path):
        return None

    def bad(problem: str, verdict: str = "edited") -> _BadRecordError:
        return _BadRecordError(0, f"head anchor {path.name}: {problem}: {verdict}")

    try:
        data = read_small_file(path, MAX_ANCHOR_BYTES)
    except FileReadError as exc:
        if exc.io_error:
            raise AuditError(f"head anchor {exc}") from None
        raise bad(exc.reason) from None
    try:
        anchor = json.loads(data.decode("ascii"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise bad(f"not JSON ({_why(exc)})") from None
    if not isinstance(anchor, dict):
        raise bad("not a JSON object")
    if set(anchor) != ANCHOR_KEYS:
        missing, extra = sorted(ANCHOR_KEYS - set(anchor)), sorted(set(anchor) - ANCHOR_KEYS)
        raise bad(f"keys missing {missing}, unknown {extra}"[:200])
    seq = anchor["seq"]
    if anchor["schema"] != SCHEMA:
        raise bad(f"not a {SCHEMA} anchor")
    if not all(
        isinstance(anchor[k], str) and _HEX64.fullmatch(anchor[k]) for k in ("hash", "header_hash")
    ):
        raise bad("a hash that is not 64 lower-case hex digits")
    if not isinstance(seq, int) or isinstance(seq, bool) or not 0 <= seq < _INT_LIMIT:
        raise bad("seq is not a record number")
    if not isinstance(anchor["closed"], bool):
        raise bad("closed is not true or false")
    public, signature = anchor["public_key"], anchor["signature"]
    if public is not None and signature is None:
        raise bad("names a signing key but is not signed", "signature removed")
    if public is None and signature is not None:
        raise bad("a signature without its public key")
    if public is not None and (
        _strict_b64(public, 32) is None or _strict_b64(signature, 64) is None
    ):
        raise bad("a key or signature that is not the base64 of 32 or 64 bytes")
    try:
        canonical = anchor_bytes(anchor)
    except (ValueError, RecursionError):
        canonical = b""
    if canonical != data:
        raise bad("bytes differ from the anchor's canonical form")
    return anchor


def _check_signature(
    result: AuditVerification, anchor: dict[str, Any], trusted: Ed25519PublicKey | None
) -> None:
    header_key = (result.header or {}).get("public_key")
    signature, public = anchor["signature"], anchor["public_key"]
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
        key = Ed25519PublicKey.from_public_bytes(base64.b64decode(public))
        key.verify(
            base64.b64decode(signature),
            anchor_message(anchor["header_hash"], anchor["seq"], anchor["hash"], anchor["closed"]),
        )
    except (InvalidSignature, ValueError):
        raise _BadRecordError(
            0, "the anchor's signature does not verify: anchor or chain rewritten"
        ) from None
    if trusted is not None:
        if trusted.public_bytes_raw() != key.public_bytes_raw():
            raise _BadRecordError(
                0,
                f"the anchor is signed by {public_key_fingerprint(key)}, but not by the trusted "
                f"key {public_key_fingerprint(trusted)}",
            )
        result.signature = "valid (trusted key)"
    else:
        result.signature = (
            f"valid, by {public_key_fingerprint(key)} named in the log itself: NOT a trusted key "
            "(give the trusted public key to check who signed)"
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
        shape = _structure_problem(record)
        if shape is not None:
            raise _BadRecordError(number, f"{shape}: forged (not a record safecase writes)")
        if kind == "header":
            if record["schema"] != SCHEMA:
                raise _BadRecordError(1, f"schema {record['schema'][:40]!r}, expected {SCHEMA}")
            result.header = record
        elif kind == "cycle":
            result.n_cycles += 1
        elif kind == "close":
            if record["n_records"] != expected:
                raise _BadRecordError(
                    number, "close record counts the wrong number of records: forged"
                )
            result.closed = True
        else:
            raise _BadRecordError(number, f"unknown record kind {kind[:40]!r}: edited")
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
    _check_signature(result, anchor, trusted)


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
        anchor = _read_anchor(log)
        partial, wanted = _walk(result, anchor)
        if result.header is None:
            if anchor is not None:
                raise _BadRecordError(
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
    except _BadRecordError as bad:
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
            record = _parse(number, raw)
            shape = _structure_problem(record)
            if shape is not None:
                raise _BadRecordError(number, shape)
            yield number, record
    except (_BadRecordError, RecordTooLongError) as bad:
        raise AuditError(
            f"audit log {log} line {bad.line}: changed since it was verified ({bad})"
        ) from None
