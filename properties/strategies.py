"""Hypothesis strategies for safecase's own types, physically bounded.

Each strategy draws only values the system can meet (finite, within the configured or
physical range) unless its name says it draws bad input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from annotated_types import Ge, Gt, Le, Lt
from hypothesis import strategies as st
from pydantic import BaseModel

from pipeline.config import SafecaseConfig

__all__ = ["ConfigField", "config_fields", "out_of_range_value", "valid_value"]


@dataclass(frozen=True, slots=True)
class ConfigField:
    """One numeric configuration key with its declared bounds."""

    section: str
    key: str
    kind: type
    low: float | None
    low_inclusive: bool
    high: float | None
    high_inclusive: bool

    @property
    def dotted(self) -> str:
        """``section.key`` as error messages name it."""
        return f"{self.section}.{self.key}"


def _numeric_fields() -> list[ConfigField]:
    fields = []
    for section, info in SafecaseConfig.model_fields.items():
        model = info.annotation
        assert isinstance(model, type)
        assert issubclass(model, BaseModel)
        for key, field_info in model.model_fields.items():
            if field_info.annotation not in (int, float):
                continue
            low = high = None
            low_inc = high_inc = True
            for meta in field_info.metadata:
                if isinstance(meta, Ge):
                    low, low_inc = float(meta.ge), True  # type: ignore[arg-type]
                elif isinstance(meta, Gt):
                    low, low_inc = float(meta.gt), False  # type: ignore[arg-type]
                elif isinstance(meta, Le):
                    high, high_inc = float(meta.le), True  # type: ignore[arg-type]
                elif isinstance(meta, Lt):
                    high, high_inc = float(meta.lt), False  # type: ignore[arg-type]
            kind = int if field_info.annotation is int else float
            fields.append(ConfigField(section, key, kind, low, low_inc, high, high_inc))
    return fields


NUMERIC_FIELDS = _numeric_fields()


def config_fields() -> st.SearchStrategy[ConfigField]:
    """Any numeric configuration key."""
    return st.sampled_from(NUMERIC_FIELDS)


def valid_value(field: ConfigField) -> st.SearchStrategy[Any]:
    """A value the field's declaration allows."""
    if field.kind is int:
        low = (
            int(field.low if field.low_inclusive else field.low + 1)
            if field.low is not None
            else -(10**6)
        )
        high = (
            int(field.high if field.high_inclusive else field.high - 1)
            if field.high is not None
            else 10**6
        )
        return st.integers(low, high)
    return st.floats(
        min_value=field.low if field.low is not None else -1e6,
        max_value=field.high if field.high is not None else 1e6,
        exclude_min=not field.low_inclusive,
        exclude_max=not field.high_inclusive,
        allow_nan=False,
        allow_infinity=False,
    )


def out_of_range_value(field: ConfigField) -> st.SearchStrategy[Any]:
    """A value the field must reject: outside its bounds, non-finite, or of the wrong type."""
    options: list[st.SearchStrategy[Any]] = [
        st.sampled_from(["1.0", "abc", ""]),
        st.none(),
    ]
    if field.kind is float:
        options.append(st.sampled_from([math.nan, math.inf, -math.inf]))
    else:
        options.append(st.floats())  # strict: an int key takes no float, not even 2.0
    if field.low is not None:
        low = field.low
        below = (
            st.floats(
                max_value=low,
                exclude_max=field.low_inclusive,
                allow_nan=False,
                allow_infinity=False,
                min_value=low - 1e6,
            )
            if field.kind is float
            else st.integers(max_value=math.ceil(low) - 1, min_value=int(low) - 10**6)
        )
        options.append(below)
    if field.high is not None:
        high = field.high
        above = (
            st.floats(
                min_value=high,
                exclude_min=field.high_inclusive,
                allow_nan=False,
                allow_infinity=False,
                max_value=high + 1e6,
            )
            if field.kind is float
            else st.integers(min_value=math.floor(high) + 1, max_value=int(high) + 10**6)
        )
        options.append(above)
    return st.one_of(options)
