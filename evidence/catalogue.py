"""The safety requirements catalogue (``safety/requirements.toml``), loaded and validated.

Requirement IDs are stable (``SR-<FAMILY>-<n>`` here); each names the kinds of evidence that
may support it and the minimum count of each kind that must be present and passing before it
can be SATISFIED (requirement SR-EVD-2). Another project's catalogue may use its own ID pattern
(a regular expression every ID must match whole; its group ``family``, if it has one, must be
the requirement's family), set with the ``safecase_id_pattern`` ini option (SR-EVD-7).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args

from pipeline.compat import tomllib
from pipeline.errors import RequirementsError

EvidenceKind = Literal["proof", "property", "cross-check", "measurement", "campaign", "example"]
EVIDENCE_KINDS: tuple[str, ...] = get_args(EvidenceKind)
Status = Literal["planned", "claimed", "unmet"]
STATUSES: tuple[str, ...] = get_args(Status)
DEFAULT_ID_PATTERN = r"SR-(?P<family>[A-Z]+)-[0-9]+"

__all__ = [
    "DEFAULT_ID_PATTERN",
    "EVIDENCE_KINDS",
    "STATUSES",
    "Catalogue",
    "EvidenceKind",
    "Requirement",
    "compile_id_pattern",
    "default_catalogue_path",
    "load_catalogue",
]


@dataclass(frozen=True, slots=True)
class Requirement:
    """One safety requirement: what is claimed, why, and what evidence it needs."""

    id: str
    family: str
    status: Status
    claim: str
    source: str
    evidence_kinds: tuple[str, ...]
    minimum: tuple[tuple[str, int], ...]
    code: tuple[str, ...]

    @property
    def claimed(self) -> bool:
        """True when the requirement must be SATISFIED for certification to pass."""
        return self.status == "claimed"


@dataclass(frozen=True, slots=True)
class Catalogue:
    """All requirements, in file order, with their families and the ID pattern they match."""

    path: str
    families: tuple[tuple[str, str], ...]
    requirements: tuple[Requirement, ...]
    id_pattern: str = DEFAULT_ID_PATTERN

    def __contains__(self, req_id: object) -> bool:
        return any(r.id == req_id for r in self.requirements)

    def get(self, req_id: str) -> Requirement:
        """The requirement with ID ``req_id``; RequirementsError when there is none."""
        for requirement in self.requirements:
            if requirement.id == req_id:
                return requirement
        raise RequirementsError(
            f"unknown requirement ID {req_id!r}; known IDs: "
            + ", ".join(r.id for r in self.requirements)
        )

    def family_title(self, family: str) -> str:
        """Human name of a family code such as ``STOP``."""
        return dict(self.families).get(family, family)


def default_catalogue_path() -> Path:
    """The catalogue shipped in the ``safety`` package."""
    return Path(str(resources.files("safety").joinpath("requirements.toml")))


def compile_id_pattern(pattern: str) -> re.Pattern[str]:
    """The compiled ID pattern; RequirementsError when it is not a regular expression."""
    try:
        return re.compile(pattern)
    except re.error as exc:
        raise RequirementsError(
            f"requirement ID pattern {pattern!r} is not a regular expression: {exc}"
        ) from None


def _need(entry: dict[str, Any], key: str, kind: type, where: str) -> Any:
    if key not in entry:
        raise RequirementsError(f"{where}: missing key {key!r}")
    value = entry[key]
    if not isinstance(value, kind):
        raise RequirementsError(f"{where}: {key} = {value!r}: expected a {kind.__name__}")
    return value


def _parse_requirement(
    entry: dict[str, Any], where: str, families: dict[str, str], pattern: re.Pattern[str]
) -> Requirement:
    req_id = _need(entry, "id", str, where)
    where = f"{where} ({req_id})"
    match = pattern.fullmatch(req_id)
    if match is None:
        raise RequirementsError(
            f"{where}: id {req_id!r} does not match the ID pattern {pattern.pattern!r}"
        )
    family = _need(entry, "family", str, where)
    if family not in families:
        raise RequirementsError(f"{where}: family {family!r} is not one of {', '.join(families)}")
    if "family" in pattern.groupindex and match["family"] != family:
        raise RequirementsError(f"{where}: id {req_id!r} must carry its family {family!r}")
    status = _need(entry, "status", str, where)
    if status not in STATUSES:
        raise RequirementsError(
            f"{where}: status {status!r} must be one of {', '.join(map(repr, STATUSES))}"
        )
    kinds = tuple(_need(entry, "evidence_kinds", list, where))
    for kind in kinds:
        if kind not in EVIDENCE_KINDS:
            raise RequirementsError(
                f"{where}: evidence kind {kind!r} is not one of {', '.join(EVIDENCE_KINDS)}"
            )
    minimum_raw = _need(entry, "minimum", dict, where)
    if not minimum_raw:
        raise RequirementsError(f"{where}: minimum must name at least one evidence kind")
    minimum: list[tuple[str, int]] = []
    for kind, count in minimum_raw.items():
        if kind not in kinds:
            raise RequirementsError(
                f"{where}: minimum names {kind!r}, which is not in evidence_kinds {list(kinds)}"
            )
        if not isinstance(count, int) or count < 1:
            raise RequirementsError(
                f"{where}: minimum.{kind} = {count!r}: expected an integer >= 1"
            )
        minimum.append((kind, count))
    code = tuple(_need(entry, "code", list, where))
    unknown = set(entry) - {
        "id",
        "family",
        "status",
        "claim",
        "source",
        "evidence_kinds",
        "minimum",
        "code",
    }
    if unknown:
        raise RequirementsError(f"{where}: unknown keys {sorted(unknown)}")
    return Requirement(
        id=req_id,
        family=family,
        status=status,
        claim=_need(entry, "claim", str, where),
        source=_need(entry, "source", str, where),
        evidence_kinds=kinds,
        minimum=tuple(minimum),
        code=code,
    )


def load_catalogue(path: Path | str | None = None, id_pattern: str | None = None) -> Catalogue:
    """Load and validate a catalogue (default: the packaged ``safety/requirements.toml``) whose
    IDs match ``id_pattern`` (default :data:`DEFAULT_ID_PATTERN`, ``SR-<FAMILY>-<n>``)."""
    file = Path(path) if path is not None else default_catalogue_path()
    pattern = compile_id_pattern(id_pattern or DEFAULT_ID_PATTERN)
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except OSError as exc:
        raise RequirementsError(f"{file}: cannot read the catalogue: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise RequirementsError(f"{file}: not valid TOML: {exc}") from None
    if data.get("schema_version") != 1:
        raise RequirementsError(
            f"{file}: schema_version = {data.get('schema_version')!r}: expected 1"
        )
    families = data.get("families")
    if not isinstance(families, dict) or not families:
        raise RequirementsError(f"{file}: a [families] table of CODE = 'title' is required")
    entries = data.get("requirement", [])
    if not isinstance(entries, list):
        raise RequirementsError(f"{file}: [[requirement]] must be an array of tables")
    requirements = [
        _parse_requirement(entry, f"{file}: requirement #{i + 1}", families, pattern)
        for i, entry in enumerate(entries)
    ]
    seen: set[str] = set()
    for requirement in requirements:
        if requirement.id in seen:
            raise RequirementsError(f"{file}: duplicate requirement ID {requirement.id!r}")
        seen.add(requirement.id)
    return Catalogue(
        path=str(file),
        families=tuple((str(k), str(v)) for k, v in families.items()),
        requirements=tuple(requirements),
        id_pattern=pattern.pattern,
    )
