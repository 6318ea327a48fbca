"""The audit log against a hostile reader: signing switched on from the configuration, keys that
cannot be used, the anchor checked byte for byte, a missing anchor and an empty file as their
own outcomes, and malformed input (deep nesting, huge integers, records lacking fields) that
must end in a verdict or a one-line error, never a traceback (SR-AUD-1, SR-AUD-2)."""

from __future__ import annotations

import base64
import json
import os
import re
import stat
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey
from typer.testing import CliRunner

from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.errors import SafecaseError
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from properties.audit_cases import write_random_log
from properties.cli_runner import run_safecase
from safety.audit.log import GENESIS, anchor_path, canonical_json, record_hash
from safety.audit.replay import replay
from safety.audit.verify import verify_log
from safety.run import run_audited

AUDIT = [
    "safety/audit/log.py",
    "safety/audit/verify.py",
    "safety/audit/records.py",
    "safety/audit/anchor.py",
    "evidence/cli/audit.py",
]
KEYS = ["safety/audit/keys.py", "safety/audit/log.py", "safety/run.py"]
CONFIG = default_config()


def _pem(key: Ed25519PrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _key_file(path: Path) -> Ed25519PrivateKey:
    key = Ed25519PrivateKey.generate()
    path.write_bytes(_pem(key))
    return key


def _public_file(path: Path, key: Ed25519PrivateKey) -> Path:
    path.write_bytes(
        key.public_key().public_bytes(
            serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
        )
    )
    return path


def _signed_config(key_path: str) -> SafecaseConfig:
    return overridden(CONFIG, {"audit": {"sign_head": True, "signing_key": key_path}})


def _short_run(config: SafecaseConfig, log: Path, scans: int = 3) -> int:
    sim = make_simulation(config, "crossing_pedestrian", 0, 1.0)
    return sum(1 for _ in run_audited(config, SimSource(sim), audit_path=log, max_scans=scans))


def _log(tmp_path: Path, n: int = 4, name: str = "run.log", **kw: Any) -> Path:
    log = tmp_path / name
    write_random_log(log, CONFIG, np.random.default_rng(7), n, **kw)
    return log


def _rechain(log: Path, edit: Callable[[int, dict[str, Any]], None]) -> None:
    """Apply ``edit`` to every record, recompute every hash and the (unsigned) anchor: what
    anyone without the signing key can do to an unsigned log."""
    lines = log.read_bytes().splitlines()
    prev = GENESIS
    for i, raw in enumerate(lines):
        body = {k: v for k, v in json.loads(raw).items() if k != "hash"}
        body["prev"] = prev
        edit(i + 1, body)
        prev = record_hash(prev, body)
        lines[i] = canonical_json({**body, "hash": prev})
    log.write_bytes(b"".join(line + b"\n" for line in lines))
    anchor = json.loads(anchor_path(log).read_bytes())
    anchor.update(hash=prev, header_hash=json.loads(lines[0])["hash"])
    anchor_path(log).write_bytes(canonical_json(anchor) + b"\n")


def _no_traceback(done: Any) -> None:
    assert "Traceback" not in done.stderr, done.stderr[-2000:]
    assert "Traceback" not in done.stdout, done.stdout[-2000:]


@dataclass
class Done:
    """What an in-process ``safecase`` command left: exit code, stdout, stderr."""

    returncode: int
    stdout: str
    stderr: str


def _cli(*args: str) -> Done:
    """``safecase ARGS`` in this process (the many-case matrices; a subprocess costs seconds).

    Any exception other than the command's own exit is a failure: the user would see a
    traceback."""
    from evidence.cli.main import app

    result = CliRunner().invoke(app, list(args), env={"COLUMNS": "200"})
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"safecase {' '.join(args)} raised") from result.exception
    return Done(result.exit_code, result.stdout, result.stderr)


# ------------------------------------------------------------------ the signed anchor is used


