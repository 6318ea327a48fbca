"""Data plans and the block cache of simulated rows (SR-CLS-3)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.config import SafecaseConfig
from pipeline.training.data import DRILL, RunSpec
from pipeline.training.plan import NAMED, cached_rows, data_plan, gather_rows, plan_blocks

CODE = ["pipeline/training/plan.py"]


def test_blocks_follow_scenario_duration_and_seed_range() -> None:
    plan = [RunSpec(DRILL, s, 3.0) for s in (48, 49, 50)]
    plan += [RunSpec("random_encounter", 50, 3.0), RunSpec("random_encounter", 51, 5.0)]
    blocks = plan_blocks(plan, 50)
    assert [[(r.scenario, r.seed) for r in b] for b in blocks] == [
        [(DRILL, 48), (DRILL, 49)],
        [(DRILL, 50)],
        [("random_encounter", 50)],
        [("random_encounter", 51)],
    ]
    blocks = plan_blocks(data_plan(2, 120, 75, 20.0, 0))
    assert len(blocks) == len(NAMED) + 3 + 2  # encounters 0-49, 50-99, 100-119; drills 0-49, 50-74
    assert sum(len(b) for b in blocks) == 2 * len(NAMED) + 195
    with pytest.raises(ValueError, match="block_runs must be at least 1, got 0"):
        plan_blocks(plan, 0)


@pytest.mark.requirement("SR-CLS-3", kind="example", code=CODE)
def test_a_grown_plan_simulates_only_its_new_blocks(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    first = [RunSpec(DRILL, 0, 3.0), RunSpec(DRILL, 1, 3.0)]
    grown = [*first, RunSpec(DRILL, 2, 3.0)]
    simulated: list[list[int]] = [[], []]
    a = cached_rows(safecase_config, first, 1, tmp_path, simulated[0].append, block_runs=1)
    b = cached_rows(safecase_config, grown, 1, tmp_path, simulated[1].append, block_runs=1)
    assert simulated == [[1, 2], [3]]  # progress: runs ready, cached ones included
    assert len(list(tmp_path.glob("rows-*.npz"))) == 3
    fresh = gather_rows(safecase_config, grown)
    assert b.runs == grown
    assert a.runs == first
    assert np.array_equal(b.run, fresh.run)
    assert set(b.run.tolist()) == {0, 1, 2}
    rounded = fresh.features.astype(np.float32).astype(np.float64)
    assert np.array_equal(b.features, rounded, equal_nan=True)
    assert np.array_equal(b.label, fresh.label)
    assert np.array_equal(b.track_id, fresh.track_id)
    assert b.dropped == fresh.dropped
    assert np.array_equal(a.features, b.features[b.run < 2], equal_nan=True)
    # A changed row-shaping section misses every block.
    other = safecase_config.model_copy(
        update={"cluster": safecase_config.cluster.model_copy(update={"min_points": 5})}
    )
    again: list[int] = []
    cached_rows(other, first, 1, tmp_path, again.append, block_runs=1)
    assert again == [1, 2]
    assert len(list(tmp_path.glob("rows-*.npz"))) == 5


class _InterruptedError(Exception):
    pass


def test_an_interrupted_plan_keeps_the_blocks_it_finished(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    plan = [RunSpec(DRILL, s, 3.0) for s in (5, 6, 7)]

    def interrupt_at_second_run(done: int) -> None:
        if done == 2:
            raise _InterruptedError

    with pytest.raises(_InterruptedError):
        cached_rows(safecase_config, plan, 1, tmp_path, interrupt_at_second_run, block_runs=1)
    assert len(list(tmp_path.glob("rows-*.npz"))) == 1
    simulated: list[int] = []
    rows = cached_rows(safecase_config, plan, 1, tmp_path, simulated.append, block_runs=1)
    assert simulated == [2, 3]
    assert rows.runs == plan
