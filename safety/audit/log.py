"""Tamper-evident audit log: one hash-chained JSON line per runtime cycle (SR-AUD-1, SR-AUD-2).

Format (``safecase-audit/1``)
-----------------------------
A JSON Lines file. Every line is the canonical JSON (sorted keys, no spaces, ASCII, no NaN) of
one record with ``kind``, ``seq`` (0, 1, 2, ... without gaps), ``prev`` (the previous
record's hash; 64 zeros for the first) and ``hash = SHA-256(prev + canonical JSON of the
record without "hash")``, hex. Line 1 is the ``header``: schema, configuration (every value)
and its hash, the classifier model hash, the latency bound the stopping model used, and the
public key when the head is signed. Then one ``cycle`` record per runtime cycle (what came in,
the monitors' observation, the governor's inputs and command, every verdict, the final
command, per-stage timings; :class:`CycleRecord`), and a ``close`` record when the writer shut
down cleanly.

The writer fsyncs every ``audit.fsync_every_records`` records and then rewrites the *head
anchor* ``LOG.head`` (atomically): one line, the canonical JSON of exactly the keys
:data:`ANCHOR_KEYS` (the last durable record's seq and hash, the header's hash, whether the log
is closed, and the public key and Ed25519 signature, both null when unsigned). With
``audit.sign_head`` the anchor is signed (:func:`signing_key_for`). The chain makes any change,
insertion, deletion or reordering visible at the first affected line; the anchor makes
truncation of durable records visible; the signature, checked against a trusted key, makes a
rewritten chain (with a rewritten anchor) visible. What no log can show: records written after
the last anchor and lost with the tail, which is exactly what a crash loses too.
:func:`safety.audit.verify.verify_log` reports the outcomes (``intact``, ``incomplete``,
``unanchored``, ``empty``, ``tampered``) with the first bad line and the reason.
"""

from __future__ import annotations

import base64
import hashlib
import os
import queue
import threading
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from importlib import metadata
from pathlib import Path
from types import TracebackType
from typing import Any

from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from pipeline.compat import UTC
from pipeline.config import AuditSection, SafecaseConfig, config_hash
from pipeline.errors import SafecaseError
from pipeline.jsoncodec import dumps, jsonable
from safety.audit.files import FileReadError, open_regular
from safety.audit.keys import load_or_create_key, load_private_key, raw_public_key
from safety.model.decision import Decision, GovernorInputs, command_to_dict
from safety.model.monitors import Observation
from safety.model.stopping import StoppingParams

__all__ = [
    "ANCHOR_KEYS",
    "GENESIS",
    "MAX_RECORD_BYTES",
    "SCHEMA",
    "AuditError",
    "AuditWriter",
    "BackgroundAuditWriter",
    "CycleRecord",
    "RecordTooLongError",
    "anchor_bytes",
    "anchor_message",
    "anchor_path",
    "canonical_json",
    "iter_lines",
    "record_hash",
    "signing_key_for",
    "summarize",
]

SCHEMA = "safecase-audit/1"
GENESIS = "0" * 64
# The keys of a head anchor, no more, no fewer.
ANCHOR_KEYS = frozenset(
    ("schema", "header_hash", "seq", "hash", "closed", "public_key", "signature")
)
# The longest record a reader accepts [bytes]. A cycle record is a few kB; 10 000 obstacles
# (geometry.max_obstacles at its bound) make about 1 MB.
MAX_RECORD_BYTES = 16 * 1024 * 1024


class AuditError(SafecaseError):
    """An audit log that cannot be written or read (exists already, unreadable, not a log)."""


class RecordTooLongError(AuditError):
    """A line longer than :data:`MAX_RECORD_BYTES`: no record the writer writes. ``line`` is
    its 1-based number."""

    def __init__(self, path: Path, line: int) -> None:
        super().__init__(f"audit log {path}: line {line} is longer than {MAX_RECORD_BYTES} bytes")
        self.line = line


def canonical_json(value: Any) -> bytes:
    """The one byte form of a record: sorted keys, no whitespace, ASCII, finite numbers only."""
    return dumps(value).encode("ascii")


