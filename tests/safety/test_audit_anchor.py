"""The head anchor read on its own: each way it can be wrong gets its own words (SR-AUD-1).

:func:`~safety.audit.anchor.read_anchor` is the first thing ``audit verify`` trusts; the
end-to-end tests (tests/safety/test_audit*.py) check that a bad anchor makes a log TAMPERED.
Here each check is met alone, by an anchor that passes every other one and is written in its
canonical bytes, so a check that is dropped or turned round is seen even where a later check
would have caught the same file for another reason.
"""

from __future__ import annotations

import base64
import os
from pathlib import Path
from typing import Any

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from safety.audit.anchor import MAX_ANCHOR_BYTES, read_anchor, signature_status
from safety.audit.keys import public_key_fingerprint
from safety.audit.log import SCHEMA, AuditError, anchor_bytes, anchor_message, anchor_path
from safety.audit.records import BadRecordError

CODE = ["safety/audit/anchor.py"]
HEAD = "ab" * 32
HEADER = "cd" * 32


def _anchor(**changes: Any) -> dict[str, Any]:
    """A valid unsigned anchor of record 7, with ``changes``."""
    anchor: dict[str, Any] = {
        "schema": SCHEMA,
        "header_hash": HEADER,
        "seq": 7,
        "hash": HEAD,
        "closed": True,
        "public_key": None,
        "signature": None,
    }
    return anchor | changes


def _signed(key: Ed25519PrivateKey, **changes: Any) -> dict[str, Any]:
    """A valid anchor signed by ``key``, with ``changes`` made after signing."""
    anchor = _anchor()
    message = anchor_message(HEADER, 7, HEAD, True)
    anchor["public_key"] = _b64(key.public_key().public_bytes_raw())
    anchor["signature"] = _b64(key.sign(message))
    return anchor | changes


def _b64(raw: bytes) -> str:
    return base64.b64encode(raw).decode("ascii")


def _write(tmp_path: Path, data: bytes) -> Path:
    log = tmp_path / "run.log"
    anchor_path(log).write_bytes(data)
    return log


