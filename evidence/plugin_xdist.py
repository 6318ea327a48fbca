"""The evidence of a session spread over pytest-xdist workers, gathered into one bundle.

Under ``pytest -n N`` every test runs in a worker process, so its evidence (what it attached,
its Hypothesis statistics, its benchmark figures, its outcome) is built there exactly as in a
serial session (:func:`evidence.plugin_capture.build_item`) and travels to the controlling
process on the test's last report, where the plugin adds it to the session's items; the
controller alone writes the bundle and enforces the verdicts (SR-EVD-10). What tests record as
session provenance and how many tests a worker deselected travel the same way.

pytest-benchmark switches itself off in workers, since timings taken beside other work are
noisy; the safecase suites compare implementations within one run (ratios), which the load of
a neighbouring worker slows alike, and a benchmark's figures decide its evidence kind, so the
plugin switches it back on in a worker and gives each worker its own part of
``--benchmark-json``, which the controller joins into the file asked for.
"""

from __future__ import annotations

import base64
import json
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from evidence.model import EvidenceItem

__all__ = [
    "Gatherer",
    "attach",
    "join_benchmark_parts",
    "receive",
    "restore_benchmarks",
    "worker_id",
]

_ITEM = "safecase_item"
_PROVENANCE = "safecase_provenance"
_DESELECTED = "safecase_deselected"


def worker_id(config: pytest.Config) -> str | None:
    """The xdist worker this process is (``gw0``, ...), or None in a controller or a serial
    session."""
    workerinput = getattr(config, "workerinput", None)
    return None if workerinput is None else str(workerinput["workerid"])


def _encode(value: Any) -> str:
    # The report crosses to the controller through execnet, which carries plain types only;
    # details hold fractions, numpy scalars and tuples, which pickle keeps exactly.
    return base64.b64encode(pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)).decode()


def _decode(text: str) -> Any:
    # the text is what this session's own worker attached (attach)
    return pickle.loads(base64.b64decode(text))


def attach(
    report: pytest.TestReport,
    item: EvidenceItem,
    provenance: dict[str, Any],
    deselected: int,
) -> None:
    """Put a test's evidence, the worker's session provenance and its count of deselected
    tests on the test's teardown ``report`` (in a worker)."""
    setattr(report, _ITEM, _encode(item))
    setattr(report, _PROVENANCE, _encode(dict(provenance)))
    setattr(report, _DESELECTED, deselected)


def receive(report: pytest.TestReport) -> tuple[EvidenceItem, dict[str, Any], int] | None:
    """What :func:`attach` put on ``report`` (in the controller), or None for a report that
    carries no evidence (setup, call, or a session without the plugin active)."""
    text = getattr(report, _ITEM, None)
    if text is None:
        return None
    item: EvidenceItem = _decode(text)
    provenance: dict[str, Any] = _decode(getattr(report, _PROVENANCE))
    return item, provenance, int(getattr(report, _DESELECTED))


class Gatherer:
    """The controller's listener: hands each test's evidence that a worker sent to ``take``
    (the test's item, the worker's session provenance, its count of deselected tests)."""

    def __init__(self, take: Callable[[EvidenceItem, dict[str, Any], int], None]) -> None:
        self._take = take

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        received = receive(report)
        if received is not None:
            self._take(*received)


def _part(path: Path, worker: str) -> Path:
    return path.with_name(f"{path.stem}.{worker}{path.suffix}")


def restore_benchmarks(config: pytest.Config) -> None:
    """Undo pytest-benchmark's switching itself off under xdist (module docstring) where tests
    run: in a worker, whose JSON output becomes this worker's part, and in a session started
    inside a worker's process (pytester), which it takes for a worker too."""
    worker = worker_id(config)
    session = getattr(config, "_benchmarksession", None)
    if session is None or not getattr(session, "xdist_warning", False):
        return
    if worker is None and config.getoption("dist", "no") != "no":
        return  # the controller runs no test
    session.disabled = False
    session.xdist_warning = False
    if worker is not None and session.json is not None:
        session.json = _part(Path(session.json), worker)


def join_benchmark_parts(config: pytest.Config) -> Path | None:
    """In the controller, join the workers' parts of ``--benchmark-json`` into the file asked
    for (benchmarks in name order) and remove the parts; the file, or None when no part was
    written."""
    target = config.getoption("benchmark_json", None)
    if target is None:
        return None
    target = Path(target)
    parts = sorted(target.parent.glob(f"{target.stem}.gw*{target.suffix}"))
    if not parts:
        return None
    documents = [json.loads(part.read_text(encoding="utf-8")) for part in parts]
    joined = dict(documents[0])
    joined["benchmarks"] = sorted(
        (bench for doc in documents for bench in doc.get("benchmarks", [])),
        key=lambda bench: str(bench.get("fullname", "")),
    )
    target.write_text(json.dumps(joined, indent=4) + "\n", encoding="utf-8")
    for part in parts:
        part.unlink()
    return target
