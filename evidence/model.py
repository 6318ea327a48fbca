"""The evidence schema (version 1) and the verdict rules (requirement SR-EVD-2).

``evidence.json`` is one :class:`Bundle` serialised by :func:`Bundle.to_json`. The schema is
documented field by field in ``evidence/SCHEMA.md``; bump :data:`SCHEMA_VERSION` on any
incompatible change.

Verdict rules, per requirement:

* VIOLATED: some linked evidence failed (a failing or erroring test, or an attached proof
  obligation whose verdict is not PROVED: ``unknown`` never counts as a pass);
* SATISFIED: nothing failed and, for every kind in the requirement's ``minimum``, at least that
  many linked items of that kind passed;
* NOT EVIDENCED: otherwise (no evidence, only skipped evidence, or too few of some kind);
* PLANNED: the requirement's status is ``planned``; its would-be verdict is kept alongside.
* NOT MET: the status is ``unmet``: built and measured, its target not reached; shown as
  failing beside its would-be verdict, never blocking certification.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

from evidence.catalogue import Catalogue, Requirement
from evidence.safety_case import SafetyCase

SCHEMA_ID = "safecase-evidence"
SCHEMA_VERSION = "1.2"

Outcome = Literal["passed", "failed", "skipped", "error"]
RequirementVerdict = Literal["SATISFIED", "VIOLATED", "NOT EVIDENCED", "PLANNED", "NOT MET"]
SmtVerdict = Literal["PROVED", "REFUTED", "UNKNOWN"]

__all__ = [
    "SCHEMA_ID",
    "SCHEMA_VERSION",
    "Bundle",
    "EvidenceItem",
    "RequirementResult",
    "compute_verdicts",
]


@dataclass(slots=True)
class EvidenceItem:
    """One test, property, proof, cross-check or benchmark, as it ran."""

    nodeid: str
    file: str
    requirement_ids: list[str]
    kind: str
    outcome: Outcome
    duration_s: float
    code: list[str] = field(default_factory=list)
    message: str = ""
    longrepr: str = ""
    hypothesis: dict[str, Any] | None = None
    details: list[dict[str, Any]] = field(default_factory=list)

    def failed_obligations(self) -> list[dict[str, Any]]:
        """Attached proof obligations that must be PROVED but are not."""
        return [
            d
            for d in self.details
            if d.get("type") == "smt" and d.get("required", True) and d.get("verdict") != "PROVED"
        ]

    @property
    def effective_outcome(self) -> Outcome:
        """The outcome once unproved obligations are taken into account."""
        if self.outcome == "passed" and self.failed_obligations():
            return "failed"
        return self.outcome


@dataclass(slots=True)
class RequirementResult:
    """A requirement's verdict and what supports it."""

    id: str
    family: str
    status: str
    claim: str
    source: str
    code: list[str]
    verdict: RequirementVerdict
    would_be: RequirementVerdict
    minimum: dict[str, int]
    passing: dict[str, int]
    missing: list[str]
    evidence: list[str]
    failures: list[str]


def _verdict_for(
    req: Requirement, items: list[EvidenceItem]
) -> tuple[RequirementVerdict, dict[str, int], list[str], list[str]]:
    passing: Counter[str] = Counter()
    failures: list[str] = []
    for item in items:
        outcome = item.effective_outcome
        if outcome in ("failed", "error"):
            failures.append(item.nodeid)
        elif outcome == "passed":
            passing[item.kind] += 1
    missing = [
        f"{kind}: {passing.get(kind, 0)} of {count} present"
        for kind, count in req.minimum
        if passing.get(kind, 0) < count
    ]
    verdict: RequirementVerdict
    if failures:
        verdict = "VIOLATED"
    elif missing:
        verdict = "NOT EVIDENCED"
    else:
        verdict = "SATISFIED"
    return verdict, dict(passing), missing, failures


def _shown(status: str, would_be: RequirementVerdict) -> RequirementVerdict:
    """The verdict a requirement shows: its own when claimed; PLANNED when not built yet; NOT
    MET when built but its target not reached (shown as failing, never blocking)."""
    if status == "claimed":
        return would_be
    return "NOT MET" if status == "unmet" else "PLANNED"


