"""The one JSON codec for values that may hold non-finite floats (SR-AUD-1, SR-EVD-2).

JSON has no NaN or infinity; safecase writes them as the text ``"nan"``, ``"inf"`` and
``"-inf"`` (Python's own ``repr``), which ``float()`` reads back. Finite floats keep their
shortest round-trip form, so decoding gives the same bits. :func:`jsonable` also turns
dataclasses into mappings, enums into their values and numpy arrays and scalars into lists and
numbers, so the audit log, the evidence bundle and the configuration share one encoding.

>>> dumps({"free_m": float("inf"), "speed_mps": 0.5})
'{"free_m":"inf","speed_mps":0.5}'
"""

from __future__ import annotations

import enum
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, is_dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.types import FloatArray

__all__ = [
    "dumps",
    "float_from_json",
    "float_to_json",
    "floats_from_json",
    "floats_to_json",
    "jsonable",
]


def float_to_json(value: float) -> float | str:
    """A float as a JSON value: itself when finite, else ``"nan"``, ``"inf"`` or ``"-inf"``."""
    value = float(value)
    return value if math.isfinite(value) else repr(value)


def float_from_json(value: float | str) -> float:
    """Inverse of :func:`float_to_json`."""
    return float(value)


def floats_to_json(values: npt.ArrayLike) -> list[float | str]:
    """An array of floats, flattened, as JSON values (:func:`float_to_json` each)."""
    return [
        v if math.isfinite(v) else repr(v)
        for v in np.asarray(values, dtype=np.float64).ravel().tolist()
    ]


def floats_from_json(values: Sequence[float | str]) -> FloatArray:
    """Inverse of :func:`floats_to_json`."""
    return np.array([float(v) for v in values], dtype=np.float64)


def jsonable(value: Any) -> Any:
    """``value`` as JSON-ready data: mappings, lists, strings, numbers, booleans, None."""
    if is_dataclass(value) and not isinstance(value, type):
        return {k: jsonable(v) for k, v in asdict(value).items()}
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, float):
        return float_to_json(value)
    if isinstance(value, np.ndarray):
        return [jsonable(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return jsonable(value.item())
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, set | frozenset):
        return [jsonable(v) for v in sorted(value, key=str)]
    return value


def dumps(value: Any, *, canonical: bool = True, indent: int | None = None) -> str:
    """Strict JSON text of :func:`jsonable` ``(value)`` (never a bare ``NaN`` token).

    ``canonical``: sorted keys and no whitespace (the audit log's byte form); otherwise keys in
    their order, ``indent`` as given.
    """
    data = jsonable(value)
    if canonical:
        return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return json.dumps(data, indent=indent, allow_nan=False)
