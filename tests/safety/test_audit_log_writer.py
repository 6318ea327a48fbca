"""The audit writers by their bytes: header, chain, anchor, durability (SR-AUD-1, SR-AUD-2).

:class:`~safety.audit.log.AuditWriter` is checked line by line against records rebuilt here
with :mod:`json` and :mod:`hashlib` (not with the module's own helpers), its head anchor against
bytes built the same way and an Ed25519 signature checked with the public key, and the moments
it makes records durable (every ``fsync_every`` records, at close) against the anchor it leaves
after each append. :class:`~safety.audit.log.BackgroundAuditWriter` is checked for order,
backpressure at ``max_pending``, the thread it writes from and how a failure in that thread
reaches the caller.
"""

from __future__ import annotations

import base64
import errno
import hashlib
import json
import math
import os
import re
import stat
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from pipeline.compat import UTC
from pipeline.config import default_config, overridden
from pipeline.types import Action, Command
from safety.audit.log import AuditError, AuditWriter, BackgroundAuditWriter, CycleRecord
from safety.model.decision import Decision
from safety.model.monitors import MonitorVerdict, Observation
from safety.model.stopping import StoppingParams

CODE = ["safety/audit/log.py"]
CONFIG = default_config()
ZEROS = "0" * 64
CREATED = "2030-01-02T03:04:05+00:00"


def _canonical(value: Any) -> bytes:
    return json.dumps(
        value, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False
    ).encode("ascii")


def _chain(records: list[tuple[str, dict[str, Any]]]) -> tuple[list[bytes], list[str]]:
    """The lines and hashes of ``(kind, body)`` records chained from the genesis hash."""
    lines, hashes, prev = [], [], ZEROS
    for seq, (kind, body) in enumerate(records):
        record = {**body, "kind": kind, "seq": seq, "prev": prev}
        prev = hashlib.sha256(prev.encode("ascii") + _canonical(record)).hexdigest()
        lines.append(_canonical({**record, "hash": prev}) + b"\n")
        hashes.append(prev)
    return lines, hashes


def _header_body(
    *,
    model_hash: str | None = None,
    latency: tuple[float, str] = (0.18, "config"),
    public_key: str | None = None,
    created: str = CREATED,
) -> dict[str, Any]:
    config = CONFIG.model_dump(mode="json")
    return {
        "schema": "safecase-audit/1",
        "created_utc": created,
        "config_hash": hashlib.sha256(_canonical(config)).hexdigest(),
        "config": config,
        "model_hash": model_hash,
        "latency": {"perception_latency_s": latency[0], "latency_source": latency[1]},
        "software": {"safecase": metadata.version("safecase")},
        "public_key": public_key,
    }


def _anchor(
    header: str, seq: int, head: str, closed: bool, key: Ed25519PrivateKey | None = None
) -> bytes:
    public = signature = None
    if key is not None:
        public = base64.b64encode(key.public_key().public_bytes_raw()).decode()
        state = "closed" if closed else "open"
        message = f"safecase-audit/1|{header}|{seq}|{head}|{state}".encode()
        signature = base64.b64encode(key.sign(message)).decode()
    anchor = {
        "schema": "safecase-audit/1",
        "header_hash": header,
        "seq": seq,
        "hash": head,
        "closed": closed,
        "public_key": public,
        "signature": signature,
    }
    return _canonical(anchor) + b"\n"


def _writer(path: Path, model_hash: str | None = None, **kw: Any) -> AuditWriter:
    return AuditWriter(path, CONFIG, model_hash=model_hash, created_utc=CREATED, **kw)


def _head(log: Path) -> bytes:
    return (log.parent / (log.name + ".head")).read_bytes()


def _body(i: int) -> dict[str, Any]:
    """A cycle body as a caller hands it over: unsorted keys, unicode, an infinite float."""
    return {"stamp_s": 0.5 * i, "z": [i, math.inf], "a": {"y": "\u00e9", "b": None}}


def _ready(i: int) -> dict[str, Any]:
    """:func:`_body` as JSON writes it."""
    return {"stamp_s": 0.5 * i, "z": [i, "inf"], "a": {"y": "\u00e9", "b": None}}