def compute_verdicts(catalogue: Catalogue, items: list[EvidenceItem]) -> list[RequirementResult]:
    """One :class:`RequirementResult` per catalogue entry, in catalogue order (SR-EVD-2)."""
    results = []
    for req in catalogue.requirements:
        linked = [item for item in items if req.id in item.requirement_ids]
        would_be, passing, missing, failures = _verdict_for(req, linked)
        results.append(
            RequirementResult(
                id=req.id,
                family=req.family,
                status=req.status,
                claim=req.claim,
                source=req.source,
                code=sorted(set(req.code).union(*(item.code for item in linked))),
                verdict=_shown(req.status, would_be),
                would_be=would_be,
                minimum=dict(req.minimum),
                passing=passing,
                missing=missing,
                evidence=[item.nodeid for item in linked],
                failures=failures,
            )
        )
    return results


@dataclass(slots=True)
class Bundle:
    """Everything ``evidence.json`` holds."""

    created_utc: str
    profile: str
    provenance: dict[str, Any]
    environment: dict[str, Any]
    catalogue_path: str
    families: dict[str, str]
    requirements: list[RequirementResult]
    tests: list[EvidenceItem]
    session_exit_status: int
    schema: str = SCHEMA_ID
    schema_version: str = SCHEMA_VERSION
    selection: dict[str, Any] | None = None
    safety_case: SafetyCase | None = None

    @property
    def is_slice(self) -> bool:
        """True when the session ran a selection of the suite (``-k``, ``-m``, deselected
        tests): then only the requirements its tests touched are judged."""
        return self.selection is not None

    @property
    def summary(self) -> dict[str, Any]:
        """Counts of test outcomes and requirement verdicts, and the overall result."""
        outcomes = Counter(item.effective_outcome for item in self.tests)
        verdicts = Counter(r.verdict for r in self.requirements)
        judged = [r for r in self.requirements if not self.is_slice or r.evidence]
        blocking = [r.id for r in judged if r.status == "claimed" and r.verdict != "SATISFIED"]
        passed = not blocking and self.session_exit_status == 0
        return {
            "tests": {k: outcomes.get(k, 0) for k in ("passed", "failed", "error", "skipped")},
            "requirements": {
                k: verdicts.get(k, 0)
                for k in ("SATISFIED", "VIOLATED", "NOT EVIDENCED", "PLANNED", "NOT MET")
            },
            "scope": "slice" if self.is_slice else "suite",
            "judged_requirements": [r.id for r in judged],
            "blocking_requirements": blocking,
            "overall": "PASS" if passed else "FAIL",
            "certification": (
                ("SLICE PASS" if passed else "SLICE FAIL")
                if self.is_slice
                else ("CERTIFIED" if passed else "NOT CERTIFIED")
            ),
        }

    def family_verdicts(self) -> dict[str, dict[str, int]]:
        """Per family: count of each verdict."""
        table: dict[str, Counter[str]] = {code: Counter() for code in self.families}
        for result in self.requirements:
            table.setdefault(result.family, Counter())[result.verdict] += 1
        return {family: dict(counts) for family, counts in table.items()}

    def to_dict(self) -> dict[str, Any]:
        """The JSON-ready form (field order fixed, stable across runs)."""
        return {
            "schema": self.schema,
            "schema_version": self.schema_version,
            "created_utc": self.created_utc,
            "profile": self.profile,
            "summary": self.summary,
            "provenance": self.provenance,
            "environment": self.environment,
            "catalogue_path": self.catalogue_path,
            "families": self.families,
            "requirements": [asdict(r) for r in self.requirements],
            "tests": [asdict(t) for t in self.tests],
            "session_exit_status": self.session_exit_status,
            "selection": self.selection,
            "safety_case": None if self.safety_case is None else asdict(self.safety_case),
        }

    def to_json(self) -> str:
        """Serialise with sorted nested keys where order carries no meaning."""
        return json.dumps(self.to_dict(), indent=2, sort_keys=False, default=str) + "\n"
