"""Replay of a log whose records were forged with correct hashes (SR-AUD-2).

A log re-chained by someone who knows the hash function passes ``audit verify`` without its
signed anchor; replay is what still catches a forged decision. Each test here forges one thing
and checks what replay reports: which line, which value, what was recorded and what the
governor decides from the recorded inputs.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from pipeline.config import default_config
from properties.audit_cases import write_random_log
from safety.audit.log import GENESIS, AuditError, anchor_path, canonical_json, record_hash
from safety.audit.replay import ReplayMismatch, governor_for, replay
from safety.audit.verify import AuditStatus
from safety.model.decision import decide
from safety.model.monitors import Observation

CODE = ["safety/audit/replay.py"]
# Seed 17 writes a stage's STOP verdict (a failed tracker) into the first cycle (line 2).
SEED = 17


def _log(tmp_path: Path) -> tuple[Path, list[dict[str, Any]]]:
    log = tmp_path / "run.log"
    write_random_log(log, default_config(), np.random.default_rng(SEED), 4)
    anchor_path(log).unlink()
    return log, [json.loads(line) for line in log.read_bytes().splitlines()]


def _forge(log: Path, records: list[dict[str, Any]]) -> None:
    """Write ``records`` re-chained: every prev and hash recomputed."""
    prev, lines = GENESIS, []
    for record in records:
        body = {k: v for k, v in record.items() if k != "hash"} | {"prev": prev}
        prev = record_hash(prev, body)
        lines.append(canonical_json(body | {"hash": prev}) + b"\n")
    log.write_bytes(b"".join(lines))


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_every_cycle_is_reproduced_including_a_failed_stage(tmp_path: Path) -> None:
    log, records = _log(tmp_path)
    assert "stage:track" in [v["monitor"] for v in records[1]["verdicts"]]
    report = replay(log, require_anchor=False)
    assert (report.n_cycles, report.n_reproduced, report.mismatches, report.refused) == (
        4,
        4,
        [],
        "",
    )
    assert report.ok


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_a_forged_command_is_a_mismatch_of_its_line(tmp_path: Path) -> None:
    log, records = _log(tmp_path)
    recorded = records[2]["command"]
    forged = recorded | {"action": "PROCEED" if recorded["action"] != "PROCEED" else "STOP"}
    records[2] = records[2] | {"command": forged}
    # The failed stage's verdict dropped from the record: without it the decision differs.
    records[1] = records[1] | {
        "verdicts": [v for v in records[1]["verdicts"] if v["monitor"] != "stage:track"]
    }
    _forge(log, records)
    report = replay(log, require_anchor=False)
    assert not report.ok
    assert (report.n_cycles, report.n_reproduced) == (4, 2)
    by_line = {m.line: m for m in report.mismatches}
    assert by_line[3] == ReplayMismatch(3, 2, "command", forged, recorded)
    assert by_line[2].what in {"verdicts", "command"}


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_recorded_values_that_cannot_be_decided_are_reported_not_raised(tmp_path: Path) -> None:
    log, records = _log(tmp_path)
    records[2] = records[2] | {"observation": {}}
    records[3] = records[3] | {"governor_inputs": {"stamp_s": 1.0}}
    # A list where the runtime writes a mapping of counters.
    records[4] = records[4] | {"observation": records[4]["observation"] | {"over_cap": [1]}}
    _forge(log, records)
    report = replay(log, require_anchor=False)
    assert [(m.line, m.seq, m.what, m.recorded) for m in report.mismatches] == [
        (3, 2, "inputs", "undecodable"),
        (4, 3, "inputs", "undecodable"),
        (5, 4, "inputs", "undecodable"),
    ]
    assert report.mismatches[0].replayed.startswith("KeyError(")
    assert report.mismatches[2].replayed == (
        "ValueError('over_cap: expected a mapping of cap name to count, got [1]')"
    )
    assert (report.n_cycles, report.n_reproduced) == (4, 1)


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_a_tampered_or_empty_log_is_not_replayed(tmp_path: Path) -> None:
    log, _ = _log(tmp_path)
    lines = log.read_bytes().splitlines(keepends=True)
    log.write_bytes(b"".join(lines[:2] + lines[3:]))
    report = replay(log, require_anchor=False)
    assert report.refused == (
        "not replayed: the log is tampered (TAMPERED at line 3: records seq 2..2 missing: "
        f"deleted (or reordered) ({report.verification.n_records} records, "
        f"{report.verification.n_cycles} cycles, head seq 1, signature absent))"
    )
    assert (report.n_cycles, report.ok) == (0, False)
    log.write_bytes(b"")
    empty = replay(log, require_anchor=False)
    assert empty.refused == "not replayed: the log has no header (not an audit log)"
    assert not empty.ok


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_a_header_that_does_not_give_a_governor_is_an_error_saying_why(tmp_path: Path) -> None:
    _, records = _log(tmp_path)
    header = records[0]
    config, governor = governor_for(header)
    assert config == default_config()
    assert governor.params.perception_latency_s == header["latency"]["perception_latency_s"]
    assert governor.params.latency_source == header["latency"]["latency_source"]
    broken = header | {"config": header["config"] | {"stopping": {"decel_min_mps2": -1}}}
    with pytest.raises(AuditError) as refused:
        governor_for(broken)
    assert str(refused.value) == (
        "audit header: configuration does not load: audit header: stopping.decel_min_mps2 = -1: "
        "Input should be greater than 0; allowed: a number > 0.0 and <= 20.0"
    )
    # The governor runs with the header's latency bound, not the configuration's.
    bench = header | {"latency": {"perception_latency_s": 0.25, "latency_source": "bench"}}
    _, measured = governor_for(bench)
    assert (measured.params.perception_latency_s, measured.params.latency_source) == (
        0.25,
        "bench",
    )
    assert measured.params.reaction_s > governor.params.reaction_s
    other = header | {"config_hash": "ab" * 32}
    with pytest.raises(AuditError) as caught:
        governor_for(other)
    assert str(caught.value) == (
        f"audit header: configuration hashes to {header['config_hash'][:16]}, the header "
        "records abababababababab"
    )
    late = header | {"latency": {"perception_latency_s": "soon", "latency_source": "x"}}
    with pytest.raises(AuditError, match=r"^audit header: latency bound unusable: "):
        governor_for(late)


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_replay_verifies_first_with_the_anchor_and_the_trusted_key_it_is_given(
    tmp_path: Path,
) -> None:
    unanchored, _ = _log(tmp_path)
    assert replay(unanchored).verification.status is AuditStatus.UNANCHORED
    assert replay(unanchored, require_anchor=False).verification.status is AuditStatus.INTACT
    key, other = Ed25519PrivateKey.generate(), Ed25519PrivateKey.generate()
    signed = tmp_path / "signed.log"
    write_random_log(signed, default_config(), np.random.default_rng(SEED), 2, key=key)
    assert replay(signed, trusted_key=key.public_key()).ok
    stranger = replay(signed, trusted_key=other.public_key())
    assert stranger.verification.status is AuditStatus.TAMPERED
    assert stranger.refused.startswith("not replayed: the log is tampered (TAMPERED: ")


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_a_decision_that_raises_is_reported_and_the_replay_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No decodable record found so far makes the decision raise (it fails safe instead); the
    replay still must not stop on one, so one is made to raise here, on the third line."""
    log, _ = _log(tmp_path)
    real = decide
    calls = []

    def decide_or_raise(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        if len(calls) == 2:
            raise ArithmeticError("x" * 300)
        return real(*args, **kwargs)

    monkeypatch.setattr("safety.audit.replay.decide", decide_or_raise)
    report = replay(log, require_anchor=False)
    assert report.mismatches == [
        ReplayMismatch(3, 2, "decision", "recorded", repr(ArithmeticError("x" * 300))[:200])
    ]
    assert (report.n_cycles, report.n_reproduced, len(calls)) == (4, 3, 4)


@pytest.mark.requirement("SR-AUD-2", kind="example", code=CODE)
def test_an_undecodable_records_reason_is_cut_to_200_characters(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    log, _ = _log(tmp_path)

    def refuse(value: Any) -> Any:
        raise ValueError("y" * 300)

    monkeypatch.setattr(Observation, "from_dict", staticmethod(refuse))
    report = replay(log, require_anchor=False)
    assert [m.replayed for m in report.mismatches] == [repr(ValueError("y" * 300))[:200]] * 4
    assert len(report.mismatches[0].replayed) == 200
