"""Campaign tests whose bodies run ahead, in a worker beside the suite (certify only).

A campaign that runs for a minute or more on one core computes its figures and checks them; its
body needs nothing from the test session but the configuration, a recorder and perhaps the
classifier. Decorated with :func:`ahead`, such a test's body is queued on the workers of
:mod:`properties.beside` when collection ends under certify (``properties/conftest.py``), on the
core the suite leaves idle, at a lower priority than the suite (:data:`NICE`), and the test
itself, run near the end, takes what the body recorded and how it ended: the details are
attached to its evidence in the order they were recorded, a failure is raised here with the
worker's traceback, and counters give the body's wall time in the worker
(:data:`evidence.durations.WORKER_TIME`) with a note that any wall-clock time the body recorded
includes its preemption by the suite (the timing requirements are measured in the suite). Run
alone, under any other profile, or when nothing was queued for it, the test runs its body
in-process as any other test. The figures are the same either way: the campaigns draw their
randomness from seeds, never from the process.

The body gets the same fixtures in the worker: ``safecase_config`` (the session's configuration,
passed to the worker), ``evidence`` (the worker's recorder) and ``classifier`` (the configured
model, loaded in the worker); a test asking for any other fixture cannot be decorated.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import os
import pickle
import time
import traceback
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any

from hypothesis import settings

from evidence.durations import WORKER_TIME
from evidence.profiles import active_profile, register_profiles, set_active_profile
from evidence.record import current
from pipeline.config import SafecaseConfig
from properties import beside

__all__ = [
    "FIXTURES",
    "NICE",
    "WORKER_TIME",
    "Outcome",
    "WorkerTracebackError",
    "ahead",
    "is_ahead",
    "key_of",
    "run_body",
    "start",
]

FIXTURES = frozenset({"safecase_config", "evidence", "classifier"})
"""The fixtures a body run ahead may ask for."""


NICE = 10
"""How much lower than the suite's a body run ahead is scheduled (``os.nice``)."""

_MARK = "__safecase_ahead__"


class WorkerTracebackError(Exception):
    """Where in the worker a body run ahead failed (the cause of the error raised here)."""

    def __str__(self) -> str:
        return str(self.args[0])


@dataclass(frozen=True)
class Outcome:
    """What a body recorded in the worker and how it ended."""

    details: list[dict[str, Any]]
    counters: dict[str, dict[str, float]]
    kind: str | None
    provenance: dict[str, Any]
    error: BaseException | None
    traceback: str
    wall_s: float


def key_of(test: Callable[..., Any]) -> Hashable:
    """The key a test's body is queued under on the beside workers."""
    return ("ahead", test.__module__, test.__qualname__)


def is_ahead(test: Any) -> bool:
    """Whether ``test`` was decorated with :func:`ahead`."""
    return bool(getattr(test, _MARK, False))


def ahead(test: Callable[..., None]) -> Callable[..., None]:
    """Let the certify session run ``test``'s body in a worker beside the suite (module
    docstring). Raises ``TypeError`` when it asks for a fixture the worker cannot provide, or
    not for ``safecase_config`` (the configuration the worker is given)."""
    wanted = set(inspect.signature(test).parameters)
    if wanted - FIXTURES or "safecase_config" not in wanted:
        raise TypeError(
            f"{test.__qualname__}: cannot run ahead with fixtures {sorted(wanted)} (it must ask "
            f"for safecase_config, and the worker provides only {sorted(FIXTURES)})"
        )

    @functools.wraps(test)
    def run(**fixtures: Any) -> None:
        if not beside.started(key_of(test)):
            test(**fixtures)
            return
        outcome: Outcome = beside.result(
            run_body, *_call(test, fixtures["safecase_config"]), key=key_of(test)
        )
        recorder = current()
        recorder.replay(outcome.details, outcome.counters, outcome.kind, outcome.provenance)
        recorder.counts(WORKER_TIME, {"wall s": round(outcome.wall_s, 1)})
        recorder.note(
            f"Run in a worker beside the suite at nice {NICE}: any wall-clock time in these "
            "details includes the worker's preemption by the suite and is no timing evidence "
            "(the timing requirements are measured in the suite)."
        )
        if outcome.error is not None:
            raise outcome.error from WorkerTracebackError(outcome.traceback)

    setattr(run, _MARK, True)
    return run


def _call(test: Callable[..., Any], config: SafecaseConfig) -> tuple[str, str, SafecaseConfig, str]:
    return (test.__module__, test.__qualname__, config, active_profile())


def start(test: Callable[..., Any], config: SafecaseConfig) -> None:
    """Queue the body of the decorated ``test`` on the session's beside workers."""
    if not is_ahead(test):
        raise ValueError(f"{test.__qualname__} is not decorated with @ahead")
    body = test.__wrapped__  # type: ignore[attr-defined]
    beside.start(run_body, *_call(body, config), key=key_of(body))


def run_body(module: str, qualname: str, config: SafecaseConfig, profile: str) -> Outcome:
    """Run the body of ``module.qualname`` under ``profile`` in this (worker) process, with the
    fixtures it asks for, and return what it recorded and how it ended."""
    # The suite is the critical path (its timing measurements, its Dask campaigns): the body
    # takes only the processor time the suite leaves (one worker process per body).
    os.nice(NICE)
    register_profiles()
    settings.load_profile(profile)
    set_active_profile(profile)
    test = getattr(importlib.import_module(module), qualname).__wrapped__
    recorder = current()
    recorder.begin(f"{module}::{qualname}")
    error: BaseException | None = None
    trace = ""
    start_s = time.perf_counter()
    try:
        test(**_fixtures(test, config, recorder))
    except BaseException as exc:  # pytest's skip and fail are BaseExceptions too
        if isinstance(exc, KeyboardInterrupt | SystemExit):
            raise
        error, trace = exc, traceback.format_exc()
    wall_s = time.perf_counter() - start_s
    record = recorder.end()
    assert record is not None
    if error is not None:
        try:
            pickle.dumps(error)
        except Exception:  # an exception that cannot cross processes still fails the test
            error = RuntimeError(f"{type(error).__name__}: {error}")
    return Outcome(
        details=record.details,
        counters=record.counters,
        kind=record.kind,
        provenance=dict(recorder.session_provenance),
        error=error,
        traceback=trace,
        wall_s=wall_s,
    )


def _fixtures(test: Callable[..., Any], config: SafecaseConfig, recorder: Any) -> dict[str, Any]:
    wanted = inspect.signature(test).parameters
    fixtures: dict[str, Any] = {}
    if "safecase_config" in wanted:
        fixtures["safecase_config"] = config
    if "evidence" in wanted:
        fixtures["evidence"] = recorder
    if "classifier" in wanted:
        from pipeline.classify.model import Classifier

        fixtures["classifier"] = Classifier.from_config(config.classify)
    return fixtures
