"""The audit log by example: format, anchor, signature, crash vs tampering, the CLI."""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from evidence.record import Recorder
from pipeline.config import config_hash, default_config, overridden
from properties.audit_cases import random_cycle, write_random_log
from safety.audit.log import (
    GENESIS,
    AuditError,
    AuditWriter,
    BackgroundAuditWriter,
    anchor_path,
    canonical_json,
    record_hash,
    signing_key_for,
)
from safety.audit.verify import AuditStatus, verify_log
from safety.model.governor import Governor

AUDIT = [
    "safety/audit/log.py",
    "safety/audit/verify.py",
    "safety/audit/records.py",
    "safety/audit/anchor.py",
    "evidence/cli/audit.py",
]
CONFIG = default_config()


def _log(tmp_path: Path, n: int = 6, **kw: object) -> Path:
    log = tmp_path / "run.log"
    write_random_log(log, CONFIG, np.random.default_rng(5), n, **kw)  # type: ignore[arg-type]
    return log


def _records(log: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in log.read_bytes().splitlines()]


@pytest.mark.requirement("SR-AUD-2", kind="example", code=["safety/audit/log.py"])
def test_header_records_config_model_and_latency(tmp_path: Path) -> None:
    log = _log(tmp_path, model_hash="ab" * 32)
    header, *cycles, close = _records(log)
    assert header["kind"] == "header"
    assert header["seq"] == 0
    assert header["prev"] == GENESIS
    assert header["config_hash"] == config_hash(CONFIG)
    assert header["config"] == CONFIG.model_dump(mode="json")
    assert header["model_hash"] == "ab" * 32
    assert header["latency"] == {"perception_latency_s": 0.18, "latency_source": "config"}
    assert [c["kind"] for c in cycles] == ["cycle"] * 6
    assert close == {**close, "kind": "close", "n_records": 7, "seq": 7}
    for record in (header, *cycles, close):
        body = {k: v for k, v in record.items() if k != "hash"}
        assert record["hash"] == record_hash(str(record["prev"]), body)
    line = log.read_bytes().splitlines()[1]
    assert line == canonical_json(json.loads(line))


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_intact_log_and_anchor(tmp_path: Path) -> None:
    log = _log(tmp_path)
    result = verify_log(log)
    assert result.status is AuditStatus.INTACT, result.describe()
    assert (result.n_records, result.n_cycles, result.closed) == (8, 6, True)
    anchor = json.loads(anchor_path(log).read_bytes())
    assert anchor["seq"] == 7
    assert anchor["closed"]
    assert anchor["hash"] == result.head_hash
    assert result.signature == "absent"


def test_anchor_follows_the_fsync_period(tmp_path: Path) -> None:
    log = tmp_path / "live.log"
    writer = write_random_log(log, CONFIG, np.random.default_rng(1), 7, fsync_every=3, close=False)
    anchor = json.loads(anchor_path(log).read_bytes())
    assert anchor["seq"] == 6
    assert not anchor["closed"]
    live = verify_log(log)
    assert live.status is AuditStatus.INCOMPLETE
    assert "no close record after seq 7" in live.problem
    writer.close()
    assert verify_log(log).ok


def test_an_existing_log_is_never_overwritten(tmp_path: Path) -> None:
    log = _log(tmp_path)
    with pytest.raises(AuditError, match="exists already"):
        AuditWriter(log, CONFIG, model_hash=None)
    writer = AuditWriter(tmp_path / "other.log", CONFIG, model_hash=None)
    writer.close()
    writer.close()  # idempotent
    with pytest.raises(AuditError, match="is closed"):
        writer._append("cycle", {})


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_crash_is_incomplete_and_anchored_truncation_is_tampering(tmp_path: Path) -> None:
    log = tmp_path / "crash.log"
    writer = write_random_log(log, CONFIG, np.random.default_rng(2), 5, fsync_every=2, close=False)
    os.close(writer._fd)
    data = log.read_bytes()
    log.write_bytes(data[:-40])  # the last record half written
    result = verify_log(log)
    assert result.status is AuditStatus.INCOMPLETE
    assert result.problem.startswith("partial last line")
    assert result.first_bad_line == 6
    # Cutting into records the anchor says were durable is tampering, not a crash.
    cut = len(b"".join(line + b"\n" for line in data.split(b"\n")[:3]))
    log.write_bytes(data[:cut])
    result = verify_log(log)
    assert result.status is AuditStatus.TAMPERED
    assert "truncated" in result.problem
    assert result.first_bad_line == 4