# ------------------------------------------------------------------ the header and the chain


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_the_header_records_config_model_latency_and_software_byte_for_byte(
    tmp_path: Path,
) -> None:
    log = tmp_path / "run.log"
    params = StoppingParams.from_config(
        CONFIG, perception_latency_s=0.25, latency_source="measured p99"
    )
    writer = _writer(log, model_hash="ef" * 32, params=params)
    header = _header_body(model_hash="ef" * 32, latency=(0.25, "measured p99"))
    lines, hashes = _chain([("header", header)])
    assert log.read_bytes() == lines[0]
    assert writer.header_hash == hashes[0]
    assert (writer.seq, writer.head, writer.closed) == (0, hashes[0], False)
    writer.close()
    lines, hashes = _chain([("header", header), ("close", {"n_records": 1})])
    assert log.read_bytes() == b"".join(lines)


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_without_params_the_header_has_the_configured_latency_bound(tmp_path: Path) -> None:
    config = overridden(CONFIG, {"stopping": {"perception_latency_s": 0.3}})
    log = tmp_path / "run.log"
    AuditWriter(log, config, model_hash=None, created_utc=CREATED).close()
    header = json.loads(log.read_bytes().splitlines()[0])
    assert header["latency"] == {"perception_latency_s": 0.3, "latency_source": "config"}
    assert header["model_hash"] is None
    assert header["config"] == config.model_dump(mode="json")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_without_a_creation_time_the_header_has_now_in_utc_to_the_second(
    tmp_path: Path,
) -> None:
    before = datetime.now(UTC).replace(microsecond=0)
    AuditWriter(tmp_path / "run.log", CONFIG, model_hash=None).close()
    after = datetime.now(UTC)
    created = json.loads((tmp_path / "run.log").read_bytes().splitlines()[0])["created_utc"]
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", created), created
    assert before <= datetime.fromisoformat(created) <= after


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_an_uninstalled_package_is_recorded_as_version_unknown(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def not_installed(name: str) -> str:
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "version", not_installed)
    AuditWriter(tmp_path / "run.log", CONFIG, model_hash=None).close()
    header = json.loads((tmp_path / "run.log").read_bytes().splitlines()[0])
    assert header["software"] == {"safecase": "unknown"}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_records_are_numbered_from_zero_and_each_chains_to_the_one_before(
    tmp_path: Path,
) -> None:
    log = tmp_path / "run.log"
    writer = _writer(log, fsync_every=100)
    returned = [writer.append_body(_body(i)) for i in range(1, 4)]
    writer.close()
    lines, hashes = _chain(
        [
            ("header", _header_body()),
            *(("cycle", _ready(i)) for i in range(1, 4)),
            ("close", {"n_records": 4}),
        ]
    )
    assert log.read_bytes() == b"".join(lines)
    assert returned == hashes[1:4]
    assert (writer.seq, writer.head) == (4, hashes[4])


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_cycle_record_is_written_as_its_body(tmp_path: Path) -> None:
    observation = Observation(now_s=4.0, scan_stamp_s=3.95, n_beams=10)
    stop = Command(Action.STOP, 0.0, 4.0, ("zone",))
    record = CycleRecord(
        observation, Decision(stop, None, (MonitorVerdict.ok("deadline"),)), None, {"n": 1}
    )
    log = tmp_path / "run.log"
    writer = _writer(log)
    digest = writer.append(record)
    writer.close()
    lines, hashes = _chain(
        [("header", _header_body()), ("cycle", record.body()), ("close", {"n_records": 2})]
    )
    assert log.read_bytes() == b"".join(lines)
    assert digest == hashes[1]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_record_the_disk_takes_in_pieces_is_still_written_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real_write = os.write
    sizes: list[int] = []

    def seven_at_a_time(fd: int, data: Any) -> int:
        written = real_write(fd, bytes(data)[:7])
        sizes.append(written)
        return written

    log = tmp_path / "run.log"
    writer = _writer(log, fsync_every=100)
    monkeypatch.setattr(os, "write", seven_at_a_time)
    writer.append_body(_body(1))
    monkeypatch.undo()
    writer.close()
    lines, _ = _chain(
        [("header", _header_body()), ("cycle", _ready(1)), ("close", {"n_records": 2})]
    )
    assert log.read_bytes() == b"".join(lines)
    assert sizes[:-1] == [7] * (len(sizes) - 1)
    assert sum(sizes) == len(lines[1])


# ------------------------------------------------------------------ durability and the anchor


