"""Campaign bodies run ahead in a worker beside the suite (properties.ahead)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig
from properties import ahead, beside


@ahead.ahead
def records_its_process(safecase_config: SafecaseConfig, evidence: Recorder) -> None:
    """A body that records where it ran (importable: the worker spawns; not collected)."""
    evidence.note(f"pid {os.getpid()}")
    evidence.count("calls", "body", 2)
    evidence.provenance("ahead test", safecase_config.runtime.sim_cycle_s)


@ahead.ahead
def fails_after_recording(safecase_config: SafecaseConfig, evidence: Recorder) -> None:
    """A body that records a note and then fails an assertion."""
    evidence.note("before the failure")
    assert safecase_config.runtime.sim_cycle_s < 0, "the cycle is never negative"


@pytest.fixture
def workers(monkeypatch: pytest.MonkeyPatch) -> Iterator[beside.Beside]:
    """Workers of the test's own: the session's (the certify soaks and campaigns) are never
    touched."""
    own = beside.Beside()
    monkeypatch.setattr(ahead, "beside", own)
    yield own
    own.stop()


def _notes() -> list[str]:
    record = current().peek()
    assert record is not None
    return [d["text"] for d in record.details if d["type"] == "note"]


def test_a_body_run_ahead_is_recorded_here_as_the_worker_recorded_it(
    workers: beside.Beside, safecase_config: SafecaseConfig
) -> None:
    ahead.start(records_its_process, safecase_config)
    assert workers.started(ahead.key_of(records_its_process))
    records_its_process(safecase_config=safecase_config, evidence=current())
    notes = _notes()
    pid = int(notes[-2].removeprefix("pid "))
    assert "no timing evidence" in notes[-1]
    assert pid != os.getpid()
    record = current().peek()
    assert record is not None
    assert record.counters["calls"]["body"] == 2
    assert record.counters[ahead.WORKER_TIME]["wall s"] >= 0
    assert current().session_provenance.pop("ahead test") == safecase_config.runtime.sim_cycle_s
    assert not workers.started(ahead.key_of(records_its_process))  # taken once


def test_a_body_not_started_runs_here(safecase_config: SafecaseConfig) -> None:
    records_its_process(safecase_config=safecase_config, evidence=current())
    current().session_provenance.pop("ahead test")
    assert _notes()[-1] == f"pid {os.getpid()}"


def test_a_failure_in_the_worker_fails_here_with_its_traceback(
    workers: beside.Beside, safecase_config: SafecaseConfig
) -> None:
    ahead.start(fails_after_recording, safecase_config)
    with pytest.raises(AssertionError, match="never negative") as raised:
        fails_after_recording(safecase_config=safecase_config, evidence=current())
    assert "fails_after_recording" in str(raised.value.__cause__)
    assert isinstance(raised.value.__cause__, ahead.WorkerTracebackError)
    assert "before the failure" in _notes()


def test_only_decorated_tests_with_the_provided_fixtures_run_ahead(
    safecase_config: SafecaseConfig,
) -> None:
    def uses_tmp_path(safecase_config: SafecaseConfig, tmp_path: object) -> None:
        """Asks for a fixture the worker cannot give."""

    def no_config(evidence: Recorder) -> None:
        """Does not ask for the configuration."""

    for body in (uses_tmp_path, no_config):
        with pytest.raises(TypeError, match="cannot run ahead"):
            ahead.ahead(body)
    with pytest.raises(ValueError, match="not decorated"):
        ahead.start(uses_tmp_path, safecase_config)
