"""Same-run timing comparisons of our implementation against its reference.

pytest-benchmark gives the headline figure of each implementation; :func:`compare` times all
candidates interleaved in one loop (so machine load hits them alike), attaches the samples and
a table of p50 / p99 and ratios to the running test's evidence, and returns the figures. No
test asserts on them: speed targets are reported, not enforced by timed asserts.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from evidence.record import current

__all__ = ["Timing", "compare"]


@dataclass(frozen=True, slots=True)
class Timing:
    """Per-call wall-clock statistics of one candidate, in seconds."""

    name: str
    samples_s: np.ndarray
    p50_s: float
    p99_s: float
    min_s: float


def compare(
    candidates: Mapping[str, Callable[[], object]],
    *,
    reference: str,
    rounds: int = 200,
    warmup: int = 5,
    title: str = "timing",
    target_s: float | None = None,
) -> dict[str, Timing]:
    """Time each candidate ``rounds`` times, interleaved; record samples and a ratio table.

    ``reference`` names the candidate the ratios are taken against (ratio = reference p50 /
    candidate p50, so > 1 means faster than the reference). ``target_s`` (optional) is the
    per-call target shown beside the p99.
    """
    if reference not in candidates:
        raise ValueError(f"compare: reference {reference!r} is not one of {list(candidates)}")
    if rounds < 1:
        raise ValueError(f"compare: rounds must be >= 1, got {rounds}")
    for fn in candidates.values():
        for _ in range(warmup):
            fn()
    samples = {name: np.empty(rounds) for name in candidates}
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        for i in range(rounds):
            for name, fn in candidates.items():
                start = time.perf_counter_ns()
                fn()
                samples[name][i] = (time.perf_counter_ns() - start) * 1e-9
    finally:
        if gc_was_enabled:
            gc.enable()
    timings = {
        name: Timing(
            name=name,
            samples_s=values,
            p50_s=float(np.percentile(values, 50)),
            p99_s=float(np.percentile(values, 99)),
            min_s=float(values.min()),
        )
        for name, values in samples.items()
    }
    ref = timings[reference]
    rows = []
    for name, timing in timings.items():
        rows.append(
            [
                name,
                f"{timing.p50_s * 1e3:.4f}",
                f"{timing.p99_s * 1e3:.4f}",
                f"{ref.p50_s / timing.p50_s:.2f}x",
                "" if target_s is None else ("yes" if timing.p99_s <= target_s else "no"),
            ]
        )
    recorder = current()
    recorder.table(
        title,
        [
            "implementation",
            "p50 ms",
            "p99 ms",
            f"speed vs {reference} (p50)",
            "p99 within target" if target_s is not None else "",
        ],
        rows,
        caption=f"{rounds} interleaved rounds"
        + (f"; target {target_s * 1e3:.3f} ms per call" if target_s is not None else ""),
    )
    for name, timing in timings.items():
        recorder.samples(f"{title}: {name}", timing.samples_s, unit="s")
    return timings
