"""What the evidence plugin records of one test: its outcome, Hypothesis statistics and
falsifying example, benchmark figures and the details it attached (SR-EVD-2)."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

import pytest
from hypothesis import settings as hypothesis_settings

from evidence.profiles import active_profile

if TYPE_CHECKING:
    from evidence.model import EvidenceItem, Outcome

__all__ = ["benchmark_detail", "build_item", "summarise_stats"]

_MAX_TEXT = 20_000


_FALSIFYING_START = re.compile(r"^(Falsifying (explicit )?example|Failing test case)\b")
_BLOB = re.compile(r"@reproduce_failure\([^)]*\)")


def _falsifying_example(text: str) -> str:
    """The falsifying example Hypothesis printed (pytest prefixes such lines with 'E')."""
    lines = [re.sub(r"^E {0,7}", "", line) for line in text.splitlines()]
    for start, line in enumerate(lines):
        if _FALSIFYING_START.match(line):
            block = [line]
            for follow in lines[start + 1 :]:
                if not follow.strip():
                    break
                block.append(follow)
                if follow.rstrip() == ")":
                    break
            return "\n".join(block)
    return ""


def summarise_stats(stats: dict[str, Any], item: pytest.Item) -> dict[str, Any]:
    counts = {"valid": 0, "invalid": 0, "overrun": 0, "interesting": 0}
    for phase in ("reuse-phase", "generate-phase", "explain-phase"):
        for case in stats.get(phase, {}).get("test-cases", []):
            counts[case["status"]] = counts.get(case["status"], 0) + 1
    current_settings = hypothesis_settings()
    return {
        "examples_run": sum(counts.values()),
        "valid": counts["valid"],
        "invalid": counts["invalid"] + counts["overrun"],
        "failing": counts["interesting"],
        "stopped_because": str(stats.get("stopped-because", "")),
        "profile": active_profile(),
        "max_examples": current_settings.max_examples,
        "seed": (
            "derandomized (derived from the test)"
            if current_settings.derandomize
            else str(item.config.getoption("hypothesis_seed", None) or "random")
        ),
    }


def benchmark_detail(item: pytest.Item) -> dict[str, Any] | None:
    funcargs = getattr(item, "funcargs", None) or {}
    fixture = funcargs.get("benchmark")
    meta = getattr(fixture, "stats", None)
    stats = getattr(meta, "stats", None)
    if stats is None or not getattr(stats, "data", None):
        return None
    return {
        "type": "benchmark",
        "name": getattr(fixture, "name", item.name),
        "group": getattr(fixture, "group", None) or "",
        "rounds": int(stats.rounds),
        "min_s": float(stats.min),
        "max_s": float(stats.max),
        "mean_s": float(stats.mean),
        "median_s": float(stats.median),
        "stddev_s": float(stats.stddev) if stats.rounds > 1 else 0.0,
        "extra_info": dict(getattr(fixture, "extra_info", {}) or {}),
    }


def build_item(
    item: pytest.Item,
    reports: dict[str, pytest.TestReport],
    record: Any,
    bench: dict[str, Any] | None,
    hyp: dict[str, Any] | None,
) -> EvidenceItem:
    """The evidence item of ``item`` from its setup/call/teardown ``reports``, what it attached
    (``record``), its benchmark figures and its Hypothesis statistics (either may be None)."""
    from evidence.model import EvidenceItem

    outcome: Outcome = "passed"
    message = ""
    longrepr = ""
    duration = sum(r.duration for r in reports.values())
    for when in ("setup", "call", "teardown"):
        report = reports.get(when)
        if report is None:
            continue
        if report.failed:
            outcome = "failed" if when == "call" else "error"
            longrepr = str(report.longreprtext)[-_MAX_TEXT:]
            message = longrepr.strip().splitlines()[-1][:500] if longrepr.strip() else ""
            break
        if report.skipped:
            outcome = "skipped"
            message = _skip_reason(report)
            break
    ids: list[str] = []
    code: list[str] = []
    kind: str | None = None
    for marker in item.iter_markers("requirement"):
        ids.extend(a for a in marker.args if a not in ids)
        code.extend(marker.kwargs.get("code", ()))
        kind = kind or marker.kwargs.get("kind")
    details: list[dict[str, Any]] = list(record.details) if record else []
    for group, values in record.counters.items() if record else []:
        details.append({"type": "counts", "name": group, "values": dict(values)})
    if bench is not None:
        details.append(bench)
    if hyp is not None:
        info = str(getattr(item, "hypothesis_report_information", "")) + "\n" + longrepr
        hyp["falsifying_example"] = _falsifying_example(info)
        blob = _BLOB.search(info)
        hyp["reproduce_blob"] = blob.group(0) if blob else ""
    inferred = (
        kind
        or (record.kind if record else None)
        or ("measurement" if bench is not None else None)
        or ("property" if hyp is not None else "example")
    )
    return EvidenceItem(
        nodeid=item.nodeid,
        file=str(item.path.relative_to(item.config.rootpath))
        if item.path.is_relative_to(item.config.rootpath)
        else str(item.path),
        requirement_ids=ids,
        kind=inferred,
        outcome=outcome,
        duration_s=duration,
        code=code,
        message=message,
        longrepr=longrepr,
        hypothesis=hyp,
        details=details,
    )


def _skip_reason(report: pytest.TestReport) -> str:
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2])
    return str(longrepr)
