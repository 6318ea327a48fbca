"""What ``audit verify`` says of each kind of edit, read whole (SR-AUD-1).

The property tests (properties/test_audit.py) make random edits and check that the verdict is
TAMPERED at a line the edit explains. Here each check of :mod:`safety.audit.verify` is met by
one edit that passes every earlier check (hashes recomputed where the edit is a forgery that
knows the hash function), and the line and the sentence are compared whole: what the reader is
told is where to look and what happened there.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from pipeline.config import default_config
from properties.audit_cases import write_random_log
from safety.audit.log import (
    GENESIS,
    MAX_RECORD_BYTES,
    AuditError,
    anchor_bytes,
    anchor_path,
    canonical_json,
    record_hash,
)
from safety.audit.verify import AuditStatus, AuditVerification, iter_records, verify_log

CODE = ["safety/audit/verify.py"]
OTHER = "11" * 32


def _log(tmp_path: Path, *, close: bool = True, key: Ed25519PrivateKey | None = None) -> Path:
    """Header, four cycles and (``close``) the close record: seq 0..5 on lines 1..6."""
    log = tmp_path / "run.log"
    write_random_log(log, default_config(), np.random.default_rng(11), 4, close=close, key=key)
    return log


def _records(log: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in log.read_bytes().splitlines()]


def _sealed(record: dict[str, Any], prev: str) -> dict[str, Any]:
    body = {k: v for k, v in record.items() if k != "hash"} | {"prev": prev}
    return body | {"hash": record_hash(prev, body)}


def _rechain(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records with every ``prev`` and ``hash`` recomputed: a forger who knows the hash."""
    prev, out = GENESIS, []
    for record in records:
        sealed = _sealed(record, prev)
        out.append(sealed)
        prev = sealed["hash"]
    return out


def _write(log: Path, records: list[dict[str, Any]], tail: bytes = b"") -> None:
    log.write_bytes(b"".join(canonical_json(r) + b"\n" for r in records) + tail)


def _verdict(log: Path, **kw: Any) -> tuple[AuditStatus, int | None, str]:
    result = verify_log(log, **kw)
    return result.status, result.first_bad_line, result.problem


TAMPERED = AuditStatus.TAMPERED