def record_hash(prev: str, body: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of the previous hash followed by the canonical JSON of ``body``."""
    return hashlib.sha256(prev.encode("ascii") + canonical_json(body)).hexdigest()


def anchor_path(log: Path) -> Path:
    """Where the head anchor of ``log`` lives (``LOG.head`` beside it)."""
    return log.with_name(log.name + ".head")


def anchor_message(header_hash: str, seq: int, head: str, closed: bool) -> bytes:
    """The bytes an anchor's Ed25519 signature covers."""
    return f"{SCHEMA}|{header_hash}|{seq}|{head}|{'closed' if closed else 'open'}".encode()


def anchor_bytes(anchor: Mapping[str, Any]) -> bytes:
    """The one byte form of a head anchor file: its canonical JSON and a newline."""
    return canonical_json(anchor) + b"\n"


def _raw_public(key: Ed25519PrivateKey) -> str:
    return base64.b64encode(raw_public_key(key.public_key())).decode("ascii")


def signing_key_for(section: AuditSection) -> Ed25519PrivateKey | None:
    """The key that signs the head anchor (SR-AUD-1): None unless ``audit.sign_head``.

    ``audit.signing_key`` set: that Ed25519 PEM file, which must exist (it is never created,
    so a mistyped path cannot silently sign with a new key nobody trusts). Empty: the default
    key of :func:`safety.audit.keys.default_key_path` (``$SAFECASE_SIGNING_KEY`` or
    ``~/.config/safecase/signing-key.pem``), the key that signs evidence bundles, created on
    first use. Raises :class:`~safety.audit.keys.SigningKeyError` naming the path when the key
    cannot be used (missing, unreadable, not a regular file, not an Ed25519 PEM).
    """
    if not section.sign_head:
        return None
    if section.signing_key:
        return load_private_key(Path(section.signing_key).expanduser())
    key, _, _ = load_or_create_key(None)
    return key


def summarize(**parts: Any) -> dict[str, Any]:
    """A JSON-ready summary of a cycle's inputs from stage outputs and counters.

    Dataclasses (``DropCounts``, ``ClusterCounts``, ``CycleCounts``, ``FusionCounts``) become
    mappings, enums their values, non-finite floats text; ``None`` parts are left out. A
    ``scan`` part (a :class:`~pipeline.types.Scan`) is reduced to its seq, stamp, source, beam
    count and completeness.
    """
    out: dict[str, Any] = {}
    for name, value in parts.items():
        if value is None:
            continue
        if name == "scan" and hasattr(value, "n_beams"):
            value = {
                "seq": value.seq,
                "stamp_s": value.stamp_s,
                "source": value.source,
                "n_beams": value.n_beams,
                "complete": value.complete,
            }
        out[name] = jsonable(value)
    return out


@dataclass(frozen=True)
class CycleRecord:
    """What one runtime cycle writes to the log (SR-AUD-1, SR-AUD-2).

    ``inputs`` summarises what came in (see :func:`summarize`); ``observation``,
    ``governor_inputs`` and ``decision`` are exactly what :func:`safety.model.decision.decide` read
    and returned, so :func:`safety.audit.replay.replay` can recompute the command; ``timings_s`` are
    the per-stage durations [s].
    """

    observation: Observation
    decision: Decision
    governor_inputs: GovernorInputs | None
    inputs: Mapping[str, Any] = field(default_factory=dict)
    timings_s: Mapping[str, float] = field(default_factory=dict)

    def body(self) -> dict[str, Any]:
        """The record's JSON-ready content (without kind, seq, prev, hash)."""
        d = self.decision
        return {
            "stamp_s": jsonable(self.observation.now_s),
            "inputs": jsonable(dict(self.inputs)),
            "observation": self.observation.to_dict(),
            "governor_inputs": (
                None if self.governor_inputs is None else self.governor_inputs.to_dict()
            ),
            "governor_command": (
                None if d.governor_command is None else command_to_dict(d.governor_command)
            ),
            "verdicts": [v.to_dict() for v in d.verdicts],
            "command": command_to_dict(d.command),
            "timings_s": jsonable(dict(self.timings_s)),
        }


class AuditWriter:
    """Append-only writer of one audit log (SR-AUD-1). Use as a context manager.

    Refuses to touch an existing file. ``params`` are the stopping parameters the governor
    runs with (their latency bound and its source go into the header, so replay uses the same
    ones); ``model_hash`` is the classifier model's SHA-256 (None while no classifier runs).
    """

    def __init__(
        self,
        path: Path | str,
        config: SafecaseConfig,
        *,
        model_hash: str | None,
        params: StoppingParams | None = None,
        signing_key: Ed25519PrivateKey | None = None,
        fsync_every: int | None = None,
        created_utc: str | None = None,
    ) -> None:
        self.path = Path(path)
        self.anchor = anchor_path(self.path)
        self.key = signing_key
        self.fsync_every = fsync_every or config.audit.fsync_every_records
        self.seq = -1
        self.head = GENESIS
        self.closed = False
        self._unsynced = 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_APPEND, 0o644)
        except FileExistsError:
            raise AuditError(
                f"audit log {self.path} exists already; logs are append-only"
            ) from None
        except OSError as exc:
            raise AuditError(f"audit log {self.path}: cannot create ({exc.strerror})") from None
        p = params if params is not None else StoppingParams.from_config(config)
        try:
            version = metadata.version("safecase")
        except metadata.PackageNotFoundError:
            version = "unknown"
        self.header_hash = self._append(
            "header",
            {
                "schema": SCHEMA,
                "created_utc": created_utc or datetime.now(UTC).isoformat(timespec="seconds"),
                "config_hash": config_hash(config),
                "config": config.model_dump(mode="json"),
                "model_hash": model_hash,
                "latency": {
                    "perception_latency_s": float(p.perception_latency_s),
                    "latency_source": p.latency_source,
                },
                "software": {"safecase": version},
                "public_key": None if signing_key is None else _raw_public(signing_key),
            },
        )
        self.sync()

    def __enter__(self) -> AuditWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _append(self, kind: str, body: Mapping[str, Any]) -> str:
        if self.closed:
            raise AuditError(f"audit log {self.path} is closed")
        record = {**body, "kind": kind, "seq": self.seq + 1, "prev": self.head}
        digest = record_hash(self.head, record)
        line = canonical_json({**record, "hash": digest}) + b"\n"
        _write_all(self._fd, line)
        self.seq += 1
        self.head = digest
        self._unsynced += 1
        return digest

    def append(self, record: CycleRecord) -> str:
        """Append one cycle record; fsync and re-anchor every ``fsync_every`` records."""
        return self.append_body(record.body())

    def append_body(self, body: Mapping[str, Any]) -> str:
        """Append the JSON-ready body of a cycle record (see :meth:`CycleRecord.body`)."""
        digest = self._append("cycle", body)
        if self._unsynced >= self.fsync_every:
            self.sync()
        return digest

    def sync(self, closed: bool = False) -> None:
        """Make every record so far durable, then rewrite the (signed) head anchor."""
        os.fsync(self._fd)
        self._unsynced = 0
        anchor = {
            "schema": SCHEMA,
            "header_hash": self.header_hash,
            "seq": self.seq,
            "hash": self.head,
            "closed": closed,
            "public_key": None if self.key is None else _raw_public(self.key),
            "signature": None,
        }
        if self.key is not None:
            message = anchor_message(self.header_hash, self.seq, self.head, closed)
            anchor["signature"] = base64.b64encode(self.key.sign(message)).decode("ascii")
        tmp = self.anchor.with_name(self.anchor.name + ".tmp")
        # A leftover of a crash, or a link planted there, is removed, never written through;
        # O_EXCL refuses whatever appears there meanwhile (a link included: it is not followed).
        tmp.unlink(missing_ok=True)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        try:
            _write_all(fd, anchor_bytes(anchor))
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, self.anchor)
        dir_fd = os.open(self.anchor.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)

    def close(self) -> None:
        """Write the close record, fsync, anchor it as closed. Idempotent."""
        if self.closed:
            return
        self._append("close", {"n_records": self.seq + 1})
        self.sync(closed=True)
        self.closed = True
        os.close(self._fd)


