"""Typed, strict reading of a ROS 2 parameter YAML file: one-line errors (SR-NAV-4).

A ROS 2 parameter file is ``node: ros__parameters: {key: value}``; a parameter named
``PolygonStop.points`` is the key ``points`` of the mapping ``PolygonStop``. :class:`Section`
reads one such mapping and refuses a value of the wrong type or range with a
:class:`Nav2ParamsError` whose single line names the key (``collision_monitor.PolygonStop.points``),
the value and what is allowed. Numbers are returned as the exact binary value Nav2 computes with
(``fractions.Fraction`` of the IEEE double; :func:`nearest_float32` for the string-encoded
polygon points, which Nav2 parses into single-precision floats).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from fractions import Fraction
from pathlib import Path
from typing import Any, overload

import numpy as np

from pipeline.errors import SafecaseError

__all__ = [
    "Nav2ParamsError",
    "Section",
    "load_yaml",
    "nearest_float32",
    "node_parameters",
    "parse_yaml",
]

# Coordinates, speeds and times beyond these are typing errors, not robots [m, m/s, s].
MAX_ABS_VALUE = Fraction(10**4)
_MAX_SHOWN = 60
_MAX_FILE_BYTES = 4 * 1024 * 1024


class Nav2ParamsError(SafecaseError, ValueError):
    """A malformed Nav2 parameter file: one line naming the key, the value and what is allowed."""


def shown(value: Any) -> str:
    """``repr(value)``, cut to a readable length."""
    text = repr(value)
    return text if len(text) <= _MAX_SHOWN else text[: _MAX_SHOWN - 3] + "..."


def load_yaml(path: Path) -> tuple[Mapping[str, Any], str]:
    """The top-level mapping of the YAML file ``path`` and its name; one-line errors."""
    try:
        if not path.is_file():
            what = "no such file" if not path.exists() else "not a regular file"
            raise Nav2ParamsError(f"{path}: cannot read the parameter file: {what}")
        raw = path.read_bytes()
    except OSError as exc:
        raise Nav2ParamsError(f"{path}: cannot read the parameter file: {exc.strerror}") from None
    if len(raw) > _MAX_FILE_BYTES:
        raise Nav2ParamsError(f"{path}: {len(raw)} bytes: allowed: at most {_MAX_FILE_BYTES}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise Nav2ParamsError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    return parse_yaml(text, str(path))


def parse_yaml(text: str, name: str) -> tuple[Mapping[str, Any], str]:
    """The top-level mapping of the YAML ``text`` (named ``name`` in errors); one-line errors."""
    from ruamel.yaml import YAML
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    path = name
    try:
        data = YAML(typ="safe", pure=True).load(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        raise Nav2ParamsError(f"{path}: not valid YAML: {exc.problem}{where}") from None
    except (YAMLError, RecursionError, ValueError) as exc:
        raise Nav2ParamsError(f"{path}: not valid YAML: {type(exc).__name__}") from None
    if not isinstance(data, Mapping):
        raise Nav2ParamsError(
            f"{path}: the document is {type(data).__name__}: expected a mapping of node names "
            "to `ros__parameters:`"
        )
    return data, name


def node_parameters(data: Mapping[str, Any], node: str) -> Section | None:
    """The ``ros__parameters`` of ``node`` (also ``/ns/node``), or None when absent."""
    for key, value in data.items():
        if not isinstance(key, str) or not (key == node or key.endswith("/" + node)):
            continue
        if not isinstance(value, Mapping) or not isinstance(value.get("ros__parameters"), Mapping):
            raise Nav2ParamsError(
                f"{key} = {shown(value)}: expected a mapping with a `ros__parameters:` mapping"
            )
        return Section(value["ros__parameters"], node)
    return None


def nearest_float32(value: Fraction) -> Fraction:
    """The single-precision float nearest to ``value`` (ties to even), exactly."""
    first = np.float32(float(value))
    candidates = (
        first,
        np.nextafter(first, np.float32(np.inf)),
        np.nextafter(first, np.float32(-np.inf)),
    )

    def key(candidate: np.float32) -> tuple[Fraction, int]:
        return abs(Fraction(float(candidate)) - value), int(candidate.view(np.uint32)) & 1

    return Fraction(float(min(candidates, key=key)))


class Section:
    """One parameter mapping, read strictly; ``prefix`` names it in error messages."""

    def __init__(self, data: Mapping[str, Any], prefix: str) -> None:
        self.data = data
        self.prefix = prefix

    def key(self, name: str) -> str:
        """The dotted name of parameter ``name`` (``collision_monitor.PolygonStop.radius``)."""
        return f"{self.prefix}.{name}"

    def fail(self, name: str, value: Any, allowed: str) -> Nav2ParamsError:
        """The one-line error for parameter ``name``."""
        return Nav2ParamsError(f"{self.key(name)} = {shown(value)}: allowed: {allowed}")

    def has(self, name: str) -> bool:
        """True when parameter ``name`` is set (to anything but null)."""
        return self.data.get(name) is not None

    @overload
    def number(
        self,
        name: str,
        default: Fraction,
        *,
        low: Fraction = ...,
        low_open: bool = ...,
        high: Fraction = ...,
    ) -> Fraction: ...

    @overload
    def number(
        self,
        name: str,
        default: None = None,
        *,
        low: Fraction = ...,
        low_open: bool = ...,
        high: Fraction = ...,
    ) -> Fraction | None: ...

    def number(
        self,
        name: str,
        default: Fraction | None = None,
        *,
        low: Fraction = -MAX_ABS_VALUE,
        low_open: bool = False,
        high: Fraction = MAX_ABS_VALUE,
    ) -> Fraction | None:
        """A finite number in ``[low, high]`` (``(low, high]`` if ``low_open``), exactly;
        ``default`` when the parameter is not set (so never None when a default is given)."""
        value = self.data.get(name)
        if value is None:
            return default
        return self.as_number(name, value, low=low, low_open=low_open, high=high)

    def as_number(
        self,
        name: str,
        value: Any,
        *,
        low: Fraction = -MAX_ABS_VALUE,
        low_open: bool = False,
        high: Fraction = MAX_ABS_VALUE,
    ) -> Fraction:
        """``value`` (of parameter ``name``) as an exact number within the range."""
        bracket = "(" if low_open else "["
        allowed = f"a number in {bracket}{float(low):g}, {float(high):g}]"
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(name, value, allowed)
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(name, value, allowed)
        exact = Fraction(value)
        if exact < low or exact > high or (low_open and exact == low):
            raise self.fail(name, value, allowed)
        return exact

    def integer(self, name: str, default: int, *, low: int) -> int:
        """An integer ``>= low``."""
        value = self.data.get(name)
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise self.fail(name, value, f"an integer >= {low}")
        return value

    def boolean(self, name: str, default: bool) -> bool:
        """``true`` or ``false``."""
        value = self.data.get(name)
        if value is None:
            return default
        if not isinstance(value, bool):
            raise self.fail(name, value, "true or false")
        return value

    def string(self, name: str, default: str | None = None) -> str | None:
        """A string."""
        value = self.data.get(name)
        if value is None:
            return default
        if not isinstance(value, str):
            raise self.fail(name, value, "a string")
        return value

    def choice(self, name: str, allowed: tuple[str, ...], default: str | None = None) -> str:
        """One of ``allowed`` (required when there is no default)."""
        value = self.data.get(name, default)
        if value not in allowed:
            raise self.fail(name, value, " | ".join(allowed))
        return str(value)

    def names(self, name: str, *, required: bool) -> tuple[str, ...]:
        """A list of distinct non-empty strings (``polygons``, ``observation_sources``)."""
        value = self.data.get(name)
        if value is None and not required:
            return ()
        allowed = "a list of distinct names"
        if not isinstance(value, list) or not value:
            raise self.fail(name, value, allowed)
        if not all(isinstance(v, str) and v for v in value) or len(set(value)) != len(value):
            raise self.fail(name, value, allowed)
        return tuple(value)

    def triple(self, name: str) -> tuple[Fraction, Fraction, Fraction] | None:
        """A list of three numbers (``[vx, vy, wz]`` of the velocity smoother)."""
        value = self.data.get(name)
        if value is None:
            return None
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(name, value, "a list of three numbers [x, y, theta]")
        x, y, theta = (self.as_number(name, v) for v in value)
        return x, y, theta

    def section(self, name: str, *, required: bool) -> Section | None:
        """The sub-mapping ``name`` (a polygon, a source, a sub-polygon)."""
        value = self.data.get(name)
        if value is None and not required:
            return None
        if not isinstance(value, Mapping):
            raise self.fail(name, value, "a mapping of its parameters")
        return Section(value, self.key(name))
