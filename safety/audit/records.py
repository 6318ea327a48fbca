"""What an audit log record of each kind holds, byte for byte (SR-AUD-1).

:func:`parse_record` reads one line: a JSON object whose bytes are its canonical form, with
the chain fields (``kind``, ``seq``, ``prev``, ``hash``), nesting no deeper than
:data:`MAX_DEPTH` and no number a record never holds; anything else is an edited line.
:func:`structure_problem` says why a correctly chained record is still not what the writer
(:mod:`safety.audit.log`) writes for its kind: a header, a cycle or a close record with a key
missing or unknown, or a value of the wrong type. :class:`BadRecordError` carries the line
(1-based; 0 for the head anchor) and the problem to :mod:`safety.audit.verify`.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import re
from typing import Any

from safety.audit.log import canonical_json

__all__ = [
    "HEX64",
    "INT_LIMIT",
    "MAX_DEPTH",
    "BadRecordError",
    "json_problem",
    "parse_record",
    "strict_b64",
    "structure_problem",
]

# The deepest nesting of a record the writer produces is below 10 (configuration -> section ->
# value; inputs -> stage summary -> counters).
MAX_DEPTH = 64
INT_LIMIT = 2**63
HEX64 = re.compile(r"[0-9a-f]{64}")
_NONFINITE = frozenset(("nan", "inf", "-inf"))


class BadRecordError(Exception):
    """A bad record (or head anchor, ``line`` 0) and what is wrong with it."""

    def __init__(self, line: int, problem: str) -> None:
        super().__init__(problem)
        self.line = line
        self.problem = problem


_KEYS = {"kind": str, "seq": int, "prev": str, "hash": str}


def json_problem(exc: BaseException) -> str:
    """A short reason for a JSON decoding failure (never the whole offending text)."""
    if isinstance(exc, RecursionError):
        return "nested too deeply"
    if isinstance(exc, json.JSONDecodeError):
        return f"{exc.msg} at column {exc.colno}"
    return str(exc).split(";", 1)[0][:100]


def _shape_problem(value: Any) -> str | None:
    """Nesting deeper than :data:`MAX_DEPTH` or a number no record holds (iterative: a hostile
    record must not exhaust the stack)."""
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            if depth > MAX_DEPTH:
                return f"nested deeper than {MAX_DEPTH} levels"
            children = item.values() if isinstance(item, dict) else item
            stack.extend((child, depth + 1) for child in children)
        elif isinstance(item, bool):
            continue
        elif isinstance(item, int) and not -INT_LIMIT <= item < INT_LIMIT:
            return "an integer beyond 64 bits"
        elif isinstance(item, float) and not math.isfinite(item):
            return "a number beyond the floating-point range"
    return None


def parse_record(number: int, raw: bytes) -> dict[str, Any]:
    """Line ``number``'s record from its bytes ``raw`` (without the newline), or
    :class:`BadRecordError` saying how it was edited."""
    try:
        record = json.loads(raw.decode("ascii"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise BadRecordError(number, f"not a JSON record ({json_problem(exc)}): edited") from None
    if not isinstance(record, dict):
        raise BadRecordError(number, "not a JSON object: edited")
    for key, kind in _KEYS.items():
        if not isinstance(record.get(key), kind) or isinstance(record.get(key), bool):
            raise BadRecordError(number, f"field {key!r} missing or not a {kind.__name__}: edited")
    shape = _shape_problem(record)
    if shape is not None:
        raise BadRecordError(number, f"{shape}: edited")
    try:
        canonical = canonical_json(record)
    except (ValueError, RecursionError):
        canonical = b""
    if canonical != raw:
        raise BadRecordError(number, "bytes differ from the record's canonical form: edited")
    return record


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _is_float_json(value: Any) -> bool:
    """A float as :func:`pipeline.jsoncodec.float_to_json` writes it."""
    return _is_number(value) or value in _NONFINITE


def _is_text_list(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(v, str) for v in value)


def strict_b64(value: Any, size: int) -> bytes | None:
    """The ``size`` bytes ``value`` encodes when it is their one base64 spelling, else None."""
    if not isinstance(value, str):
        return None
    try:
        raw = base64.b64decode(value, validate=True)
    except (binascii.Error, ValueError):
        return None
    if len(raw) != size or base64.b64encode(raw).decode("ascii") != value:
        return None
    return raw


def _command_problem(value: Any) -> str | None:
    if not isinstance(value, dict) or set(value) != {"action", "speed_mps", "stamp_s", "reasons"}:
        return "not a command"
    if not isinstance(value["action"], str) or not _is_number(value["speed_mps"]):
        return "a command without its action or speed"
    if not _is_float_json(value["stamp_s"]) or not _is_text_list(value["reasons"]):
        return "a command without its stamp or reasons"
    return None


def _verdict_ok(value: Any) -> bool:
    return (
        isinstance(value, dict)
        and set(value) == {"monitor", "action", "speed_limit_mps", "reason"}
        and isinstance(value["monitor"], str)
        and isinstance(value["action"], str)
        and (value["speed_limit_mps"] is None or _is_number(value["speed_limit_mps"]))
        and isinstance(value["reason"], str)
    )


_BASE = frozenset(_KEYS)
_BODIES = {
    "header": frozenset(
        {
            "schema",
            "created_utc",
            "config_hash",
            "config",
            "model_hash",
            "latency",
            "software",
            "public_key",
        }
    ),
    "cycle": frozenset(
        {
            "stamp_s",
            "inputs",
            "observation",
            "governor_inputs",
            "governor_command",
            "verdicts",
            "command",
            "timings_s",
        }
    ),
    "close": frozenset({"n_records"}),
}


def _header_problem(r: dict[str, Any]) -> str | None:
    latency = r["latency"]
    if not isinstance(r["schema"], str) or not isinstance(r["created_utc"], str):
        return "a header without its schema or creation time"
    if not isinstance(r["config_hash"], str) or not HEX64.fullmatch(r["config_hash"]):
        return "a header without a configuration hash"
    if not isinstance(r["config"], dict) or not isinstance(r["software"], dict):
        return "a header without its configuration or software versions"
    if r["model_hash"] is not None and not isinstance(r["model_hash"], str):
        return "a header whose model hash is not text"
    if (
        not isinstance(latency, dict)
        or set(latency) != {"perception_latency_s", "latency_source"}
        or not _is_number(latency["perception_latency_s"])
        or not isinstance(latency["latency_source"], str)
    ):
        return "a header without its latency bound"
    if r["public_key"] is not None and strict_b64(r["public_key"], 32) is None:
        return "a header whose public key is not 32 bytes of base64"
    return None


def _cycle_problem(r: dict[str, Any]) -> str | None:
    if not _is_float_json(r["stamp_s"]):
        return "a cycle without its stamp"
    if not isinstance(r["inputs"], dict) or not isinstance(r["observation"], dict):
        return "a cycle without its inputs or observation"
    if r["governor_inputs"] is not None and not isinstance(r["governor_inputs"], dict):
        return "a cycle whose governor inputs are not a mapping"
    problem = _command_problem(r["command"])
    if problem is None and r["governor_command"] is not None:
        problem = _command_problem(r["governor_command"])
    if problem is not None:
        return f"a cycle with {problem}"
    if not isinstance(r["verdicts"], list) or not all(_verdict_ok(v) for v in r["verdicts"]):
        return "a cycle whose verdicts are not verdicts"
    timings = r["timings_s"]
    if not isinstance(timings, dict) or not all(_is_float_json(v) for v in timings.values()):
        return "a cycle whose timings are not numbers"
    return None


def structure_problem(record: dict[str, Any]) -> str | None:
    """Why ``record`` is not what the writer writes for its kind (None: it is)."""
    kind = record["kind"]
    if kind not in _BODIES:
        return None  # reported as an unknown kind
    keys = set(record) - _BASE
    expected = _BODIES[kind]
    if keys != expected:
        missing, extra = sorted(expected - keys), sorted(keys - expected)
        parts = ([f"without {', '.join(missing)}"] if missing else []) + (
            [f"with unknown {', '.join(extra)}"] if extra else []
        )
        return f"a {kind} record {' and '.join(parts)}"
    if kind == "header":
        return _header_problem(record)
    if kind == "cycle":
        return _cycle_problem(record)
    if not isinstance(record["n_records"], int) or isinstance(record["n_records"], bool):
        return "a close record whose count is not a number"
    return None
