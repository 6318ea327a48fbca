"""Each check of an audit record, met alone and named (SR-AUD-1).

The log tests (tests/safety/test_audit*.py) edit real logs and check the verdict and the line.
Here a record that passes every check but one is built for each check of
:func:`~safety.audit.records.parse_record` and :func:`~safety.audit.records.structure_problem`,
and the problem it reports is compared whole: a reader of ``audit verify`` is told what was
edited, so the sentence is part of the result.
"""

from __future__ import annotations

import json
from typing import Any

import pytest

from safety.audit.log import canonical_json
from safety.audit.records import (
    INT_LIMIT,
    MAX_DEPTH,
    BadRecordError,
    json_problem,
    parse_record,
    strict_b64,
    structure_problem,
)

CODE = ["safety/audit/records.py"]
HASH = "ab" * 32
COMMAND = {"action": "STOP", "speed_mps": 0.0, "stamp_s": 1.5, "reasons": ["zone"]}
VERDICT = {"monitor": "freshness", "action": "PROCEED", "speed_limit_mps": None, "reason": ""}


def _chain(kind: str, **body: Any) -> dict[str, Any]:
    return {"kind": kind, "seq": 3, "prev": HASH, "hash": HASH, **body}


def _header(**changes: Any) -> dict[str, Any]:
    return (
        _chain(
            "header",
            schema="safecase-audit/1",
            created_utc="2026-11-27T00:00:00Z",
            config_hash=HASH,
            config={},
            model_hash=None,
            latency={"perception_latency_s": 0.18, "latency_source": "measured"},
            software={},
            public_key=None,
        )
        | changes
    )


def _cycle(**changes: Any) -> dict[str, Any]:
    return (
        _chain(
            "cycle",
            stamp_s=1.5,
            inputs={},
            observation={},
            governor_inputs=None,
            governor_command=None,
            verdicts=[VERDICT],
            command=COMMAND,
            timings_s={"total": 0.01, "late": "nan"},
        )
        | changes
    )


def test_the_records_the_writer_writes_have_no_problem() -> None:
    signed = _header(public_key="A" * 43 + "=", model_hash=HASH)
    assert strict_b64(signed["public_key"], 32) == bytes(32)
    for record in (
        _header(),
        signed,
        _cycle(),
        _cycle(governor_inputs={"v": 1.0}, governor_command=COMMAND, stamp_s="inf"),
        _cycle(verdicts=[], timings_s={}),
        _cycle(verdicts=[VERDICT | {"speed_limit_mps": 0.5}]),
        _chain("close", n_records=7),
        _chain("note", anything=1),  # an unknown kind is reported by the verifier, not here
    ):
        assert structure_problem(record) is None, record


