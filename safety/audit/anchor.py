"""The head anchor beside an audit log, read and checked byte for byte, and its signature
(SR-AUD-1).

:func:`read_anchor` returns the anchor (``LOG.head``) when it is the canonical form of exactly
its known keys, with hashes, record number, key and signature of the right shape;
:func:`signature_status` checks its Ed25519 signature against the key the log's header names
and, when given, a trusted key. Both raise :class:`~safety.audit.records.BadRecordError` (line
0: the anchor) saying what was edited, removed or rewritten.
"""

from __future__ import annotations

import base64
import json
import os
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from safety.audit.files import FileReadError, read_small_file
from safety.audit.keys import public_key_fingerprint
from safety.audit.log import (
    ANCHOR_KEYS,
    SCHEMA,
    AuditError,
    anchor_bytes,
    anchor_message,
    anchor_path,
)
from safety.audit.records import HEX64, INT_LIMIT, BadRecordError, json_problem, strict_b64

__all__ = ["MAX_ANCHOR_BYTES", "read_anchor", "signature_status"]

# An anchor is about 400 bytes signed.
MAX_ANCHOR_BYTES = 4096


def read_anchor(log: Path) -> dict[str, Any] | None:
    """The anchor beside ``log`` (None when there is none), checked byte for byte."""
    path = anchor_path(log)
    if not os.path.lexists(path):
        return None

    def bad(problem: str, verdict: str = "edited") -> BadRecordError:
        return BadRecordError(0, f"head anchor {path.name}: {problem}: {verdict}")

    try:
        data = read_small_file(path, MAX_ANCHOR_BYTES)
    except FileReadError as exc:
        if exc.io_error:
            raise AuditError(f"head anchor {exc}") from None
        raise bad(exc.reason) from None
    try:
        anchor = json.loads(data.decode("ascii"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise bad(f"not JSON ({json_problem(exc)})") from None
    if not isinstance(anchor, dict):
        raise bad("not a JSON object")
    if set(anchor) != ANCHOR_KEYS:
        missing, extra = sorted(ANCHOR_KEYS - set(anchor)), sorted(set(anchor) - ANCHOR_KEYS)
        raise bad(f"keys missing {missing}, unknown {extra}"[:200])
    seq = anchor["seq"]
    if anchor["schema"] != SCHEMA:
        raise bad(f"not a {SCHEMA} anchor")
    if not all(
        isinstance(anchor[k], str) and HEX64.fullmatch(anchor[k]) for k in ("hash", "header_hash")
    ):
        raise bad("a hash that is not 64 lower-case hex digits")
    if not isinstance(seq, int) or isinstance(seq, bool) or not 0 <= seq < INT_LIMIT:
        raise bad("seq is not a record number")
    if not isinstance(anchor["closed"], bool):
        raise bad("closed is not true or false")
    public, signature = anchor["public_key"], anchor["signature"]
    if public is not None and signature is None:
        raise bad("names a signing key but is not signed", "signature removed")
    if public is None and signature is not None:
        raise bad("a signature without its public key")
    if public is not None and (strict_b64(public, 32) is None or strict_b64(signature, 64) is None):
        raise bad("a key or signature that is not the base64 of 32 or 64 bytes")
    try:
        canonical = anchor_bytes(anchor)
    except (ValueError, RecursionError):
        canonical = b""
    if canonical != data:
        raise bad("bytes differ from the anchor's canonical form")
    return anchor


def signature_status(
    anchor: dict[str, Any], header_key: str | None, trusted: Ed25519PublicKey | None
) -> str:
    """What the anchor's signature says, as :attr:`AuditVerification.signature` reports it:
    ``absent``, ``valid (trusted key)`` or valid by a key the log itself names. ``header_key``
    is the base64 public key the log's header names (None: none)."""
    signature, public = anchor["signature"], anchor["public_key"]
    if signature is None:
        if header_key is not None:
            raise BadRecordError(0, "the header names a signing key but the anchor is not signed")
        if trusted is not None:
            raise BadRecordError(0, "a trusted key was given but the anchor is not signed")
        return "absent"
    if public != header_key:
        raise BadRecordError(0, "the anchor is signed with a key other than the header's")
    try:
        key = Ed25519PublicKey.from_public_bytes(base64.b64decode(public))
        key.verify(
            base64.b64decode(signature),
            anchor_message(anchor["header_hash"], anchor["seq"], anchor["hash"], anchor["closed"]),
        )
    except (InvalidSignature, ValueError):
        raise BadRecordError(
            0, "the anchor's signature does not verify: anchor or chain rewritten"
        ) from None
    if trusted is None:
        return (
            f"valid, by {public_key_fingerprint(key)} named in the log itself: NOT a trusted key "
            "(give the trusted public key to check who signed)"
        )
    if trusted.public_bytes_raw() != key.public_bytes_raw():
        raise BadRecordError(
            0,
            f"the anchor is signed by {public_key_fingerprint(key)}, but not by the trusted "
            f"key {public_key_fingerprint(trusted)}",
        )
    return "valid (trusted key)"