def test_an_intact_log_describes_itself_in_one_line(tmp_path: Path) -> None:
    log = _log(tmp_path)
    result = verify_log(log)
    assert (result.status, result.first_bad_line, result.problem) == (AuditStatus.INTACT, None, "")
    assert (result.n_records, result.n_cycles, result.closed, result.head_seq) == (6, 4, True, 5)
    assert result.head_hash == _records(log)[-1]["hash"]
    assert result.anchor_seq == 5
    assert result.header == _records(log)[0]
    assert result.describe() == "INTACT (6 records, 4 cycles, head seq 5, signature absent)"
    assert result.ok
    stopped = AuditVerification(log, AuditStatus.INCOMPLETE, 3, "why", 2, 1, False, 1)
    assert (
        stopped.describe() == "INCOMPLETE at line 3: why (2 records, 1 cycles, head seq 1, "
        "signature absent)"
    )
    assert not stopped.ok


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_forged_records_with_correct_hashes_are_named(tmp_path: Path) -> None:
    log = _log(tmp_path)
    anchor_path(log).unlink()
    header, *cycles, close = _records(log)
    forgeries: dict[str, tuple[list[dict[str, Any]], int, str]] = {
        "second header": (
            [header, cycles[0], header | {"seq": 2}, *cycles[1:], close],
            3,
            "a second header: inserted",
        ),
        "second header first": (
            [header, header | {"seq": 1}, *cycles[1:], close],
            2,
            "a second header: inserted",
        ),
        "seq": (
            [header, cycles[0], cycles[1] | {"seq": 7}, *cycles[2:], close],
            3,
            "seq 7 where 2 was due: forged",
        ),
        "kind": (
            [header, cycles[0], cycles[1] | {"kind": "note"}, *cycles[2:], close],
            3,
            "unknown record kind 'note': edited",
        ),
        "structure": (
            [header, {k: v for k, v in cycles[0].items() if k != "inputs"}, *cycles[1:], close],
            2,
            "a cycle record without inputs: forged (not a record safecase writes)",
        ),
        "schema": (
            [header | {"schema": "safecase-audit/9"}, *cycles, close],
            1,
            "schema 'safecase-audit/9', expected safecase-audit/1",
        ),
        "long schema": (
            [header | {"schema": "s" * 50}, *cycles, close],
            1,
            f"schema {'s' * 40!r}, expected safecase-audit/1",
        ),
        "long kind": (
            [header, cycles[0] | {"kind": "k" * 50}, *cycles[1:], close],
            2,
            f"unknown record kind {'k' * 40!r}: edited",
        ),
        "count": (
            [header, *cycles, close | {"n_records": 4}],
            6,
            "close record counts the wrong number of records: forged",
        ),
        "no header": (
            [c | {"seq": i} for i, c in enumerate(cycles)],
            1,
            "the first record is not the header: header removed or replaced",
        ),
        "header seq": (
            [header | {"seq": 1}, *cycles, close],
            1,
            "the first record is not the header: header removed or replaced",
        ),
    }
    for name, (records, line, problem) in forgeries.items():
        _write(log, _rechain(records))
        assert _verdict(log, require_anchor=False) == (TAMPERED, line, problem), name
    # A header that does not start from the genesis hash.
    _write(log, [_sealed(header, OTHER)])
    assert _verdict(log, require_anchor=False) == (
        TAMPERED,
        1,
        "the first record is not the header: header removed or replaced",
    )


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_broken_links_say_what_was_inserted_deleted_reordered_or_replaced(tmp_path: Path) -> None:
    log = _log(tmp_path)
    anchor_path(log).unlink()
    records = _records(log)
    r = records
    inserted = _sealed(r[3] | {"inputs": {"edited": 1}}, r[2]["hash"])
    stray = _sealed(r[2] | {"inputs": {"edited": 1}}, OTHER)
    replaced = _sealed(r[2] | {"inputs": {"edited": 1}}, r[1]["hash"])
    edits: dict[str, tuple[list[dict[str, Any]], int, str]] = {
        "inserted": (
            [*r[:3], inserted, *r[3:]],
            4,
            "line 5 (seq 3) links to line 3: lines 4..4 were inserted",
        ),
        "deleted": ([*r[:2], *r[3:]], 3, "records seq 2..2 missing: deleted (or reordered)"),
        "reordered": ([*r[:4], stray], 5, "seq 2 where 4 was due: records reordered"),
        "replaced": (
            [*r[:2], replaced, *r[3:]],
            3,
            "line 4 does not chain to line 3: one was replaced",
        ),
        "copied": ([*r[:3], r[2], *r[3:]], 4, "copy of line 3: inserted"),
        "changed": (
            [*r[:2], r[2] | {"stamp_s": -1.0}, *r[3:]],
            3,
            "content does not match its hash: changed",
        ),
    }
    for name, (edited, line, problem) in edits.items():
        _write(log, edited)
        assert _verdict(log, require_anchor=False) == (TAMPERED, line, problem), name


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_anything_after_the_close_record_is_appended(tmp_path: Path) -> None:
    log = _log(tmp_path)
    records = _records(log)
    after = _sealed(records[1] | {"seq": 6}, records[-1]["hash"])
    _write(log, [*records, after])
    assert _verdict(log) == (TAMPERED, 7, "record after the close record: appended")
    _write(log, records, b"{")
    assert _verdict(log) == (TAMPERED, 7, "bytes after the close record: appended")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_log_that_stops_is_incomplete_and_says_where(tmp_path: Path) -> None:
    log = _log(tmp_path, close=False)
    records = _records(log)
    assert _verdict(log) == (
        AuditStatus.INCOMPLETE,
        None,
        "no close record after seq 4: the writer stopped (crash) or is still writing",
    )
    _write(log, records, b'{"kind":')
    assert _verdict(log) == (
        AuditStatus.INCOMPLETE,
        6,
        "partial last line (8 bytes): the writer stopped mid-write",
    )
    anchor_path(log).unlink()
    assert _verdict(log) == (
        AuditStatus.UNANCHORED,
        None,
        "head anchor run.log.head missing: the chain checks out, but truncation at a record "
        "boundary cannot be excluded; and incomplete: partial last line (8 bytes): the writer "
        "stopped mid-write",
    )
    result = verify_log(log, require_anchor=False)
    assert (result.status, result.first_bad_line) == (AuditStatus.INCOMPLETE, 6)
    assert result.notes == [
        "no head anchor checked: truncation at a record boundary shows",
        "as an incomplete log, not as tampering",
    ]
    log.write_bytes(b'{"kind":')
    assert _verdict(log) == (
        AuditStatus.EMPTY,
        None,
        "no complete record (a line without its newline): not an audit log",
    )
    log.write_bytes(b"")
    assert _verdict(log) == (AuditStatus.EMPTY, None, "empty file: not an audit log")
    # With an anchor that says records were made durable, an empty log was truncated.
    (tmp_path / "anchored").mkdir()
    anchored = _log(tmp_path / "anchored")
    anchored.write_bytes(b"")
    assert _verdict(anchored) == (
        TAMPERED,
        1,
        "empty log, but the anchor says records were written: truncated",
    )


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_an_anchor_that_does_not_match_the_log_is_named(tmp_path: Path) -> None:
    log = _log(tmp_path)
    head = anchor_path(log)
    anchor = json.loads(head.read_bytes())
    records = _records(log)
    cases = {
        "another log": (
            anchor | {"header_hash": OTHER},
            None,
            "the head anchor belongs to another log (anchor)",
        ),
        "truncated": (
            anchor | {"seq": 9},
            7,
            "the anchor says seq 9 was made durable, the log ends at seq 5: truncated",
        ),
        "other hash": (anchor | {"hash": OTHER}, 6, "record seq 5 differs from the anchored hash"),
        "closed early": (
            anchor | {"seq": 3, "hash": records[3]["hash"]},
            5,
            "records after the anchored close record: appended",
        ),
    }
    for name, (edited, line, problem) in cases.items():
        head.write_bytes(anchor_bytes(edited))
        assert _verdict(log) == (TAMPERED, line, problem), name
    # An open anchor of an earlier record is what a run that is still writing leaves.
    head.write_bytes(anchor_bytes(anchor | {"seq": 3, "hash": records[3]["hash"], "closed": False}))
    result = verify_log(log)
    assert (result.status, result.anchor_seq) == (AuditStatus.INTACT, 3)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_signed_log_without_its_anchor_says_the_signature_was_not_checked(
    tmp_path: Path,
) -> None:
    log = _log(tmp_path, key=Ed25519PrivateKey.generate())
    assert verify_log(log).signature.startswith("valid, by sha256:")
    anchor_path(log).unlink()
    result = verify_log(log)
    assert (result.status, result.signature) == (AuditStatus.UNANCHORED, "not checked (no anchor)")
    assert result.problem == (
        "head anchor run.log.head missing: the chain checks out, but truncation at a record "
        "boundary cannot be excluded"
    )
    assert verify_log(log, require_anchor=False).status is AuditStatus.INTACT


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_path_that_is_no_log_is_an_error_naming_it(tmp_path: Path) -> None:
    with pytest.raises(AuditError, match=r"^audit log .*missing\.log: no such file$"):
        verify_log(tmp_path / "missing.log")
    with pytest.raises(
        AuditError, match=rf"^audit log {tmp_path}: not a regular file \(a directory\)$"
    ):
        verify_log(tmp_path)
    loop = tmp_path / "loop.log"
    loop.symlink_to(loop.name)
    with pytest.raises(AuditError, match=r"^audit log .*loop\.log: cannot read \("):
        verify_log(loop)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_line_longer_than_any_record_is_an_edit_at_that_line(tmp_path: Path) -> None:
    log = _log(tmp_path)
    with log.open("ab") as handle:
        handle.write(b"x" * (MAX_RECORD_BYTES + 1))
    assert _verdict(log) == (TAMPERED, 7, "longer than any record: edited")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_records_are_read_again_up_to_a_line_and_a_change_since_is_an_error(
    tmp_path: Path,
) -> None:
    log = _log(tmp_path, close=False)
    records = _records(log)
    assert [n for n, _ in iter_records(log, 3)] == [1, 2, 3]
    assert [r for _, r in iter_records(log, 99)] == records
    _write(log, records, b"{")
    assert len(list(iter_records(log, 99))) == 5
    _write(log, [*records[:2], records[2] | {"inputs": []}])
    with pytest.raises(AuditError) as caught:
        list(iter_records(log, 3))
    assert str(caught.value) == (
        f"audit log {log} line 3: changed since it was verified (a cycle without its inputs or "
        "observation)"
    )
    os.truncate(log, 0)
    with log.open("ab") as handle:
        handle.write(b" " + canonical_json(records[0]) + b"\n")
    with pytest.raises(AuditError, match=r"line 1: changed since it was verified \(bytes differ"):
        list(iter_records(log, 1))
