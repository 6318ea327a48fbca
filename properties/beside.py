"""Long measurements that run beside the suite, on the core the suite leaves idle.

The certify suite runs its tests one after another on one core; a soak of an hour of cycles
(SR-RUN-5) needs a core for as long. :func:`start` hands such a call to a spawned worker process
as soon as collection has finished (see ``properties/conftest.py``); the test that needs the
figures calls :func:`result` with the same call, which waits for the worker's answer, or runs
the call in-process when nothing was started for it. Up to :data:`WORKERS` calls run at once,
each in its own process: the device soak is paced by its scanner's rate and leaves most of a
core idle, so the two soaks side by side end in the time of the longer one instead of the sum.
A spawned process shares no state (no forked solver or thread pools, no heap the earlier tests
left) with the suite: what a soak measures is its own process (its RSS and its main thread's
CPU time).

The module-level functions use the session's one :class:`Beside`; anything else (its own
tests) makes its own, so stopping it never ends the session's soaks.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Hashable
from multiprocessing.pool import AsyncResult, Pool
from typing import Any

__all__ = ["WORKERS", "Beside", "result", "start", "started", "stop"]

WORKERS = 2
"""How many started calls run at once (one process each)."""


def _key(call: Callable[..., Any]) -> Hashable:
    return (call.__module__, call.__qualname__)


class Beside:
    """Worker processes for calls started ahead of the tests that need them (module
    docstring)."""

    def __init__(self, workers: int = WORKERS) -> None:
        self.workers = workers
        self._pool: Pool | None = None
        self._started: dict[Hashable, tuple[tuple[Any, ...], AsyncResult[Any]]] = {}

    def start(self, call: Callable[..., Any], *args: Any, key: Hashable = None) -> None:
        """Queue ``call(*args)`` on the worker processes (started on first use); one call per
        function, or per ``key`` when one function serves several callers."""
        key = _key(call) if key is None else key
        if key in self._started:
            raise ValueError(f"{call.__qualname__} is already queued as {key!r}")
        if self._pool is None:
            context = multiprocessing.get_context("spawn")
            self._pool = context.Pool(processes=self.workers, maxtasksperchild=1)
        self._started[key] = (args, self._pool.apply_async(call, args))

    def started(self, key: Hashable) -> bool:
        """Whether a call queued under ``key`` waits for its :meth:`result`."""
        return key in self._started

    def result(self, call: Callable[..., Any], *args: Any, key: Hashable = None) -> Any:
        """What ``call(*args)`` returns: from a worker when :meth:`start` queued this very call,
        else computed here. Raises ``ValueError`` when the queued call had other arguments (the
        figures would not be the ones asked for)."""
        pending = self._started.pop(_key(call) if key is None else key, None)
        if pending is None:
            return call(*args)
        queued, answer = pending
        if queued != args:
            raise ValueError(f"{call.__qualname__} was queued with other arguments")
        return answer.get()

    def stop(self) -> None:
        """End the workers, whatever they are doing."""
        self._started.clear()
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
            self._pool = None


_session = Beside()


def start(call: Callable[..., Any], *args: Any, key: Hashable = None) -> None:
    """:meth:`Beside.start` on the session's workers."""
    _session.start(call, *args, key=key)


def started(key: Hashable) -> bool:
    """:meth:`Beside.started` on the session's workers."""
    return _session.started(key)


def result(call: Callable[..., Any], *args: Any, key: Hashable = None) -> Any:
    """:meth:`Beside.result` on the session's workers."""
    return _session.result(call, *args, key=key)


def stop() -> None:
    """End the session's workers (the session is over)."""
    _session.stop()