def _key(path: Path) -> Ed25519PrivateKey:
    key = Ed25519PrivateKey.generate()
    path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return key


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_signed_head_catches_a_rewritten_chain(tmp_path: Path) -> None:
    key_file = tmp_path / "key.pem"
    key = _key(key_file)
    config = overridden(CONFIG, {"audit": {"sign_head": True, "signing_key": str(key_file)}})
    loaded = signing_key_for(config.audit)
    assert loaded is not None
    assert loaded.public_key() == key.public_key()
    assert signing_key_for(CONFIG.audit) is None
    for signed in (False, True):
        log = _log(tmp_path / str(signed), key=key if signed else None)
        trusted = key.public_key() if signed else None
        assert verify_log(log, trusted_key=trusted).ok
        # Rewrite the whole chain after changing one command, and the anchor with it.
        lines = log.read_bytes().splitlines()
        prev = GENESIS
        for i, raw in enumerate(lines):
            body = {k: v for k, v in json.loads(raw).items() if k != "hash"}
            body["prev"] = prev
            if i == 2:
                body["command"]["action"] = "PROCEED"
            prev = record_hash(prev, body)
            lines[i] = canonical_json({**body, "hash": prev})
        log.write_bytes(b"".join(line + b"\n" for line in lines))
        anchor = json.loads(anchor_path(log).read_bytes())
        anchor.update(hash=prev, header_hash=json.loads(lines[0])["hash"])
        anchor_path(log).write_bytes(canonical_json(anchor) + b"\n")
        result = verify_log(log, trusted_key=trusted)
        if signed:
            assert result.status is AuditStatus.TAMPERED
            assert "signature does not verify" in result.problem
        else:
            # Without a signature a complete rewrite is undetectable: the documented limit.
            assert result.ok


def test_anchor_removed_or_signed_by_someone_else(tmp_path: Path) -> None:
    key = _key(tmp_path / "k.pem")
    log = _log(tmp_path, key=key)
    other = Ed25519PrivateKey.generate().public_key()
    assert "not by the trusted key" in verify_log(log, trusted_key=other).problem
    anchor = json.loads(anchor_path(log).read_bytes())
    stripped = {**anchor, "signature": None}
    anchor_path(log).write_bytes(canonical_json(stripped) + b"\n")
    assert "not signed" in verify_log(log).problem
    stripped["public_key"] = None
    anchor_path(log).write_bytes(canonical_json(stripped) + b"\n")
    assert "the header names a signing key but the anchor is not signed" in (
        verify_log(log).problem
    )
    anchor["public_key"] = base64.b64encode(other.public_bytes_raw()).decode()
    anchor_path(log).write_bytes(canonical_json(anchor) + b"\n")
    assert "other than the header's" in verify_log(log).problem
    anchor_path(log).unlink()
    # Without the anchor an intact chain is its own outcome: not tampered, not intact.
    unanchored = verify_log(log)
    assert unanchored.status is AuditStatus.UNANCHORED, unanchored.describe()
    assert unanchored.signature == "not checked (no anchor)"
    copied = verify_log(log, require_anchor=False)
    assert copied.ok
    assert copied.notes


