"""Held-out rows grouped by scenario and object role (SR-CLS-6 evidence helper)."""

from __future__ import annotations

import numpy as np

from pipeline.config import default_config
from pipeline.training.data import DRILL, Rows, RunSpec
from properties.heldout_roles import DRAWN, row_roles


def _rows(runs: list[RunSpec], run: list[int], object_id: list[int]) -> Rows:
    n = len(run)
    zeros_i, zeros_f = np.zeros(n, np.int64), np.zeros(n)
    return Rows(
        features=np.zeros((n, 1)),
        label=zeros_i,
        run=np.array(run),
        stamp_s=zeros_f,
        track_id=zeros_i,
        object_id=np.array(object_id),
        range_m=zeros_f,
        runs=runs,
        dropped={},
    )


def test_roles_name_the_objects_of_named_scenarios_and_the_drill() -> None:
    runs = [
        RunSpec(DRILL, 100_000, 5.0),
        RunSpec(DRILL, 100_001, 5.0),
        RunSpec("random_encounter", 100_000, 5.0),
        RunSpec("reversing_forklift_aisle", 100_000, 5.0),
    ]
    rows = _rows(runs, [0, 1, 1, 2, 3, 3], [1, 2, 3, 1, 1, 99])
    assert row_roles(rows, default_config()) == [
        (DRILL, "aisle_forklift"),
        (DRILL, "cross_forklift"),
        (DRILL, "bystander"),
        ("random_encounter", DRAWN),
        ("reversing_forklift_aisle", "forklift"),
        ("reversing_forklift_aisle", "object 99"),
    ]
