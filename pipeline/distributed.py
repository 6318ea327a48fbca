"""Seeded, independent tasks on Dask distributed: a LocalCluster here or a scheduler elsewhere.

Campaigns (closed-loop encounters, SR-RUN-8) and classifier training data (SR-CLS-3) have the
same shape of work: many runs, each seeded by its own spec alone, so a run gives the same
result on any worker and in any order. :func:`open_client` connects to ``scheduler`` (a
``tcp://host:port`` address) or starts a :class:`distributed.LocalCluster` of ``workers``
single-threaded processes (the simulator and the runtime hold the GIL; processes, not threads,
give the parallelism). :func:`as_done` submits every task and yields each result as it
arrives; :func:`in_order` yields them in submission order for callers whose output must not
depend on timing (training rows). Without a client (``None``) both run every task here, one
after another, in submission order: for a debugger or a profiler, and for tests that must not
start processes of their own.

Faults: a worker that dies mid-task (killed, out of memory) loses its task to the scheduler,
which reruns it on another worker up to ``retries`` times (the scheduler's count of suspicious
deaths, ``distributed.scheduler.allowed-failures``, set for a LocalCluster; a remote scheduler
keeps its own); a task
that raises comes back as a :class:`TaskFailed` naming the task and the error, never dropped
and never retried (a seeded run that raised will raise again).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import dask
from distributed import Client, Future, LocalCluster, as_completed

__all__ = [
    "DEFAULT_RETRIES",
    "Done",
    "TaskFailed",
    "as_done",
    "in_order",
    "open_client",
]

T = TypeVar("T")
R = TypeVar("R")

DEFAULT_RETRIES = 3
"""Reruns of a task whose worker died (a killed worker, not a task that raised)."""


@dataclass(frozen=True)
class TaskFailed:
    """A task that raised: its position in the submitted list and the error, as text."""

    index: int
    error: str


@dataclass(frozen=True)
class Done(Generic[R]):
    """One task's outcome: its position in the submitted list and its result or failure."""

    index: int
    result: R | TaskFailed


@contextlib.contextmanager
def open_client(
    scheduler: str | None = None, workers: int = 2, *, retries: int = DEFAULT_RETRIES
) -> Iterator[Client]:
    """A client of ``scheduler``, or of a new LocalCluster of ``workers`` processes (one
    thread each, no dashboard port clash: a free port is taken) closed on exit.

    Raises ``ValueError`` for ``workers < 1``; a scheduler that cannot be reached raises
    ``OSError`` naming the address (the caller turns it into its error line).
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    with dask.config.set({"distributed.scheduler.allowed-failures": retries}):
        if scheduler is not None:
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError) as exc:
                raise OSError(f"Dask scheduler {scheduler}: cannot connect ({exc})") from exc
            with client:
                yield client
            return
        # The cluster's own logs would interleave with the caller's progress bar; a worker
        # that dies is reported by the scheduler's retry and, when retries run out, the task.
        logging.getLogger("distributed").setLevel(logging.ERROR)
        with (
            LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            ) as cluster,
            Client(cluster) as client,
        ):
            yield client


def _guarded(fn: Callable[[T], R], index: int, item: T) -> Done[R]:
    """Run one task on a worker, turning an exception into a :class:`TaskFailed`."""
    try:
        return Done(index, fn(item))
    except Exception as exc:  # recorded and counted by the caller, never dropped
        return Done(index, TaskFailed(index, f"{type(exc).__name__}: {exc}"))


def _submit(client: Client, fn: Callable[[T], R], items: Sequence[T]) -> list[Future[Done[R]]]:
    return [
        client.submit(_guarded, fn, index, item, pure=False) for index, item in enumerate(items)
    ]


def _here(fn: Callable[[T], R], items: Iterable[T]) -> Iterator[Done[R]]:
    """Every task run in this process, in order (no client: module docstring)."""
    for index, item in enumerate(items):
        yield _guarded(fn, index, item)


def as_done(
    client: Client | None,
    fn: Callable[[T], R],
    items: Iterable[T],
) -> Iterator[Done[R]]:
    """``fn`` applied to every item on the cluster, each outcome as soon as it arrives
    (without a client: here, in order).

    ``fn`` must be importable by the workers (a module-level function) and seeded by its item
    alone. A task whose workers died more often than the cluster allows (``retries`` of
    :func:`open_client`; a remote scheduler's own setting) comes back as a :class:`TaskFailed`.
    """
    if client is None:
        yield from _here(fn, items)
        return
    futures = _submit(client, fn, list(items))
    index_of = {future.key: i for i, future in enumerate(futures)}
    for future in as_completed(futures):
        yield _outcome(future, index_of[future.key])
        future.release()


def in_order(
    client: Client | None,
    fn: Callable[[T], R],
    items: Iterable[T],
) -> Iterator[Done[R]]:
    """As :func:`as_done`, but yielded in the order of ``items`` (each as soon as it and every
    one before it are done), so the output does not depend on the workers' timing."""
    if client is None:
        yield from _here(fn, items)
        return
    futures = _submit(client, fn, list(items))
    for index, future in enumerate(futures):
        yield _outcome(future, index)
        future.release()


def _outcome(future: Future[Done[R]], index: int) -> Done[R]:
    try:
        done: Done[R] = future.result()
    except Exception as exc:  # KilledWorker after the retries, a lost scheduler
        return Done(index, TaskFailed(index, f"{type(exc).__name__}: {exc}"))
    return done
