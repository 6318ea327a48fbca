"""The availability campaign on a LocalCluster gives the figures it gives in one process."""

from __future__ import annotations

import pytest

from pipeline.config import default_config
from safety.availability import compare_all


@pytest.mark.requirement("SR-AVL-1", kind="example", code=["safety/availability.py"])
def test_two_workers_give_the_same_comparisons_in_the_same_order() -> None:
    config = default_config()
    runs = [("pallet_jack_slow", 0, 1.0), ("crossing_pedestrian", 1, 1.0)]
    alone = compare_all(config, runs, workers=1)
    pair = compare_all(config, runs, workers=2)
    assert [(c.name, c.seed) for c in pair.comparisons] == [
        ("pallet_jack_slow", 0),
        ("crossing_pedestrian", 1),
    ]
    for a, b in zip(alone.comparisons, pair.comparisons, strict=True):
        assert a.progress_share() == b.progress_share()
        assert a.nuisance_cycles == b.nuisance_cycles
        assert a.ours.actions == b.ours.actions
