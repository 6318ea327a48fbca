"""pipeline.compat: Python 3.10's stand-ins behave as 3.11's standard library (SR-EVD-9).

The 3.10 string enum is defined on every Python, so it is checked here against the real
``enum.StrEnum`` wherever that exists, and against plain-string behaviour on 3.10 itself.
"""

from __future__ import annotations

import datetime
import enum
import sys
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pipeline import compat
from pipeline.compat import UTC, StrEnum, StrEnum310, tomllib
from pipeline.sources.serial.faults import FaultKind

_NAMES = st.from_regex(r"[A-Z][A-Z0-9_]{0,8}", fullmatch=True).filter(
    lambda s: not s.startswith("_") and not s.endswith("_")
)
_SPECS = st.sampled_from(["", ">12", "<3", "^9", "s", "!r"])


def _make(base: type[Any], members: dict[str, str | None]) -> Any:
    return base(
        "Made",
        [(name, enum.auto() if value is None else value) for name, value in members.items()],
    )


def _reading(cls: Any, spec: str) -> list[tuple[Any, ...]]:
    """Everything a record could be written from: value, str, format, f-string, equality."""
    out = []
    for member in cls:
        shown = f"{member!r}" if spec == "!r" else format(member, spec)
        out.append(
            (member.name, member.value, str(member), shown, f"{member}", member == str(member))
        )
    return out


@pytest.mark.requirement("SR-EVD-9", kind="property", code=["pipeline/compat.py"])
@given(
    members=st.dictionaries(_NAMES, st.one_of(st.none(), st.text(max_size=6)), max_size=6),
    spec=_SPECS,
)
def test_the_310_string_enum_reads_as_the_standard_one(
    members: dict[str, str | None], spec: str
) -> None:
    made = _make(StrEnum310, members)
    if sys.version_info >= (3, 11):
        reference = _make(enum.StrEnum, members)
        assert _reading(made, spec) == _reading(reference, spec)
    else:  # pragma: no cover - Python 3.10 session
        for member in made:
            assert str(member) == member.value == f"{member}"
    for name, value in members.items():
        assert made[name].value == (name.lower() if value is None else value)


@pytest.mark.requirement("SR-EVD-9", kind="example", code=["pipeline/compat.py"])
def test_compat_names_are_the_standard_library_where_it_has_them() -> None:
    # Audit records store fault kinds by str(): the same on every Python.
    assert [str(k) for k in FaultKind] == [k.value for k in FaultKind]
    assert f"{FaultKind.DROP_BYTE}" == "drop_byte"
    stamp = datetime.datetime(2026, 1, 1, 12, tzinfo=UTC)
    assert stamp.isoformat() == "2026-01-01T12:00:00+00:00"
    assert UTC is datetime.timezone.utc
    with pytest.raises(tomllib.TOMLDecodeError):
        tomllib.loads("a = ")
    assert tomllib.loads("a = 1.5\n[b]\nc = 'x'\n") == {"a": 1.5, "b": {"c": "x"}}
    with pytest.raises(TypeError, match="is not a string"):
        _make(StrEnum310, {"A": 1})  # type: ignore[dict-item]
    if sys.version_info >= (3, 11):
        from typing import Self

        import tomllib as std_tomllib

        assert compat.tomllib is std_tomllib
        assert StrEnum is enum.StrEnum
        assert compat.Self is Self
        assert UTC is datetime.UTC
    else:  # pragma: no cover - Python 3.10 session
        assert StrEnum is StrEnum310