STRUCTURE: dict[str, tuple[dict[str, Any], str]] = {
    "header without a key": (
        {k: v for k, v in _header().items() if k not in ("config", "software")},
        "a header record without config, software",
    ),
    "header with a key more": (_header(extra=1), "a header record with unknown extra"),
    "header with two keys more": (
        _header(extra=1, more=2),
        "a header record with unknown extra, more",
    ),
    "cycle both": (
        {k: v for k, v in _cycle(zz=1).items() if k != "inputs"},
        "a cycle record without inputs and with unknown zz",
    ),
    "schema": (_header(schema=1), "a header without its schema or creation time"),
    "created": (_header(created_utc=None), "a header without its schema or creation time"),
    "config hash": (_header(config_hash="AB" * 32), "a header without a configuration hash"),
    "config hash type": (_header(config_hash=1), "a header without a configuration hash"),
    "config": (
        _header(config=[]),
        "a header without its configuration or software versions",
    ),
    "software": (
        _header(software="1.0"),
        "a header without its configuration or software versions",
    ),
    "model hash": (_header(model_hash=1), "a header whose model hash is not text"),
    "latency keys": (
        _header(latency={"perception_latency_s": 0.18}),
        "a header without its latency bound",
    ),
    "latency list": (_header(latency=[0.18]), "a header without its latency bound"),
    "latency value": (
        _header(latency={"perception_latency_s": True, "latency_source": "x"}),
        "a header without its latency bound",
    ),
    "latency source": (
        _header(latency={"perception_latency_s": 0.1, "latency_source": None}),
        "a header without its latency bound",
    ),
    "public key": (
        _header(public_key="A" * 42 + "=="),
        "a header whose public key is not 32 bytes of base64",
    ),
    "stamp": (_cycle(stamp_s="soon"), "a cycle without its stamp"),
    "stamp bool": (_cycle(stamp_s=True), "a cycle without its stamp"),
    "inputs": (_cycle(inputs=[]), "a cycle without its inputs or observation"),
    "observation": (_cycle(observation=None), "a cycle without its inputs or observation"),
    "governor inputs": (
        _cycle(governor_inputs=[]),
        "a cycle whose governor inputs are not a mapping",
    ),
    "command": (_cycle(command=None), "a cycle with not a command"),
    "command keys": (
        _cycle(command={k: v for k, v in COMMAND.items() if k != "reasons"}),
        "a cycle with not a command",
    ),
    "action": (
        _cycle(command=COMMAND | {"action": 1}),
        "a cycle with a command without its action or speed",
    ),
    "speed": (
        _cycle(command=COMMAND | {"speed_mps": "0"}),
        "a cycle with a command without its action or speed",
    ),
    "command stamp": (
        _cycle(command=COMMAND | {"stamp_s": "later"}),
        "a cycle with a command without its stamp or reasons",
    ),
    "reasons": (
        _cycle(command=COMMAND | {"reasons": ["a", 1]}),
        "a cycle with a command without its stamp or reasons",
    ),
    "reasons text": (
        _cycle(command=COMMAND | {"reasons": "zone"}),
        "a cycle with a command without its stamp or reasons",
    ),
    "governor command": (
        _cycle(governor_command=COMMAND | {"speed_mps": None}),
        "a cycle with a command without its action or speed",
    ),
    "verdicts": (_cycle(verdicts={}), "a cycle whose verdicts are not verdicts"),
    "verdict keys": (
        _cycle(verdicts=[VERDICT | {"extra": 1}]),
        "a cycle whose verdicts are not verdicts",
    ),
    "verdict monitor": (
        _cycle(verdicts=[VERDICT, VERDICT | {"monitor": 1}]),
        "a cycle whose verdicts are not verdicts",
    ),
    "verdict action": (
        _cycle(verdicts=[VERDICT | {"action": None}]),
        "a cycle whose verdicts are not verdicts",
    ),
    "verdict limit": (
        _cycle(verdicts=[VERDICT | {"speed_limit_mps": "1"}]),
        "a cycle whose verdicts are not verdicts",
    ),
    "verdict reason": (
        _cycle(verdicts=[VERDICT | {"reason": None}]),
        "a cycle whose verdicts are not verdicts",
    ),
    "verdict not a mapping": (_cycle(verdicts=[[]]), "a cycle whose verdicts are not verdicts"),
    "timings": (_cycle(timings_s=[0.01]), "a cycle whose timings are not numbers"),
    "timing": (
        _cycle(timings_s={"total": 0.01, "x": "slow"}),
        "a cycle whose timings are not numbers",
    ),
    "close count": (_chain("close", n_records="7"), "a close record whose count is not a number"),
    "close count bool": (
        _chain("close", n_records=True),
        "a close record whose count is not a number",
    ),
}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
@pytest.mark.parametrize("case", sorted(STRUCTURE))
def test_each_structural_check_names_what_is_wrong(case: str) -> None:
    record, problem = STRUCTURE[case]
    assert structure_problem(record) == problem


def _line(record: Any) -> bytes:
    return canonical_json(record)


