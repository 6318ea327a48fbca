"""The audit log's byte forms and line reader, each output compared whole (SR-AUD-1, SR-AUD-2).

:mod:`safety.audit.log` fixes the bytes everything else hashes, signs and verifies: the
canonical JSON of a record, the SHA-256 chaining a record to the one before, the head anchor's
path, file bytes and signed message, the key that signs it, the summary and body of a cycle,
and how a log file is cut into lines. Each expected value here is built independently (json
with its own arguments, hashlib, literal bytes), so a changed separator, key, branch or bound
in the module shows as a difference, not as the same mistake made twice.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from pipeline.config import AuditSection
from pipeline.types import Action, Command, Scan
from safety.audit.keys import SigningKeyError, private_key_pem
from safety.audit.log import (
    GENESIS,
    MAX_RECORD_BYTES,
    SCHEMA,
    AuditError,
    CycleRecord,
    RecordTooLongError,
    anchor_bytes,
    anchor_message,
    anchor_path,
    canonical_json,
    iter_lines,
    record_hash,
    signing_key_for,
    summarize,
)
from safety.model.decision import Decision, GovernorInputs
from safety.model.monitors import MonitorVerdict, Observation

CODE = ["safety/audit/log.py"]
HEAD = "cd" * 32
HEADER = "ab" * 32


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# ------------------------------------------------------------------ canonical JSON and hashes


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_canonical_json_sorts_keys_at_every_depth_without_whitespace() -> None:
    value = {"b": 1, "a": {"d": [3, {"f": 4, "e": 5}], "c": None}, "A": True}
    assert canonical_json(value) == b'{"A":true,"a":{"c":null,"d":[3,{"e":5,"f":4}]},"b":1}'
    assert canonical_json([1, "two", 3.5, False]) == b'[1,"two",3.5,false]'
    assert canonical_json((0.1, 1e-07, 10**20)) == b"[0.1,1e-07,100000000000000000000]"


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_canonical_json_writes_non_finite_floats_as_text() -> None:
    value = {"x": math.nan, "y": math.inf, "z": -math.inf, "w": [np.float64(math.inf)]}
    assert canonical_json(value) == b'{"w":["inf"],"x":"nan","y":"inf","z":"-inf"}'


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_canonical_json_escapes_everything_outside_ascii() -> None:
    encoded = canonical_json({"name": "Zo\u00eb \u2603 \U0001d11e", "nl": 'a\nb"c'})
    assert encoded == b'{"name":"Zo\\u00eb \\u2603 \\ud834\\udd1e","nl":"a\\nb\\"c"}'
    assert isinstance(encoded, bytes)
    assert json.loads(encoded) == {"name": "Zo\u00eb \u2603 \U0001d11e", "nl": 'a\nb"c'}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_record_hash_is_sha256_of_the_previous_hash_and_the_canonical_body() -> None:
    first = {"kind": "header", "seq": 0, "prev": GENESIS, "x": "\u00e9"}
    h1 = record_hash(GENESIS, first)
    assert h1 == _sha256(
        b"0" * 64 + b'{"kind":"header","prev":"' + b"0" * 64 + b'","seq":0,"x":"\\u00e9"}'
    )
    second = {"seq": 1, "prev": h1, "kind": "cycle"}
    h2 = record_hash(h1, second)
    assert h2 == _sha256(h1.encode() + b'{"kind":"cycle","prev":"' + h1.encode() + b'","seq":1}')
    third = {"seq": 2, "prev": h2, "kind": "close", "n_records": 2}
    assert record_hash(h2, third) == _sha256(
        h2.encode() + b'{"kind":"close","n_records":2,"prev":"' + h2.encode() + b'","seq":2}'
    )
    assert record_hash(GENESIS, {}) == _sha256(b"0" * 64 + b"{}")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_previous_hash_that_is_not_ascii_is_refused_not_hashed() -> None:
    # A previous hash is hex; anything else must fail loudly rather than chain.
    with pytest.raises(UnicodeEncodeError):
        record_hash("\u00e9" * 64, {})


# ------------------------------------------------------------------ the head anchor's forms


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_anchor_lives_beside_the_log_with_head_appended_to_its_name() -> None:
    assert anchor_path(Path("/var/log/run.log")) == Path("/var/log/run.log.head")
    assert anchor_path(Path("logs/a.b.jsonl")) == Path("logs/a.b.jsonl.head")
    assert anchor_path(Path("plain")) == Path("plain.head")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_signed_message_names_schema_header_seq_head_and_state() -> None:
    closed = anchor_message(HEADER, 7, HEAD, True)
    assert closed == f"safecase-audit/1|{HEADER}|7|{HEAD}|closed".encode("ascii")
    assert anchor_message(HEADER, 0, HEAD, False) == (
        f"safecase-audit/1|{HEADER}|0|{HEAD}|open".encode("ascii")
    )
    assert SCHEMA == "safecase-audit/1"
    assert GENESIS == "0" * 64


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_anchor_file_is_its_canonical_json_and_one_newline() -> None:
    anchor = {
        "signature": None,
        "seq": 12,
        "schema": SCHEMA,
        "public_key": None,
        "hash": HEAD,
        "header_hash": HEADER,
        "closed": False,
    }
    assert anchor_bytes(anchor) == (
        b'{"closed":false,"hash":"'
        + HEAD.encode()
        + b'","header_hash":"'
        + HEADER.encode()
        + b'","public_key":null,"schema":"safecase-audit/1","seq":12,"signature":null}\n'
    )


# ------------------------------------------------------------------ which key signs the head


def _key_file(path: Path) -> Ed25519PrivateKey:
    key = Ed25519PrivateKey.generate()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(private_key_pem(key))
    return key


def _raw(key: Ed25519PrivateKey) -> bytes:
    return key.public_key().public_bytes_raw()


@pytest.fixture
def default_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Where the default signing key goes in these tests: never the real home."""
    path = tmp_path / "default" / "signing-key.pem"
    monkeypatch.setenv("SAFECASE_SIGNING_KEY", str(path))
    return path


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_no_key_signs_unless_sign_head_even_when_a_key_is_named(
    tmp_path: Path, default_key: Path
) -> None:
    missing = tmp_path / "missing.pem"
    assert signing_key_for(AuditSection()) is None
    assert signing_key_for(AuditSection(sign_head=False, signing_key=str(missing))) is None
    assert not missing.exists()
    assert not default_key.exists()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_configured_key_is_loaded_from_its_path(tmp_path: Path, default_key: Path) -> None:
    path = tmp_path / "keys" / "head.pem"
    key = _key_file(path)
    loaded = signing_key_for(AuditSection(sign_head=True, signing_key=str(path)))
    assert loaded is not None
    assert _raw(loaded) == _raw(key)
    assert not default_key.exists()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_configured_key_under_home_is_found_through_the_tilde(
    tmp_path: Path, default_key: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    home = tmp_path / "home"
    key = _key_file(home / "keys" / "head.pem")
    monkeypatch.setenv("HOME", str(home))
    loaded = signing_key_for(AuditSection(sign_head=True, signing_key="~/keys/head.pem"))
    assert loaded is not None
    assert _raw(loaded) == _raw(key)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_configured_key_that_is_missing_is_refused_naming_it_and_never_created(
    tmp_path: Path, default_key: Path
) -> None:
    missing = tmp_path / "missing.pem"
    with pytest.raises(SigningKeyError) as caught:
        signing_key_for(AuditSection(sign_head=True, signing_key=str(missing)))
    assert str(caught.value) == f"signing key {missing}: no such file"
    assert not missing.exists()
    assert not default_key.exists()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_sign_head_without_a_key_creates_the_default_key_once_and_reuses_it(
    default_key: Path,
) -> None:
    section = AuditSection(sign_head=True)
    first = signing_key_for(section)
    assert first is not None
    assert default_key.is_file()
    second = signing_key_for(section)
    assert second is not None
    assert _raw(second) == _raw(first)


# ------------------------------------------------------------------ a cycle's summary and body


@dataclass(frozen=True)
class Counts:
    kept: int
    dropped: int
    worst_s: float


def _scan() -> Scan:
    return Scan(
        stamp_s=12.5,
        angles_rad=np.array([0.0, 0.5, 1.0]),
        ranges_m=np.array([1.0, np.nan, 2.0]),
        seq=42,
        source="lidar0",
        complete=False,
    )


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_summary_reduces_a_scan_to_its_seq_stamp_source_beams_and_completeness() -> None:
    assert summarize(scan=_scan()) == {
        "scan": {
            "seq": 42,
            "stamp_s": 12.5,
            "source": "lidar0",
            "n_beams": 3,
            "complete": False,
        }
    }


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_summary_keeps_a_scan_under_another_name_and_a_scan_part_that_is_no_scan() -> None:
    assert summarize(previous=_scan()) == {
        "previous": {
            "stamp_s": 12.5,
            "angles_rad": [0.0, 0.5, 1.0],
            "ranges_m": [1.0, "nan", 2.0],
            "intensities": None,
            "beam_period_s": 0.0,
            "seq": 42,
            "source": "lidar0",
            "complete": False,
        }
    }
    assert summarize(scan={"seq": 3, "late_s": math.inf}) == {"scan": {"seq": 3, "late_s": "inf"}}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_summary_leaves_out_none_parts_and_keeps_the_ones_after() -> None:
    assert summarize(a=1, b=None, c=2, d=None) == {"a": 1, "c": 2}
    assert summarize(only=None) == {}
    assert summarize() == {}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_summary_makes_dataclasses_enums_and_floats_json_ready() -> None:
    summary = summarize(
        counts=Counts(kept=5, dropped=2, worst_s=-math.inf),
        action=Action.SLOW,
        late_s=math.nan,
        ids=(1, 2),
        name="x",
    )
    assert summary == {
        "counts": {"kept": 5, "dropped": 2, "worst_s": "-inf"},
        "action": "SLOW",
        "late_s": "nan",
        "ids": [1, 2],
        "name": "x",
    }
    # Parts keep the order they were given in.
    assert list(summary) == ["counts", "action", "late_s", "ids", "name"]


def _observation(now_s: float) -> Observation:
    return Observation(
        now_s=now_s,
        previous_now_s=2.4,
        scan_stamp_s=2.45,
        scan_complete=True,
        n_beams=360,
        n_below_min=3,
        driver_state="ok",
        driver_age_s=0.01,
        cycle_duration_s=0.02,
        over_cap=(("cluster.max_clusters", 2),),
    )


STOP = Command(Action.STOP, 0.0, 2.5, ("deadline: late",))
SLOW = Command(Action.SLOW, 0.5, 2.5, ("zone",))
VERDICTS = (MonitorVerdict.ok("freshness"), MonitorVerdict.stop("deadline", "late"))


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_a_cycle_body_holds_everything_decide_read_and_returned() -> None:
    observation = _observation(2.5)
    inputs = GovernorInputs(
        stamp_s=2.5,
        free_distance_m=np.array([1.5, np.inf]),
        confidence=np.array([0.9, 0.4]),
        near_reversal=np.array([False, True]),
    )
    record = CycleRecord(
        observation,
        Decision(STOP, SLOW, VERDICTS),
        inputs,
        {"n_tracks": 2, "late_s": math.nan, "ids": (1, 2)},
        {"points": 0.001, "total": math.inf},
    )
    assert record.body() == {
        "stamp_s": 2.5,
        "inputs": {"n_tracks": 2, "late_s": "nan", "ids": [1, 2]},
        "observation": observation.to_dict(),
        "governor_inputs": {
            "stamp_s": 2.5,
            "free_distance_m": [1.5, "inf"],
            "closing_speed_mps": None,
            "confidence": [0.9, 0.4],
            "near_reversal": [False, True],
        },
        "governor_command": {
            "action": "SLOW",
            "speed_mps": 0.5,
            "stamp_s": 2.5,
            "reasons": ["zone"],
        },
        "verdicts": [
            {"monitor": "freshness", "action": "PROCEED", "speed_limit_mps": None, "reason": ""},
            {"monitor": "deadline", "action": "STOP", "speed_limit_mps": 0.0, "reason": "late"},
        ],
        "command": {
            "action": "STOP",
            "speed_mps": 0.0,
            "stamp_s": 2.5,
            "reasons": ["deadline: late"],
        },
        "timings_s": {"points": 0.001, "total": "inf"},
    }
    assert observation.to_dict()["over_cap"] == {"cluster.max_clusters": 2}


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_a_cycle_without_governor_inputs_records_nulls_and_empty_mappings() -> None:
    observation = _observation(math.inf)
    body = CycleRecord(observation, Decision(STOP, None, ()), None).body()
    assert body == {
        "stamp_s": "inf",
        "inputs": {},
        "observation": observation.to_dict(),
        "governor_inputs": None,
        "governor_command": None,
        "verdicts": [],
        "command": {
            "action": "STOP",
            "speed_mps": 0.0,
            "stamp_s": 2.5,
            "reasons": ["deadline: late"],
        },
        "timings_s": {},
    }
    # The body is JSON-ready as it stands: canonical JSON has nothing left to convert.
    assert canonical_json(body) == json.dumps(
        body, sort_keys=True, separators=(",", ":"), allow_nan=False
    ).encode("ascii")


# ------------------------------------------------------------------ cutting a log into lines


def _file(tmp_path: Path, data: bytes) -> Path:
    path = tmp_path / "run.log"
    path.write_bytes(data)
    return path


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_complete_lines_come_numbered_from_one_without_their_newline(tmp_path: Path) -> None:
    path = _file(tmp_path, b'{"a":1}\n\n{"b":2}\r\n{"c":3}\n')
    assert list(iter_lines(path)) == [
        (1, b'{"a":1}', True),
        (2, b"", True),
        (3, b'{"b":2}\r', True),
        (4, b'{"c":3}', True),
    ]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_last_line_without_newline_comes_whole_and_unterminated(tmp_path: Path) -> None:
    assert list(iter_lines(_file(tmp_path, b"one\ntwo"))) == [(1, b"one", True), (2, b"two", False)]
    assert list(iter_lines(_file(tmp_path, b"x"))) == [(1, b"x", False)]
    assert list(iter_lines(_file(tmp_path, b"\n"))) == [(1, b"", True)]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_an_empty_file_has_no_lines(tmp_path: Path) -> None:
    assert list(iter_lines(_file(tmp_path, b""))) == []


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_path_that_is_not_a_readable_regular_file_is_an_audit_error(tmp_path: Path) -> None:
    missing = tmp_path / "missing.log"
    with pytest.raises(AuditError) as caught:
        list(iter_lines(missing))
    assert str(caught.value) == f"audit log {missing}: no such file"
    assert not isinstance(caught.value, RecordTooLongError)
    with pytest.raises(AuditError) as caught:
        list(iter_lines(tmp_path))
    assert str(caught.value) == f"audit log {tmp_path}: not a regular file (a directory)"


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_line_of_exactly_the_limit_is_read_whole_terminated_or_not(tmp_path: Path) -> None:
    assert MAX_RECORD_BYTES == 16 * 1024 * 1024
    longest = b"x" * MAX_RECORD_BYTES
    path = _file(tmp_path, longest + b"\n" + b"y\n" + longest)
    assert list(iter_lines(path)) == [(1, longest, True), (2, b"y", True), (3, longest, False)]


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
@pytest.mark.parametrize("tail", [b"\nmore\n", b""], ids=["terminated", "at-the-end"])
def test_a_line_one_byte_over_the_limit_is_refused_with_its_number(
    tmp_path: Path, tail: bytes
) -> None:
    path = _file(tmp_path, b"ok\n" + b"z" * (MAX_RECORD_BYTES + 1) + tail)
    lines = iter_lines(path)
    assert next(lines) == (1, b"ok", True)
    with pytest.raises(RecordTooLongError) as caught:
        next(lines)
    assert caught.value.line == 2
    assert str(caught.value) == f"audit log {path}: line 2 is longer than 16777216 bytes"
    assert isinstance(caught.value, AuditError)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_too_long_error_names_the_path_and_line_it_is_given() -> None:
    error = RecordTooLongError(Path("/x/a.log"), 9)
    assert error.line == 9
    assert str(error) == "audit log /x/a.log: line 9 is longer than 16777216 bytes"
