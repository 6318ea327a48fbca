"""What a rear scanner buys on ``tug_overtaking`` (SR-LID-4), in closed loop: the same seeds
with one forward 270 deg scanner and with a second one facing backwards (one seed under ``ci``,
ten under ``certify``; properties/second_lidar_study.py)."""

from __future__ import annotations

import math

import pytest

from evidence.profiles import by_profile
from evidence.record import current
from pipeline.config import SafecaseConfig
from properties.ahead import ahead
from properties.second_lidar_study import HEADER, overtaking_run, table
from properties.studies import caption, flat, side_by_side

CODE = [
    "properties/second_lidar_study.py",
    "pipeline/sources/sim/second_lidar.py",
    "pipeline/sources/sim/overtaking.py",
    "pipeline/scanners.py",
]
# How much earlier the tug must be tracked with the rear scanner [s] (SR-LID-4).
EARLIER_S = 2.0


@pytest.mark.requirement("SR-LID-4", kind="campaign", code=CODE)
@ahead
def test_a_rear_scanner_tracks_an_overtaking_tug_earlier_without_contact(
    safecase_config: SafecaseConfig,
) -> None:
    n_seeds = by_profile(ci=1, certify=10)
    # 8 s covers the overtaking (the front scanner sees the tug by about 5 s); 14 s the turn.
    duration = by_profile(ci=8.0, certify=14.0)
    pairs = side_by_side(
        lambda seed, rear: overtaking_run(safecase_config, seed, rear, duration), range(n_seeds)
    )
    current().table(
        "tug_overtaking: front scanner only / with the rear scanner",
        HEADER,
        table(flat(pairs)),
        caption=caption(n_seeds, "python -m properties.second_lidar_study --seeds 10", duration),
    )
    for front, both in pairs:
        assert front.moving_contacts == 0, front
        assert both.moving_contacts == 0, both
        assert math.isfinite(both.seen_s), both
        assert both.seen_s <= front.seen_s - EARLIER_S, (front, both)
        assert both.second_left_out == 0, both