PARSE: dict[str, tuple[bytes, str]] = {
    "not ascii": (b'{"a":"\xc3\xa9"}', "not a JSON record ("),
    "not json": (b'{"kind":', "not a JSON record (Expecting value at column 9): edited"),
    "a list": (b"[]", "not a JSON object: edited"),
    "no kind": (_line(_chain("x") | {"kind": None}), "field 'kind' missing or not a str: edited"),
    "seq text": (_line(_chain("x", seq="3")), "field 'seq' missing or not a int: edited"),
    "seq bool": (_line(_chain("x", seq=True)), "field 'seq' missing or not a int: edited"),
    "no prev": (
        _line({k: v for k, v in _chain("x").items() if k != "prev"}),
        "field 'prev' missing or not a str: edited",
    ),
    "hash number": (_line(_chain("x", hash=1)), "field 'hash' missing or not a str: edited"),
    "deep": (
        _line(_chain("x", v=json.loads("[" * MAX_DEPTH + "]" * MAX_DEPTH))),
        f"nested deeper than {MAX_DEPTH} levels: edited",
    ),
    "huge int": (_line(_chain("x", v=[INT_LIMIT])), "an integer beyond 64 bits: edited"),
    "huge negative int": (
        _line(_chain("x", v={"a": -INT_LIMIT - 1})),
        "an integer beyond 64 bits: edited",
    ),
    "huge float": (b'{"hash":"h","kind":"x","prev":"p","seq":1,"v":1e999}', "a number beyond"),
    "spaces": (
        json.dumps(_chain("x")).encode(),
        "bytes differ from the record's canonical form: edited",
    ),
}


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
@pytest.mark.parametrize("case", sorted(PARSE))
def test_each_check_of_a_line_names_what_is_wrong(case: str) -> None:
    raw, problem = PARSE[case]
    with pytest.raises(BadRecordError) as caught:
        parse_record(12, raw)
    assert caught.value.line == 12
    assert caught.value.problem.startswith(problem), caught.value.problem
    assert caught.value.problem.endswith(": edited"), caught.value.problem


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_record_at_the_limits_reads_back() -> None:
    """The deepest nesting allowed, the largest and smallest 64-bit integers, true as a value
    (a bool is not an integer beyond range) and a float at the top of the range."""
    deepest = json.loads("[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1))
    record = _chain("x", v=[INT_LIMIT - 1, -INT_LIMIT, True, 1.7e308], d=deepest)
    assert parse_record(1, _line(record)) == record


def test_a_json_problem_is_short_and_never_the_text() -> None:
    with pytest.raises(json.JSONDecodeError) as caught:
        json.loads('{"a": tru}')
    assert json_problem(caught.value) == "Expecting value at column 7"
    assert json_problem(RecursionError("deep")) == "nested too deeply"
    long = ValueError("x" * 300 + "; the rest")
    assert json_problem(long) == "x" * 100
    assert json_problem(ValueError("first; second")) == "first"
    assert json_problem(ValueError("first; second; third")) == "first"
    bad = BadRecordError(3, "a cycle without its stamp")
    assert (str(bad), bad.line, bad.problem) == ("a cycle without its stamp", 3, bad.problem)


def test_base64_has_one_spelling_and_one_length() -> None:
    assert strict_b64("AAAA", 3) == bytes(3)
    assert strict_b64("AAAA", 4) is None
    assert strict_b64("AAAB", 3) == b"\x00\x00\x01"
    assert strict_b64("AAA=", 2) == bytes(2)
    assert strict_b64("AAB=", 2) is None  # the same two bytes with the unused bits set
    assert strict_b64("AAE=", 2) == b"\x00\x01"
    assert strict_b64("AAF=", 2) is None  # the same bytes in another spelling
    assert strict_b64("AA A", 3) is None
    assert strict_b64(b"AAAA", 3) is None
    assert strict_b64(None, 3) is None