@pytest.mark.requirement("SR-AUD-1", kind="example", code=KEYS)
def test_sign_head_in_the_configuration_signs_the_runs_anchor(tmp_path: Path) -> None:
    key = _key_file(tmp_path / "audit-key.pem")
    config = _signed_config(str(tmp_path / "audit-key.pem"))
    log = tmp_path / "signed.jsonl"
    assert _short_run(config, log) > 0
    result = verify_log(log, trusted_key=key.public_key())
    assert result.ok, result.describe()
    assert result.signature.startswith("valid (trusted key)")
    anchor = json.loads(anchor_path(log).read_bytes())
    header = json.loads(log.read_bytes().splitlines()[0])
    raw = base64.b64encode(key.public_key().public_bytes_raw()).decode()
    assert anchor["public_key"] == header["public_key"] == raw

    # A whole rewrite of chain and anchor by someone without the key is now visible.
    def rewrite(line: int, body: dict[str, Any]) -> None:
        if line == 2:
            body["command"]["reasons"] = ["nothing to see"]

    _rechain(log, rewrite)
    rewritten = verify_log(log)
    assert rewritten.status.value == "tampered", rewritten.describe()
    assert "signature does not verify" in rewritten.problem


@pytest.mark.requirement("SR-AUD-1", kind="example", code=KEYS)
def test_safecase_run_signs_with_the_configured_key(tmp_path: Path) -> None:
    key = _key_file(tmp_path / "k.pem")
    public = _public_file(tmp_path / "k.pub", key)
    config = tmp_path / "signed.toml"
    config.write_text(f'[audit]\nsign_head = true\nsigning_key = "{tmp_path / "k.pem"}"\n')
    log = tmp_path / "run.jsonl"
    done = run_safecase(
        "run", "--duration", "0.5", "--no-plot", "--audit", str(log), "--config", str(config)
    )
    assert done.returncode == 0, done.stdout + done.stderr
    verified = run_safecase("audit", "verify", str(log), "--public-key", str(public))
    assert verified.returncode == 0, verified.stdout + verified.stderr
    assert "signature valid (trusted key)" in verified.stdout


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _dir(path: Path) -> Path:
    path.mkdir()
    return path


def _text(path: Path) -> Path:
    path.write_text("not a key\n")
    return path


def _x25519(path: Path) -> Path:
    path.write_bytes(
        X25519PrivateKey.generate().private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return path


def _under_a_file(path: Path) -> Path:
    path.write_text("x")
    return path / "key.pem"  # ENOTDIR: exists in no way


def _huge(path: Path) -> Path:
    with path.open("wb") as handle:
        handle.truncate(64 << 20)  # sparse: no disk, but 64 MiB to whoever reads it
    return path


BAD_KEYS: dict[str, tuple[Callable[[Path], Path], str]] = {
    "missing": (lambda p: p, "no such file"),
    "directory": (_dir, "not a regular file"),
    "fifo": (_fifo, "not a regular file"),
    "device": (lambda p: Path("/dev/zero"), "not a regular file"),
    "text": (_text, "not a PEM private key"),
    "x25519": (_x25519, "expected an Ed25519 key"),
    "below a file": (_under_a_file, "cannot open"),
    "huge": (_huge, "bytes"),
}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=KEYS)
@pytest.mark.parametrize("case", sorted(BAD_KEYS))
def test_a_configured_key_that_cannot_be_used_stops_the_run_before_any_cycle(
    tmp_path: Path, case: str
) -> None:
    make, why = BAD_KEYS[case]
    key_path = make(tmp_path / "key.pem")
    config = _signed_config(str(key_path))
    log = tmp_path / "never.jsonl"
    cycles: list[object] = []
    with pytest.raises(SafecaseError) as caught:
        cycles.extend(run_audited(config, SimSource(make_simulation(config)), audit_path=log))
    message = str(caught.value)
    assert str(key_path) in message, message
    assert why in message, message
    assert isinstance(caught.value, ValueError)
    assert cycles == []
    assert not log.exists()
    if case == "missing":
        assert not key_path.exists()  # a configured key is never created


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file")
def test_an_unreadable_configured_key_names_the_path(tmp_path: Path) -> None:
    key_path = tmp_path / "key.pem"
    _key_file(key_path)
    key_path.chmod(0)
    with pytest.raises(SafecaseError, match=re.escape(str(key_path))):
        list(
            run_audited(
                _signed_config(str(key_path)),
                SimSource(make_simulation(CONFIG)),
                audit_path=tmp_path / "never.jsonl",
            )
        )