def _anchors_after_each_append(writer: AuditWriter, n: int) -> list[int]:
    seqs = []
    for i in range(n):
        writer.append_body(_body(i))
        seqs.append(json.loads(_head(writer.path))["seq"])
    return seqs


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_anchor_is_rewritten_every_fsync_every_records_and_at_close(tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    writer = _writer(log, fsync_every=3)
    lines, hashes = _chain([("header", _header_body())])
    assert _head(log) == _anchor(hashes[0], 0, hashes[0], False)
    assert _anchors_after_each_append(writer, 7) == [0, 0, 3, 3, 3, 6, 6]
    bodies = [("cycle", _ready(i)) for i in range(7)]
    lines, hashes = _chain([("header", _header_body()), *bodies])
    assert _head(log) == _anchor(hashes[0], 6, hashes[6], False)
    writer.close()
    lines, hashes = _chain([("header", _header_body()), *bodies, ("close", {"n_records": 8})])
    assert _head(log) == _anchor(hashes[0], 8, hashes[8], True)
    assert log.read_bytes() == b"".join(lines)
    assert sorted(os.listdir(tmp_path)) == ["run.log", "run.log.head"]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_every_record_is_durable_at_once_when_fsync_every_is_one(tmp_path: Path) -> None:
    writer = _writer(tmp_path / "run.log", fsync_every=1)
    assert _anchors_after_each_append(writer, 3) == [1, 2, 3]
    writer.close()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_without_fsync_every_the_configured_period_is_used(tmp_path: Path) -> None:
    config = overridden(CONFIG, {"audit": {"fsync_every_records": 2}})
    writer = AuditWriter(tmp_path / "a.log", config, model_hash=None)
    assert _anchors_after_each_append(writer, 5) == [0, 2, 2, 4, 4]
    writer.close()
    # Given, it wins over the configuration.
    writer = AuditWriter(tmp_path / "b.log", config, model_hash=None, fsync_every=3)
    assert _anchors_after_each_append(writer, 4) == [0, 0, 3, 3]
    writer.close()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_sync_fsyncs_the_log_then_the_new_anchor_then_the_folder_and_renames_atomically(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real_fsync, real_replace = os.fsync, os.replace
    synced: list[tuple[int, bool]] = []
    renamed: list[tuple[str, str]] = []

    def fsync(fd: int) -> None:
        info = os.fstat(fd)
        synced.append((info.st_ino, stat.S_ISDIR(info.st_mode)))
        real_fsync(fd)

    def replace(src: Any, dst: Any) -> None:
        renamed.append((os.fspath(src), os.fspath(dst)))
        real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    log = tmp_path / "run.log"
    writer = _writer(log, fsync_every=2)
    head = log.parent / "run.log.head"
    folder = (tmp_path.stat().st_ino, True)
    assert synced == [(log.stat().st_ino, False), (head.stat().st_ino, False), folder]
    assert renamed == [(str(head) + ".tmp", str(head))]
    writer.append_body(_body(1))
    assert len(synced) == 3
    writer.append_body(_body(2))
    assert synced[3:] == [(log.stat().st_ino, False), (head.stat().st_ino, False), folder]
    writer.close()
    assert len(synced) == 9
    assert len(renamed) == 3


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_signed_anchor_carries_the_public_key_and_a_signature_that_verifies(
    tmp_path: Path,
) -> None:
    key = Ed25519PrivateKey.generate()
    public = base64.b64encode(key.public_key().public_bytes_raw()).decode()
    log = tmp_path / "run.log"
    writer = _writer(log, signing_key=key, fsync_every=1)
    header = _header_body(public_key=public)
    lines, hashes = _chain([("header", header)])
    assert log.read_bytes() == lines[0]
    assert _head(log) == _anchor(hashes[0], 0, hashes[0], False, key)
    writer.append_body(_body(1))
    writer.close()
    lines, hashes = _chain([("header", header), ("cycle", _ready(1)), ("close", {"n_records": 2})])
    assert log.read_bytes() == b"".join(lines)
    assert _head(log) == _anchor(hashes[0], 2, hashes[2], True, key)
    anchor = json.loads(_head(log))
    message = f"safecase-audit/1|{hashes[0]}|2|{hashes[2]}|closed".encode()
    key.public_key().verify(base64.b64decode(anchor["signature"]), message)
    assert anchor["public_key"] == public


# ------------------------------------------------------------------ refusals and closing


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_an_existing_file_or_link_is_refused_and_left_as_it_was(tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    log.write_bytes(b"precious\n")
    with pytest.raises(AuditError) as caught:
        _writer(log)
    assert str(caught.value) == f"audit log {log} exists already; logs are append-only"
    assert log.read_bytes() == b"precious\n"
    link = tmp_path / "link.log"
    link.symlink_to(tmp_path / "target.log")
    with pytest.raises(AuditError) as caught:
        _writer(link)
    assert str(caught.value) == f"audit log {link} exists already; logs are append-only"
    assert sorted(os.listdir(tmp_path)) == ["link.log", "run.log"]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_log_that_cannot_be_created_names_the_reason(tmp_path: Path) -> None:
    log = tmp_path / ("x" * 300)
    with pytest.raises(AuditError) as caught:
        _writer(log)
    reason = os.strerror(errno.ENAMETOOLONG)
    assert str(caught.value) == f"audit log {log}: cannot create ({reason})"


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_missing_folders_are_made_and_the_log_and_anchor_are_readable_by_all_writable_by_owner(
    tmp_path: Path,
) -> None:
    log = tmp_path / "a" / "b" / "run.log"
    previous = os.umask(0)
    try:
        _writer(log).close()
    finally:
        os.umask(previous)
    assert stat.S_IMODE(log.stat().st_mode) == 0o644
    # Its anchor too: anyone may check the head, only the writer rewrites it.
    assert stat.S_IMODE((log.parent / "run.log.head").stat().st_mode) == 0o644
    # A folder that exists already is fine too.
    _writer(log.parent / "second.log").close()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_close_writes_the_close_record_once_and_then_refuses_appends(tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    with _writer(log) as writer:
        writer.append_body(_body(1))
        writer.append_body(_body(2))
    assert writer.closed
    data, head = log.read_bytes(), _head(log)
    assert json.loads(data.splitlines()[-1]) | {"hash": ""} == {
        "kind": "close",
        "n_records": 3,
        "seq": 3,
        "prev": json.loads(data.splitlines()[-2])["hash"],
        "hash": "",
    }
    writer.close()
    assert (log.read_bytes(), _head(log)) == (data, head)
    with pytest.raises(AuditError) as caught:
        writer.append_body(_body(3))
    assert str(caught.value) == f"audit log {log} is closed"
    with pytest.raises(AuditError) as caught:
        writer.append(_record())
    assert str(caught.value) == f"audit log {log} is closed"
    assert (log.read_bytes(), _head(log)) == (data, head)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_leaving_the_context_on_an_error_still_closes_the_log(tmp_path: Path) -> None:
    log = tmp_path / "run.log"

    def failing_cycle() -> None:
        with _writer(log) as writer:
            writer.append_body(_body(1))
            raise RuntimeError("cycle failed")

    with pytest.raises(RuntimeError, match=r"^cycle failed$"):
        failing_cycle()
    assert json.loads(log.read_bytes().splitlines()[-1])["kind"] == "close"
    assert json.loads(_head(log))["closed"] is True


# ------------------------------------------------------------------ the background writer


def _record(i: int = 0) -> CycleRecord:
    stop = Command(Action.STOP, 0.0, float(i), ("zone",))
    return CycleRecord(Observation(now_s=float(i)), Decision(stop, None, ()), None)


class Hooked(AuditWriter):
    """An audit writer that calls ``hook`` with each body before writing it."""

    def __init__(self, path: Path, hook: Callable[[Mapping[str, Any]], None], **kw: Any) -> None:
        super().__init__(path, CONFIG, model_hash=None, created_utc=CREATED, **kw)
        self.hook = hook
        self.calls = 0

    def append_body(self, body: Mapping[str, Any]) -> str:
        self.calls += 1
        self.hook(body)
        return super().append_body(body)


def _kinds(log: Path) -> Iterator[str]:
    for line in log.read_bytes().splitlines():
        yield json.loads(line)["kind"]


def _wait_until(done: Callable[[], bool]) -> None:
    deadline = time.monotonic() + 10.0
    while not done():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.001)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_background_writer_writes_every_record_in_order_then_closes(tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    records = [_record(i) for i in range(5)]
    with BackgroundAuditWriter(_writer(log, fsync_every=2)) as queued:
        for record in records:
            queued.append(record)
    lines, hashes = _chain(
        [
            ("header", _header_body()),
            *(("cycle", r.body()) for r in records),
            ("close", {"n_records": 6}),
        ]
    )
    assert log.read_bytes() == b"".join(lines)
    assert _head(log) == _anchor(hashes[0], 6, hashes[6], True)
    assert queued.pending == 0
    queued.close()  # a second close changes nothing
    assert log.read_bytes() == b"".join(lines)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_background_writer_writes_from_its_own_daemon_thread(tmp_path: Path) -> None:
    seen: list[threading.Thread] = []
    writer = Hooked(tmp_path / "run.log", lambda _: seen.append(threading.current_thread()))
    queued = BackgroundAuditWriter(writer)
    queued.append(_record(1))
    queued.close()
    assert [(t.name, t.daemon) for t in seen] == [("audit-writer", True)]
    assert seen[0] is not threading.current_thread()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_close_waits_for_every_queued_record_before_the_close_record(tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    queued = BackgroundAuditWriter(Hooked(log, lambda _: time.sleep(0.002)))
    for i in range(10):
        queued.append(_record(i))
    queued.close()
    assert list(_kinds(log)) == ["header", *["cycle"] * 10, "close"]
    assert queued.writer.closed


def _blocked(
    tmp_path: Path, max_pending: int | None
) -> tuple[BackgroundAuditWriter, threading.Event]:
    """A background writer whose worker holds the first record until the event is set."""
    release, entered = threading.Event(), threading.Event()

    def hold(_: Mapping[str, Any]) -> None:
        entered.set()
        release.wait(30.0)

    writer = Hooked(tmp_path / "run.log", hold, fsync_every=1_000_000)
    queued = (
        BackgroundAuditWriter(writer)
        if max_pending is None
        else BackgroundAuditWriter(writer, max_pending=max_pending)
    )
    queued.append(_record(0))
    assert entered.wait(10.0)
    return queued, release


def _blocks(queued: BackgroundAuditWriter) -> threading.Thread:
    """Append one more record from another thread; it must still be waiting afterwards."""
    late = threading.Thread(target=queued.append, args=(_record(99),), daemon=True)
    late.start()
    late.join(0.2)
    return late


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
@pytest.mark.parametrize("max_pending", [None, 3])
def test_append_blocks_once_max_pending_records_wait_and_none_is_dropped(
    tmp_path: Path, max_pending: int | None
) -> None:
    limit = 1000 if max_pending is None else max_pending
    queued, release = _blocked(tmp_path, max_pending)
    for i in range(limit):
        queued.append(_record(i + 1))
    assert queued.pending == limit
    late = _blocks(queued)
    assert late.is_alive(), "append returned although max_pending records were waiting"
    release.set()
    late.join(10.0)
    assert not late.is_alive()
    queued.close()
    assert queued.pending == 0
    assert list(_kinds(queued.writer.path)) == ["header", *["cycle"] * (limit + 2), "close"]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_failure_in_the_worker_is_raised_by_the_next_append_and_by_close(
    tmp_path: Path,
) -> None:
    queued_all = threading.Event()

    def fail_second(_: Mapping[str, Any]) -> None:
        # The first record waits until all three are queued, so no append meets the failure
        # before the one this test makes after it.
        if writer.calls == 1:
            assert queued_all.wait(10.0)
        if writer.calls == 2:
            raise OSError(28, "No space left on device")

    log = tmp_path / "run.log"
    writer = Hooked(log, fail_second)
    queued = BackgroundAuditWriter(writer)
    for i in range(3):
        queued.append(_record(i))
    queued_all.set()
    # The third record leaves the queue only after the second one's failure is kept.
    _wait_until(lambda: queued.pending == 0)
    expected = f"audit log {log}: writer failed: [Errno 28] No space left on device"
    with pytest.raises(AuditError) as caught:
        queued.append(_record(3))
    assert str(caught.value) == expected
    with pytest.raises(AuditError) as caught:
        queued.close()
    assert str(caught.value) == expected
    # Nothing after the failure is written, and a failed log does not claim a clean close.
    assert writer.calls == 2
    assert list(_kinds(log)) == ["header", "cycle"]
    assert not writer.closed


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_closed_writer_under_the_background_writer_is_reported_at_close(
    tmp_path: Path,
) -> None:
    log = tmp_path / "run.log"
    writer = _writer(log)
    writer.close()
    queued = BackgroundAuditWriter(writer)
    queued.append(_record(1))
    with pytest.raises(AuditError) as caught:
        queued.close()
    assert str(caught.value) == (f"audit log {log}: writer failed: audit log {log} is closed")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_anchor_is_never_written_through_a_link_or_into_a_leftover(tmp_path: Path) -> None:
    """A link planted where the anchor's temporary file goes is replaced, not followed: the
    file it points to keeps its bytes; a temporary file left by a crash is replaced too."""
    victim = tmp_path / "victim.txt"
    victim.write_bytes(b"precious\n")
    (tmp_path / "run.log.head.tmp").symlink_to(victim)
    AuditWriter(tmp_path / "run.log", CONFIG, model_hash=None).close()
    assert victim.read_bytes() == b"precious\n"
    head = tmp_path / "run.log.head"
    assert not head.is_symlink()
    assert json.loads(head.read_bytes())["closed"] is True
    (tmp_path / "other.log.head.tmp").write_bytes(b"left by a crash, longer than any anchor" * 40)
    AuditWriter(tmp_path / "other.log", CONFIG, model_hash=None).close()
    assert json.loads((tmp_path / "other.log.head").read_bytes())["closed"] is True
    assert not (tmp_path / "other.log.head.tmp").exists()