def _refused(log: Path) -> str:
    with pytest.raises(BadRecordError) as caught:
        read_anchor(log)
    assert caught.value.line == 0
    return caught.value.problem


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_canonical_anchor_reads_back_and_none_is_none(tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    assert read_anchor(log) is None
    anchor = _anchor(seq=0, closed=False)
    _write(tmp_path, anchor_bytes(anchor))
    assert read_anchor(log) == anchor
    key = Ed25519PrivateKey.generate()
    _write(tmp_path, anchor_bytes(_signed(key)))
    assert read_anchor(log) == _signed(key)


CASES: dict[str, tuple[Any, str]] = {
    "a list": (["schema"], "not a JSON object: edited"),
    "a key missing": (
        {k: v for k, v in _anchor().items() if k != "closed"},
        "keys missing ['closed'], unknown []: edited",
    ),
    "a key added": (_anchor(note=1), "keys missing [], unknown ['note']: edited"),
    "another schema": (_anchor(schema="safecase-audit/2"), f"not a {SCHEMA} anchor: edited"),
    "a short hash": (
        _anchor(hash=HEAD[:-1]),
        "a hash that is not 64 lower-case hex digits: edited",
    ),
    "a header hash not hex": (
        _anchor(header_hash="g" * 64),
        "a hash that is not 64 lower-case hex digits: edited",
    ),
    "a hash that is a number": (
        _anchor(hash=1),
        "a hash that is not 64 lower-case hex digits: edited",
    ),
    "seq a string": (_anchor(seq="7"), "seq is not a record number: edited"),
    "seq true": (_anchor(seq=True), "seq is not a record number: edited"),
    "seq negative": (_anchor(seq=-1), "seq is not a record number: edited"),
    "seq 2^63": (_anchor(seq=2**63), "seq is not a record number: edited"),
    "closed 1": (_anchor(closed=1), "closed is not true or false: edited"),
    "closed null": (_anchor(closed=None), "closed is not true or false: edited"),
    "a signature without a key": (
        _anchor(signature=_b64(bytes(64))),
        "a signature without its public key: edited",
    ),
    "a key without a signature": (
        _anchor(public_key=_b64(bytes(32))),
        "names a signing key but is not signed: signature removed",
    ),
    "a key of 31 bytes": (
        _anchor(public_key=_b64(bytes(31)), signature=_b64(bytes(64))),
        "a key or signature that is not the base64 of 32 or 64 bytes: edited",
    ),
    "a signature of 63 bytes": (
        _anchor(public_key=_b64(bytes(32)), signature=_b64(bytes(63))),
        "a key or signature that is not the base64 of 32 or 64 bytes: edited",
    ),
}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
@pytest.mark.parametrize("case", sorted(CASES))
def test_each_check_of_the_anchor_names_what_is_wrong(tmp_path: Path, case: str) -> None:
    value, reason = CASES[case]
    log = _write(tmp_path, anchor_bytes(value))
    assert _refused(log) == f"head anchor run.log.head: {reason}"


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_largest_record_number_is_one_below_the_limit(tmp_path: Path) -> None:
    largest = _anchor(seq=2**63 - 1)
    log = _write(tmp_path, anchor_bytes(largest))
    assert read_anchor(log) == largest


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"\xff{}\n", "not JSON ('ascii' codec can't decode byte 0xff in position 0"),
        (b"{\n", "not JSON ("),
        (anchor_bytes(_anchor())[:-1], "bytes differ from the anchor's canonical form: edited"),
        (b" " + anchor_bytes(_anchor()), "bytes differ from the anchor's canonical form: edited"),
        (
            b"x" * (MAX_ANCHOR_BYTES + 1),
            f"{MAX_ANCHOR_BYTES + 1} bytes; at most {MAX_ANCHOR_BYTES} bytes",
        ),
        (b"x" * MAX_ANCHOR_BYTES, "not JSON ("),
    ],
)
def test_bytes_that_are_not_the_canonical_anchor_are_edited(
    tmp_path: Path, data: bytes, reason: str
) -> None:
    log = _write(tmp_path, data)
    refused = _refused(log)
    assert refused.startswith("head anchor run.log.head: "), refused
    assert reason in refused, refused
    assert refused.endswith(": edited"), refused


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_an_anchor_the_system_cannot_open_is_an_error_not_a_verdict(tmp_path: Path) -> None:
    """A directory where the anchor should be is an edit; a link that loops onto itself is
    a file the operating system refuses to open, which says nothing about the log."""
    log = tmp_path / "run.log"
    anchor_path(log).mkdir()
    assert _refused(log) == "head anchor run.log.head: not a regular file (a directory): edited"
    anchor_path(log).rmdir()
    os.symlink(anchor_path(log).name, anchor_path(log))
    with pytest.raises(
        AuditError, match=r"^head anchor .*run\.log\.head: cannot open \("
    ) as caught:
        read_anchor(log)
    assert not isinstance(caught.value, BadRecordError)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_signature_status_of_each_kind_of_anchor() -> None:
    key, other = Ed25519PrivateKey.generate(), Ed25519PrivateKey.generate()
    signed = _signed(key)
    public = signed["public_key"]
    fingerprint = public_key_fingerprint(key.public_key())
    assert signature_status(_anchor(), None, None) == "absent"
    assert signature_status(signed, public, key.public_key()) == "valid (trusted key)"
    assert signature_status(signed, public, None) == (
        f"valid, by {fingerprint} named in the log itself: NOT a trusted key (give the trusted "
        "public key to check who signed)"
    )
    refusals = [
        (_anchor(), public, None, "the header names a signing key but the anchor is not signed"),
        (_anchor(), None, key.public_key(), "a trusted key was given but the anchor is not signed"),
        (signed, None, None, "the anchor is signed with a key other than the header's"),
        (
            _signed(key, seq=8),
            public,
            None,
            "the anchor's signature does not verify: anchor or chain rewritten",
        ),
        (
            _signed(key, closed=False),
            public,
            None,
            "the anchor's signature does not verify: anchor or chain rewritten",
        ),
        (
            signed,
            public,
            other.public_key(),
            f"the anchor is signed by {fingerprint}, but not by the trusted key "
            f"{public_key_fingerprint(other.public_key())}",
        ),
    ]
    for anchor, header_key, trusted, reason in refusals:
        with pytest.raises(BadRecordError) as caught:
            signature_status(anchor, header_key, trusted)
        assert (caught.value.line, caught.value.problem) == (0, reason)
