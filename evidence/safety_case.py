"""The hazard log and the assumptions (``safety/hazards.toml``), loaded and traced (SR-EVD-2).

A :class:`Hazard` says how the guarded robot can cause harm (or the evidence can mislead about
it) and which requirements mitigate it; an :class:`Assumption` says what a proof takes as given,
which configuration keys set it, which requirements rest on it and how the runtime watches it
(a monitor, a rule checked at load, or openly "not monitored"). :func:`trace_problems` is the
check ``make test`` runs: every claimed requirement mitigates a hazard, every hazard is
mitigated, and everything named exists.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args

from evidence.catalogue import Catalogue
from pipeline.compat import tomllib
from pipeline.config import SafecaseConfig
from pipeline.errors import RequirementsError
from safety.model.monitors import DEFAULT_MONITORS
from safety.obstacles import OBJECT_SPEED_WATCH

__all__ = [
    "WATCHES",
    "Assumption",
    "Hazard",
    "SafetyCase",
    "assumption_values",
    "default_hazards_path",
    "load_safety_case",
    "trace_problems",
]

Severity = Literal["S1", "S2", "evidence"]
Watch = Literal["monitor", "config", "not monitored"]
# Every run-time check an assumption may name: the monitors and the runtime's domain check.
WATCHES: tuple[str, ...] = (*(name for name, _ in DEFAULT_MONITORS), OBJECT_SPEED_WATCH)


@dataclass(frozen=True, slots=True)
class Hazard:
    """One hazard: how harm arises, where, how bad, and what mitigates it."""

    id: str
    title: str
    cause: str
    situation: str
    severity: str
    mitigated_by: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Assumption:
    """One assumption a proof rests on, with the keys that set it and how it is watched."""

    id: str
    title: str
    statement: str
    keys: tuple[str, ...]
    used_by: tuple[str, ...]
    watch: str
    monitor: str
    how: str

    @property
    def watched(self) -> bool:
        """True when the runtime or the configuration loader checks it."""
        return self.watch != "not monitored"


@dataclass(frozen=True, slots=True)
class SafetyCase:
    """The hazard log and the assumptions, in file order."""

    path: str
    hazards: tuple[Hazard, ...]
    assumptions: tuple[Assumption, ...]


def default_hazards_path() -> Path:
    """The hazard log shipped in the ``safety`` package."""
    return Path(str(resources.files("safety").joinpath("hazards.toml")))


def _text(entry: dict[str, Any], key: str, where: str) -> str:
    value = entry.get(key)
    if not isinstance(value, str) or not value:
        raise RequirementsError(f"{where}: {key} = {value!r}: expected a non-empty string")
    return value


def _ids(entry: dict[str, Any], key: str, where: str) -> tuple[str, ...]:
    value = entry.get(key)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise RequirementsError(f"{where}: {key} = {value!r}: expected a list of strings")
    return tuple(value)


def _hazard(entry: dict[str, Any], where: str) -> Hazard:
    known = {"id", "title", "cause", "situation", "severity", "mitigated_by"}
    if unknown := set(entry) - known:
        raise RequirementsError(f"{where}: unknown keys {sorted(unknown)}")
    severity = _text(entry, "severity", where)
    if severity not in get_args(Severity):
        raise RequirementsError(f"{where}: severity {severity!r}: allowed: S1, S2, evidence")
    return Hazard(
        _text(entry, "id", where),
        _text(entry, "title", where),
        _text(entry, "cause", where),
        _text(entry, "situation", where),
        severity,
        _ids(entry, "mitigated_by", where),
    )


def _assumption(entry: dict[str, Any], where: str) -> Assumption:
    known = {"id", "title", "statement", "keys", "used_by", "watch", "monitor", "how"}
    if unknown := set(entry) - known:
        raise RequirementsError(f"{where}: unknown keys {sorted(unknown)}")
    watch = _text(entry, "watch", where)
    if watch not in get_args(Watch):
        raise RequirementsError(f"{where}: watch {watch!r}: allowed: {', '.join(get_args(Watch))}")
    monitor = entry.get("monitor", "")
    if (watch == "monitor") != bool(monitor):
        raise RequirementsError(f"{where}: watch = 'monitor' needs a monitor, and only then")
    return Assumption(
        _text(entry, "id", where),
        _text(entry, "title", where),
        _text(entry, "statement", where),
        _ids(entry, "keys", where),
        _ids(entry, "used_by", where),
        watch,
        str(monitor),
        _text(entry, "how", where),
    )


def load_safety_case(path: Path | str | None = None) -> SafetyCase:
    """Load and validate the hazard log (default: the packaged ``safety/hazards.toml``)."""
    file = Path(path) if path is not None else default_hazards_path()
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except OSError as exc:
        raise RequirementsError(f"{file}: cannot read the hazard log: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise RequirementsError(f"{file}: not valid TOML: {exc}") from None
    if data.get("schema_version") != 1:
        raise RequirementsError(f"{file}: schema_version must be 1")
    hazards = tuple(
        _hazard(entry, f"{file}: hazard {i + 1}") for i, entry in enumerate(data.get("hazard", []))
    )
    assumptions = tuple(
        _assumption(entry, f"{file}: assumption {i + 1}")
        for i, entry in enumerate(data.get("assumption", []))
    )
    ids = [h.id for h in hazards] + [a.id for a in assumptions]
    if duplicated := sorted({i for i in ids if ids.count(i) > 1}):
        raise RequirementsError(f"{file}: duplicate IDs {duplicated}")
    return SafetyCase(str(file), hazards, assumptions)


def assumption_values(assumption: Assumption, config: SafecaseConfig) -> dict[str, Any]:
    """The configured value of each of the assumption's keys (``section.key``)."""
    out = {}
    for key in assumption.keys:
        section, _, name = key.partition(".")
        out[key] = getattr(getattr(config, section), name)
    return out


def trace_problems(case: SafetyCase, catalogue: Catalogue, config: SafecaseConfig) -> list[str]:
    """Every broken link of the safety case, one line each (none: the case traces)."""
    problems: list[str] = []
    known = {r.id for r in catalogue.requirements}
    mitigating: set[str] = set()
    for h in case.hazards:
        if not h.mitigated_by:
            problems.append(f"{h.id}: mitigated by no requirement")
        for req_id in h.mitigated_by:
            if req_id not in known:
                problems.append(f"{h.id}: unknown requirement {req_id}")
        mitigating.update(h.mitigated_by)
    for r in catalogue.requirements:
        if r.status != "planned" and r.id not in mitigating:
            problems.append(f"{r.id} ({r.status}): mitigates no hazard")
    for a in case.assumptions:
        for req_id in a.used_by:
            if req_id not in known:
                problems.append(f"{a.id}: unknown requirement {req_id}")
        if not a.used_by:
            problems.append(f"{a.id}: used by no requirement")
        for key in a.keys:
            section, _, name = key.partition(".")
            if not hasattr(getattr(config, section, None), name) or not name:
                problems.append(f"{a.id}: unknown configuration key {key}")
        if a.watch == "monitor" and a.monitor not in WATCHES:
            problems.append(f"{a.id}: unknown monitor {a.monitor!r}; known: {', '.join(WATCHES)}")
    return problems
