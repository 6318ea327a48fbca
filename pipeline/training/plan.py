"""The classifier's data plans and their rows, simulated or from a block cache (SR-CLS-3).

A data plan is a list of runs (:class:`RunSpec`: scenario, seed, duration). Its rows are the
concatenation of every run's rows in plan order, whatever the number of worker processes
(runs are independent and seeded by their spec alone, so a run gives the same rows in any plan).

The cache keeps rows in **blocks**: consecutive runs of one scenario and duration whose seeds
share ``seed // block_runs``, each block in one ``.npz`` named by a hash of the configuration
sections that shape rows, the feature names and the block's runs. A plan that grows (more
encounter seeds, say) simulates only the blocks it does not find; a changed configuration or
feature set misses every block. Run indices inside a block file count from 0 and are renumbered
to plan positions when blocks are put together.
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.errors import SafecaseError
from pipeline.features import FEATURE_NAMES
from pipeline.sources.sim.scenarios import SCENARIOS
from pipeline.training.data import DRILL, Rows, RunSpec, load_rows, run_rows, save_rows

__all__ = [
    "BLOCK_RUNS",
    "NAMED",
    "ROW_SECTIONS",
    "TrainingDataError",
    "cached_rows",
    "concat_rows",
    "data_plan",
    "gather_rows",
    "plan_blocks",
]

# The configuration sections that shape the rows (not the classifier's training parameters).
ROW_SECTIONS = ("scan", "cluster", "track", "predict", "sim", "stopping")
NAMED = tuple(n for n in SCENARIOS if n != "random_encounter")
BLOCK_RUNS = 50


class TrainingDataError(SafecaseError):
    """A run of a data plan that raised: training stops naming it."""


def data_plan(
    named_seeds: int, encounter_seeds: int, drill_seeds: int, duration_s: float, first_seed: int
) -> list[RunSpec]:
    """Runs of the plan: each named scenario, ``random_encounter`` and the drill with seeds
    ``first_seed .. first_seed + n - 1``."""
    plan = [RunSpec(name, first_seed + s, duration_s) for name in NAMED for s in range(named_seeds)]
    plan += [
        RunSpec("random_encounter", first_seed + s, duration_s) for s in range(encounter_seeds)
    ]
    plan += [RunSpec(DRILL, first_seed + s, duration_s) for s in range(drill_seeds)]
    return plan


def concat_rows(parts: Sequence[Rows]) -> Rows:
    """The rows of ``parts`` one after the other; run indices renumbered to positions in the
    joined run list; drop counts summed."""
    dropped: dict[str, int] = {}
    runs: list[RunSpec] = []
    offsets = []
    for part in parts:
        offsets.append(len(runs))
        runs.extend(part.runs)
        for key, value in part.dropped.items():
            dropped[key] = dropped.get(key, 0) + value
    if not parts:
        width = len(FEATURE_NAMES)
        empty_i, empty_f = np.zeros(0, np.int64), np.zeros(0)
        return Rows(np.zeros((0, width)), empty_i, empty_i, empty_f, empty_i, empty_i, empty_f)
    return Rows(
        features=np.concatenate([p.features for p in parts]),
        label=np.concatenate([p.label for p in parts]),
        run=np.concatenate([p.run + off for p, off in zip(parts, offsets, strict=True)]),
        stamp_s=np.concatenate([p.stamp_s for p in parts]),
        track_id=np.concatenate([p.track_id for p in parts]),
        object_id=np.concatenate([p.object_id for p in parts]),
        range_m=np.concatenate([p.range_m for p in parts]),
        runs=runs,
        dropped=dropped,
    )


def _run(config: SafecaseConfig, spec: RunSpec) -> Rows:
    return run_rows(config, spec, 0)


def _gather_parts(
    config: SafecaseConfig,
    plan: Sequence[RunSpec],
    workers: int,
    progress: Callable[[int], None] | None,
) -> Iterator[Rows]:
    """Each run's rows, in plan order, as soon as that run (and every one before it) is done:
    in this process for ``workers`` 1, else on a Dask LocalCluster of ``workers`` processes
    (:mod:`pipeline.distributed`, the engine campaigns use too).

    Raises :class:`TrainingDataError` naming the run when a run raised (or its workers kept
    dying): training never goes on without a run of its plan.
    """
    if workers <= 1:
        for done, spec in enumerate(plan, start=1):
            part = _run(config, spec)
            if progress is not None:
                progress(done)
            yield part
        return
    from pipeline.distributed import TaskFailed, in_order, open_client

    with open_client(None, workers) as client:
        task = functools.partial(_run, config)
        for outcome in in_order(client, task, plan):
            result = outcome.result
            if isinstance(result, TaskFailed):
                spec = plan[outcome.index]
                raise TrainingDataError(
                    f"run {spec.scenario} seed {spec.seed} ({spec.duration_s:g} s) failed: "
                    f"{result.error}"
                )
            if progress is not None:
                progress(outcome.index + 1)
            yield result


def gather_rows(
    config: SafecaseConfig,
    plan: Sequence[RunSpec],
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
) -> Rows:
    """Rows of every run of ``plan``, in plan order whatever ``workers`` is (deterministic).

    ``progress`` is called with the number of runs done after each run.
    """
    return concat_rows(list(_gather_parts(config, plan, workers, progress)))


def plan_blocks(plan: Sequence[RunSpec], block_runs: int = BLOCK_RUNS) -> list[list[RunSpec]]:
    """``plan`` cut into cache blocks (module docstring), in plan order."""
    if block_runs < 1:
        raise ValueError(f"block_runs must be at least 1, got {block_runs}")
    blocks: list[list[RunSpec]] = []
    last: tuple[str, float, int] | None = None
    for spec in plan:
        key = (spec.scenario, spec.duration_s, spec.seed // block_runs)
        if key != last:
            blocks.append([])
            last = key
        blocks[-1].append(spec)
    return blocks


def _block_path(config: SafecaseConfig, cache: Path, block: Sequence[RunSpec]) -> Path:
    dumped = config.model_dump(mode="json")
    sections = {k: dumped[k] for k in ROW_SECTIONS}
    runs = [[r.scenario, r.seed, r.duration_s] for r in block]
    key = json.dumps([sections, list(FEATURE_NAMES), runs], sort_keys=True)
    return cache / f"rows-{hashlib.sha256(key.encode()).hexdigest()[:16]}.npz"


def cached_rows(
    config: SafecaseConfig,
    plan: Sequence[RunSpec],
    workers: int,
    cache: Path | None,
    progress: Callable[[int], None] | None = None,
    block_runs: int = BLOCK_RUNS,
) -> Rows:
    """:func:`gather_rows`, taking every block of ``plan`` found in ``cache`` from there and
    simulating (and storing) only the others.

    ``progress`` is called after each simulated run with the number of the plan's runs ready,
    the cached ones included (so a bar over ``len(plan)`` ends full).
    """
    if cache is None:
        return gather_rows(config, plan, workers, progress)
    blocks = plan_blocks(plan, block_runs)
    paths = [_block_path(config, cache, block) for block in blocks]
    missing = [i for i, path in enumerate(paths) if not path.exists()]
    # Blocks are stored as they complete, so an interrupted run keeps what it simulated.
    cached = len(plan) - sum(len(blocks[i]) for i in missing)
    ready = None if progress is None else (lambda n: progress(cached + n))
    todo = iter(missing)
    block, done = next(todo, -1), []
    for part in _gather_parts(config, [r for i in missing for r in blocks[i]], workers, ready):
        done.append(part)
        if len(done) == len(blocks[block]):
            save_rows(paths[block], concat_rows(done))
            block, done = next(todo, -1), []
    # Every block is read back from its file: the same float32 rounding either way.
    return concat_rows([load_rows(path) for path in paths])
