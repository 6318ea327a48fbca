"""Long measurements that run beside the suite, on the core the suite leaves idle.

The certify suite runs its tests one after another on one core; a soak of an hour of cycles
(SR-RUN-5) needs a core for as long. :func:`start` hands such a call to a spawned worker process
as soon as collection has finished (see ``properties/conftest.py``); the test that needs the
figures calls :func:`result` with the same call, which waits for the worker's answer, or runs
the call in-process when nothing was started for it (any profile but certify, or the test run
alone). Up to :data:`WORKERS` calls run at once, each in its own process: the device soak is
paced by its scanner's rate and leaves most of a core idle, so the two soaks side by side end
in the time of the longer one instead of the sum. A spawned process shares no state (no forked
solver or thread pools) with the suite. The figures are the same whichever process computes
them: what is measured is the call's own process (its RSS and its main thread's CPU time).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Hashable
from multiprocessing.pool import AsyncResult, Pool
from typing import Any

__all__ = ["WORKERS", "result", "start", "stop"]

WORKERS = 2
"""How many started calls run at once (one process each)."""

_pool: Pool | None = None
_started: dict[Hashable, tuple[tuple[Any, ...], AsyncResult[Any]]] = {}


def _key(call: Callable[..., Any]) -> Hashable:
    return (call.__module__, call.__qualname__)


def start(call: Callable[..., Any], *args: Any) -> None:
    """Queue ``call(*args)`` on the worker processes (started on first use); one call per
    function."""
    global _pool
    if _key(call) in _started:
        raise ValueError(f"{call.__qualname__} is already queued")
    if _pool is None:
        _pool = multiprocessing.get_context("spawn").Pool(processes=WORKERS, maxtasksperchild=1)
    _started[_key(call)] = (args, _pool.apply_async(call, args))


def result(call: Callable[..., Any], *args: Any) -> Any:
    """What ``call(*args)`` returns: from the worker when :func:`start` queued this very call,
    else computed here. Raises ``ValueError`` when the queued call had other arguments (the
    figures would not be the ones asked for)."""
    pending = _started.pop(_key(call), None)
    if pending is None:
        return call(*args)
    queued, answer = pending
    if queued != args:
        raise ValueError(f"{call.__qualname__} was queued with other arguments")
    return answer.get()


def stop() -> None:
    """End the worker, whatever it is doing (the session is over)."""
    global _pool
    _started.clear()
    if _pool is not None:
        _pool.terminate()
        _pool.join()
        _pool = None