SAFECASE = [sys.executable, "-m", "evidence.cli"]


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MPLBACKEND="Agg", COLUMNS="200")
    return subprocess.run(
        [*SAFECASE, "audit", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_cli_verify_show_tail_replay(tmp_path: Path) -> None:
    log = _log(tmp_path, n=4)
    done = _cli("verify", str(log))
    assert done.returncode == 0
    assert done.stdout.startswith("INTACT (6 records, 4 cycles")
    shown = _cli("show", str(log))
    assert shown.returncode == 0
    assert "commands:" in shown.stdout
    assert "header" in shown.stdout
    assert _cli("tail", str(log), "-n", "2").returncode == 0
    replayed = _cli("replay", str(log))
    assert replayed.returncode == 0
    assert "replayed 4 of 4 cycles exactly" in replayed.stdout
    data = bytearray(log.read_bytes())
    data[data.index(b'"action":"') + 10] ^= 0x01
    log.write_bytes(bytes(data))
    bad = _cli("verify", str(log))
    assert bad.returncode == 1
    assert bad.stdout.startswith("TAMPERED at line 2")
    assert _cli("replay", str(log)).returncode == 1
    crashed = tmp_path / "crashed.log"
    writer = write_random_log(crashed, CONFIG, np.random.default_rng(3), 2, close=False)
    os.close(writer._fd)
    assert _cli("verify", str(crashed)).returncode == 3
    missing = _cli("verify", str(tmp_path / "nope.log"))
    assert missing.returncode == 2
    assert "no such file" in missing.stderr


def test_background_writer_writes_the_same_bytes(tmp_path: Path) -> None:
    governor = Governor.from_config(CONFIG)
    rng = np.random.default_rng(9)
    records = [random_cycle(rng, governor, CONFIG, 0.1 * i, None) for i in range(25)]
    paths = []
    for background in (False, True):
        log = tmp_path / f"bg{background}.log"
        writer = AuditWriter(log, CONFIG, model_hash=None, fsync_every=4, created_utc="t")
        if background:
            with BackgroundAuditWriter(writer, max_pending=3) as queued:
                for record in records:
                    queued.append(record)
        else:
            with writer:
                for record in records:
                    writer.append(record)
        paths.append(log)
    assert paths[0].read_bytes() == paths[1].read_bytes()
    assert verify_log(paths[1]).ok


def test_background_writer_reports_a_failure(tmp_path: Path) -> None:
    writer = AuditWriter(tmp_path / "f.log", CONFIG, model_hash=None)
    writer.close()  # every later append fails in the worker
    queued = BackgroundAuditWriter(writer)
    queued.append(
        random_cycle(np.random.default_rng(0), Governor.from_config(CONFIG), CONFIG, 1.0, None)
    )
    with pytest.raises(AuditError, match=r"writer failed: .* is closed"):
        queued.close()


@pytest.mark.requirement("SR-AUD-1", kind="measurement", code=["safety/audit/log.py"])
def test_append_cost_with_and_without_waiting_for_the_disk(
    tmp_path: Path, evidence: Recorder
) -> None:
    governor = Governor.from_config(CONFIG)
    rng = np.random.default_rng(11)
    records = [random_cycle(rng, governor, CONFIG, 0.1 * i, None) for i in range(600)]
    rows = []
    for name, background in (("synchronous", False), ("background thread", True)):
        writer = AuditWriter(tmp_path / f"{name}.log", CONFIG, model_hash=None, fsync_every=10)
        sink: AuditWriter | BackgroundAuditWriter = (
            BackgroundAuditWriter(writer) if background else writer
        )
        costs = np.empty(len(records))
        for i, record in enumerate(records):
            start = time.perf_counter_ns()
            sink.append(record)
            costs[i] = (time.perf_counter_ns() - start) * 1e-6
        sink.close()
        evidence.samples(f"append, {name} (fsync every 10)", costs, "ms")
        p50, p99 = np.percentile(costs, [50, 99])
        rows.append([name, f"{p50:.3f}", f"{p99:.3f}", f"{costs.max():.3f}"])
        assert verify_log(tmp_path / f"{name}.log").ok
    evidence.table(
        "audit append cost per cycle record [ms]",
        ["writer", "p50", "p99", "max"],
        rows,
        caption="what the cycle waits for; the synchronous writer includes the fsyncs",
    )
