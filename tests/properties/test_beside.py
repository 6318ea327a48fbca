"""The worker that runs long measurements beside the suite (properties.beside)."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from properties import beside


def pid_plus(offset: int) -> int:
    """The process id of whoever runs it, plus ``offset`` (importable: the worker spawns)."""
    return os.getpid() + offset


@pytest.fixture
def worker() -> Iterator[beside.Beside]:
    """Workers of the test's own: the session's (the certify soaks) are never touched."""
    own = beside.Beside()
    yield own
    own.stop()


def test_a_started_call_runs_in_the_worker_and_an_unstarted_one_here(worker: beside.Beside) -> None:
    worker.start(pid_plus, 0)
    assert worker.result(pid_plus, 0) != os.getpid()
    assert worker.result(pid_plus, 0) == os.getpid()  # taken once; now computed here


def test_a_call_queued_with_other_arguments_is_refused(worker: beside.Beside) -> None:
    worker.start(pid_plus, 1)
    with pytest.raises(ValueError, match="other arguments"):
        worker.result(pid_plus, 2)
    worker.start(pid_plus, 1)
    with pytest.raises(ValueError, match="already queued"):
        worker.start(pid_plus, 1)


def _rendezvous(mine: Path, other: Path, timeout_s: float) -> bool:
    """Leave ``mine``, then wait for ``other``: True only if both calls ran at the same time
    (the timeout only ends a wait that would otherwise never end)."""
    mine.touch()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if other.exists():
            return True
        time.sleep(0.01)
    return False


def first(mine: Path, other: Path) -> bool:
    """One side of the rendezvous (importable: the worker spawns)."""
    return _rendezvous(mine, other, 60.0)


def second(mine: Path, other: Path) -> bool:
    """The other side."""
    return _rendezvous(mine, other, 60.0)


def test_two_started_calls_run_side_by_side(worker: beside.Beside, tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    worker.start(first, a, b)
    worker.start(second, b, a)
    assert worker.result(first, a, b)
    assert worker.result(second, b, a)