def _write_all(fd: int, data: bytes) -> None:
    """Write all of ``data`` to ``fd``, however few bytes each write takes."""
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


class BackgroundAuditWriter:
    """An :class:`AuditWriter` fed from the cycle, written by a worker thread (SR-AUD-1).

    fsync latency is the disk's, not ours (p99 15 ms, maximum 100 ms measured here with an
    fsync every 10 records), so a cycle that waited for it could miss its deadline. ``append``
    turns the record into its JSON-ready body in the calling thread (so buffers the runtime
    reuses cannot change it later) and queues it; the worker hashes, writes and syncs in
    order. At most ``max_pending`` bodies wait: beyond that ``append`` blocks (backpressure,
    which the deadline monitor then sees) rather than drop a record. A failure in the worker
    is raised by the next ``append`` or by ``close``.
    """

    def __init__(self, writer: AuditWriter, max_pending: int = 1000) -> None:
        self.writer = writer
        self._queue: queue.Queue[Mapping[str, Any] | None] = queue.Queue(max_pending)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="audit-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (body := self._queue.get()) is not None:
            if self._error is None:
                try:
                    self.writer.append_body(body)
                except BaseException as exc:  # handed to the cycle thread, never lost
                    self._error = exc

    def _raise(self) -> None:
        if self._error is not None:
            raise AuditError(f"audit log {self.writer.path}: writer failed: {self._error}")

    def append(self, record: CycleRecord) -> None:
        """Queue one cycle record (blocks only when ``max_pending`` records wait)."""
        self._raise()
        self._queue.put(record.body())

    @property
    def pending(self) -> int:
        """Records queued and not yet written."""
        return self._queue.qsize()

    def close(self) -> None:
        """Write everything queued, then close the log (close record, final anchor)."""
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        self._raise()
        self.writer.close()

    def __enter__(self) -> BackgroundAuditWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def iter_lines(path: Path) -> Iterator[tuple[int, bytes, bool]]:
    """``(line number, bytes without newline, terminated)`` for every line of ``path``.

    Raises :class:`AuditError` when ``path`` is not a readable regular file (a FIFO or a device
    would block or never end) and :class:`RecordTooLongError` at a line longer than
    :data:`MAX_RECORD_BYTES`.
    """
    try:
        fd = open_regular(path)
    except FileReadError as exc:
        raise AuditError(f"audit log {exc}") from None
    with os.fdopen(fd, "rb") as handle:
        number = 0
        while raw := handle.readline(MAX_RECORD_BYTES + 1):
            number += 1
            terminated = raw.endswith(b"\n")
            if len(raw) > MAX_RECORD_BYTES and not terminated:
                raise RecordTooLongError(path, number)
            yield number, raw[:-1] if terminated else raw, terminated