@pytest.mark.requirement("SR-AUD-1", kind="example", code=KEYS)
def test_sign_head_without_a_key_uses_the_default_key_created_on_first_use(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    default = tmp_path / "home" / "safecase" / "signing-key.pem"
    monkeypatch.setenv("SAFECASE_SIGNING_KEY", str(default))
    log = tmp_path / "default.jsonl"
    previous = os.umask(0)
    try:
        _short_run(_signed_config(""), log, scans=2)
    finally:
        os.umask(previous)
    assert stat.S_IMODE(default.stat().st_mode) == 0o600
    assert stat.S_IMODE(default.parent.stat().st_mode) == 0o700
    assert stat.S_IMODE(default.parent.parent.stat().st_mode) == 0o700
    key = serialization.load_pem_private_key(default.read_bytes(), password=None)
    assert isinstance(key, Ed25519PrivateKey)
    result = verify_log(log, trusted_key=key.public_key())
    assert result.ok, result.describe()


# ------------------------------------------------------------------ the anchor, byte for byte


def _anchor_edits() -> dict[str, Callable[[bytes], bytes]]:
    return {
        "renamed null public_key": lambda a: a.replace(b'"public_key":null', b'"public_kez":null'),
        "renamed null signature": lambda a: a.replace(b'"signature":null', b'"signaturf":null'),
        "renamed schema": lambda a: a.replace(b'"schema"', b'"schemb"'),
        "extra key": lambda a: a.replace(b'"closed"', b'"x":1,"closed"'),
        "spaces": lambda a: a.replace(b",", b", "),
        "no newline": lambda a: a.rstrip(b"\n"),
        "two newlines": lambda a: a + b"\n",
        "key order": lambda a: (
            json.dumps(dict(reversed(json.loads(a).items())), separators=(",", ":")).encode()
            + b"\n"
        ),
        "negative seq": lambda a: re.sub(rb'"seq":\d+', b'"seq":-1', a),
        "upper-case hash": lambda a: re.sub(
            rb'"hash":"([0-9a-f]+)"', lambda m: b'"hash":"' + m.group(1).upper() + b'"', a
        ),
    }


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
@pytest.mark.parametrize("edit", sorted(_anchor_edits()))
def test_any_change_of_the_anchor_bytes_is_tampering(tmp_path: Path, edit: str) -> None:
    log = _log(tmp_path)
    assert verify_log(log).ok
    head = anchor_path(log)
    original = head.read_bytes()
    changed = _anchor_edits()[edit](original)
    assert changed != original
    head.write_bytes(changed)
    result = verify_log(log)
    assert result.status.value == "tampered", (edit, result.describe())
    assert "(anchor)" in result.problem


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_a_signature_in_another_base64_spelling_is_tampering(tmp_path: Path) -> None:
    key = _key_file(tmp_path / "k.pem")
    log = _log(tmp_path, key=key)
    head = anchor_path(log)
    anchor = json.loads(head.read_bytes())
    # The last base64 digit of 64 bytes carries 4 unused bits: same bytes, other text.
    sig = anchor["signature"]
    alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/"
    last = sig[-3]
    sibling = alphabet[alphabet.index(last) ^ 1]
    anchor["signature"] = sig[:-3] + sibling + sig[-2:]
    assert base64.b64decode(anchor["signature"]) == base64.b64decode(sig)
    head.write_bytes(canonical_json(anchor) + b"\n")
    result = verify_log(log, trusted_key=key.public_key())
    assert result.status.value == "tampered", result.describe()


# ---------------------------------------------------- a missing anchor, an empty file: own verdicts


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_a_log_copied_without_its_anchor_is_unanchored_not_tampered(tmp_path: Path) -> None:
    log = _log(tmp_path)
    anchor_path(log).unlink()
    result = verify_log(log)
    assert result.status.value == "unanchored", result.describe()
    assert result.first_bad_line is None
    assert "truncation" in result.problem
    done = run_safecase("audit", "verify", str(log))
    assert done.returncode == 4, done.stdout + done.stderr
    assert done.stdout.startswith("UNANCHORED")
    # An edit is still an edit without the anchor.
    data = bytearray(log.read_bytes())
    data[data.index(b'"action":"') + 10] ^= 0x01
    log.write_bytes(bytes(data))
    assert verify_log(log).status.value == "tampered"
    # --no-anchor: the reader accepts that truncation cannot be seen.
    clean = _log(tmp_path, name="clean.log")
    anchor_path(clean).unlink()
    assert run_safecase("audit", "verify", "--no-anchor", str(clean)).returncode == 0


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_an_empty_file_is_not_a_log(tmp_path: Path) -> None:
    empty = tmp_path / "empty.log"
    empty.write_bytes(b"")
    result = verify_log(empty)
    assert result.status.value == "empty", result.describe()
    for command in ("verify", "show", "tail", "replay"):
        done = _cli("audit", command, str(empty))
        assert done.returncode == 5, (command, done.stdout, done.stderr)
        assert "EMPTY" in done.stdout, (command, done.stdout)
        assert "not an audit log" in done.stdout
    real = run_safecase("audit", "verify", str(empty))
    assert real.returncode == 5, real.stdout + real.stderr
    # With an anchor that says records were written, an empty log was truncated.
    log = _log(tmp_path)
    log.write_bytes(b"")
    assert verify_log(log).status.value == "tampered"


# ----------------------------------------------------------- malformed input: never a traceback


def _replace_line(log: Path, number: int, raw: bytes) -> None:
    lines = log.read_bytes().split(b"\n")
    lines[number - 1] = raw
    log.write_bytes(b"\n".join(lines))


MALFORMED: dict[str, bytes] = {
    "deep arrays": b"[" * 100_000 + b"]" * 100_000,
    "deep objects": b'{"a":' * 50_000 + b"1" + b"}" * 50_000,
    "huge integer": b'{"hash":"x","kind":"cycle","prev":"y","seq":' + b"9" * 5000 + b"}",
    "huge float": b'{"seq":1e999999}',
    "not utf-8": b"\xff\xfe{}",
}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_lines_are_tampering_at_their_line(tmp_path: Path, case: str) -> None:
    log = _log(tmp_path)
    _replace_line(log, 3, MALFORMED[case])
    result = verify_log(log)
    assert result.status.value == "tampered", result.describe()
    assert result.first_bad_line == 3
    assert len(result.describe()) < 400
    for command in ("verify", "show", "tail", "replay"):
        done = _cli("audit", command, str(log))
        assert done.returncode == 1, (command, done.stdout, done.stderr[-500:])
        assert "TAMPERED at line 3" in done.stdout, (command, done.stdout)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_a_malformed_anchor_is_tampering(tmp_path: Path, case: str) -> None:
    log = _log(tmp_path)
    anchor_path(log).write_bytes(MALFORMED[case] + b"\n")
    result = verify_log(log)
    assert result.status.value == "tampered", result.describe()
    assert "(anchor)" in result.problem
    assert _cli("audit", "verify", str(log)).returncode == 1


def _drop(field: str, line: int) -> Callable[[int, dict[str, Any]], None]:
    def edit(number: int, body: dict[str, Any]) -> None:
        if number == line:
            del body[field]

    return edit


def _set(path: tuple[str, ...], value: Any, line: int) -> Callable[[int, dict[str, Any]], None]:
    def edit(number: int, body: dict[str, Any]) -> None:
        if number == line:
            target = body
            for key in path[:-1]:
                target = target[key]
            target[path[-1]] = value

    return edit


RECHAINED: dict[str, tuple[Callable[[int, dict[str, Any]], None], int]] = {
    "cycle without command": (_drop("command", 2), 2),
    "cycle without inputs": (_drop("inputs", 3), 3),
    "cycle without timings": (_drop("timings_s", 2), 2),
    "header without latency": (_drop("latency", 1), 1),
    "header without config hash": (_drop("config_hash", 1), 1),
    "command action a number": (_set(("command", "action"), 3, 2), 2),
    "speed a huge integer": (_set(("command", "speed_mps"), 10**400, 2), 2),
    "stamp a huge integer": (_set(("stamp_s",), -(10**4000), 3), 3),
    "inputs a list": (_set(("inputs",), [1, 2], 2), 2),
    "tracker a list": (_set(("inputs", "tracker"), [1], 2), 2),
    "reasons not text": (_set(("command", "reasons"), [{"a": 1}], 2), 2),
    "close count text": (_set(("n_records",), "6", 6), 6),
}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
@pytest.mark.parametrize("case", sorted(RECHAINED))
def test_a_rechained_record_lacking_fields_never_raises(tmp_path: Path, case: str) -> None:
    log = _log(tmp_path)
    edit, line = RECHAINED[case]
    _rechain(log, edit)
    result = verify_log(log)
    for command in ("verify", "show", "tail", "replay"):
        done = _cli("audit", command, str(log))
        assert done.returncode in (0, 1), (command, done.stdout, done.stderr[-800:])
    replay(log)
    if case == "tracker a list":
        # Free-form inputs the writer does not constrain: intact, and shown without error.
        assert result.ok, result.describe()
        return
    assert result.status.value == "tampered", (case, result.describe())
    assert result.first_bad_line == line, result.describe()
    assert "forged" in result.problem or "edited" in result.problem


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_a_trusted_key_that_is_a_device_or_fifo_is_a_one_line_error(tmp_path: Path) -> None:
    log = _log(tmp_path)
    for key in (Path("/dev/zero"), _fifo(tmp_path / "fifo"), tmp_path):
        # A subprocess with a time limit: reading a FIFO or /dev/zero would never return.
        done = run_safecase("audit", "verify", str(log), "--public-key", str(key), timeout_s=30)
        _no_traceback(done)
        assert done.returncode == 2, (key, done.stdout, done.stderr)
        assert str(key) in done.stderr
        assert "not a regular file" in done.stderr
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    for command in ("show", "replay"):
        inproc = _cli("audit", command, str(log), "--public-key", str(tmp_path))
        assert inproc.returncode == 2, (command, inproc.stdout, inproc.stderr)
        assert "not a regular file" in inproc.stderr


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_a_log_that_is_a_device_or_fifo_is_a_one_line_error(tmp_path: Path) -> None:
    for log in (Path("/dev/zero"), _fifo(tmp_path / "fifo.log"), tmp_path):
        done = run_safecase("audit", "verify", str(log), timeout_s=30)
        _no_traceback(done)
        assert done.returncode == 2, (log, done.stdout, done.stderr)
        assert "not a regular file" in done.stderr, done.stderr


@pytest.mark.requirement("SR-AUD-1", kind="example", code=AUDIT)
def test_existing_logs_still_verify_intact(tmp_path: Path) -> None:
    key = _key_file(tmp_path / "k.pem")
    for signed in (None, key):
        log = _log(tmp_path, name=f"{signed is None}.log", key=signed)
        trusted = None if signed is None else signed.public_key()
        result = verify_log(log, trusted_key=trusted)
        assert result.ok, result.describe()
        assert _cli("audit", "show", str(log)).returncode == 0
