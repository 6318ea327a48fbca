"""The four standard-library names that arrived in Python 3.11, on Python 3.10 as well.

safecase runs on CPython 3.10, 3.11 and 3.12 (docs/python-versions.md). On 3.11 and later
every name here *is* the standard library's; on 3.10 it is the closest stand-in:

* ``tomllib``: ``tomli``, the package tomllib was made from (same API, same errors);
* ``UTC``: ``datetime.timezone.utc``, the object ``datetime.UTC`` is an alias of;
* ``Self``: ``typing_extensions.Self``;
* ``StrEnum``: :class:`StrEnum310`, whose ``str()``, ``format()``, f-strings and ``auto()``
  values are those of 3.11's ``enum.StrEnum`` (a plain ``class X(str, Enum)`` would print
  ``X.MEMBER``, and an audit record or a bundle would then differ by Python version; SR-EVD-9).
"""

from __future__ import annotations

import enum
import sys
from typing import Any

__all__ = ["UTC", "Self", "StrEnum", "StrEnum310", "tomllib"]


class StrEnum310(str, enum.Enum):
    """Members are strings that print as their value, as ``enum.StrEnum`` does on 3.11+."""

    _value_: str

    @property
    def value(self) -> str:
        """The member's string (typed: Enum's own ``value`` is ``Any`` to a type checker)."""
        return self._value_

    def __new__(cls, value: str) -> StrEnum310:
        # Only strings are members' values, as enum.StrEnum insists (3.11 raises TypeError).
        if not isinstance(value, str):
            raise TypeError(f"{value!r} is not a string")
        member = str.__new__(cls, value)
        member._value_ = value
        return member

    __str__ = str.__str__
    __format__ = str.__format__  # type: ignore[assignment]

    @staticmethod
    def _generate_next_value_(name: str, start: int, count: int, last_values: list[Any]) -> str:
        # auto() gives the member's name in lower case, as enum.StrEnum's does.
        return name.lower()


if sys.version_info >= (3, 11):
    from datetime import UTC
    from enum import StrEnum
    from typing import Self

    import tomllib
else:  # pragma: no cover - exercised by the Python 3.10 session (nox -s tests-3.10)
    from datetime import timezone

    import tomli as tomllib
    from typing_extensions import Self

    UTC = timezone.utc
    StrEnum = StrEnum310
