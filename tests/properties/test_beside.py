"""The worker that runs long measurements beside the suite (properties.beside)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from properties import beside


def pid_plus(offset: int) -> int:
    """The process id of whoever runs it, plus ``offset`` (importable: the worker spawns)."""
    return os.getpid() + offset


@pytest.fixture
def worker() -> Iterator[None]:
    yield
    beside.stop()


@pytest.mark.usefixtures("worker")
def test_a_started_call_runs_in_the_worker_and_an_unstarted_one_here() -> None:
    beside.start(pid_plus, 0)
    assert beside.result(pid_plus, 0) != os.getpid()
    assert beside.result(pid_plus, 0) == os.getpid()  # taken once; now computed here


@pytest.mark.usefixtures("worker")
def test_a_call_queued_with_other_arguments_is_refused() -> None:
    beside.start(pid_plus, 1)
    with pytest.raises(ValueError, match="other arguments"):
        beside.result(pid_plus, 2)
    beside.start(pid_plus, 1)
    with pytest.raises(ValueError, match="already queued"):
        beside.start(pid_plus, 1)
