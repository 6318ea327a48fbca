"""What a rear scanner buys on ``tug_overtaking`` (SR-LID-4), in closed loop: the same seeds
with one forward 270 deg scanner and with a second one facing backwards (one seed under ``ci``,
ten under ``certify``; properties/second_lidar_study.py)."""

from __future__ import annotations

import math

import pytest

from evidence.profiles import active_profile
from evidence.record import current
from pipeline.config import SafecaseConfig
from properties.second_lidar_study import HEADER, overtaking_run, table

CODE = [
    "properties/second_lidar_study.py",
    "pipeline/sources/sim/second_lidar.py",
    "pipeline/sources/sim/overtaking.py",
    "pipeline/scanners.py",
]
# How much earlier the tug must be tracked with the rear scanner [s] (SR-LID-4).
EARLIER_S = 2.0


@pytest.mark.requirement("SR-LID-4", kind="campaign", code=CODE)
def test_a_rear_scanner_tracks_an_overtaking_tug_earlier_without_contact(
    safecase_config: SafecaseConfig,
) -> None:
    certify = active_profile() == "certify"
    n_seeds = 10 if certify else 1
    # 8 s covers the overtaking (the front scanner sees the tug by about 5 s); 14 s the turn.
    duration = 14.0 if certify else 8.0
    runs = [
        overtaking_run(safecase_config, seed, rear, duration)
        for seed in range(n_seeds)
        for rear in (False, True)
    ]
    current().table(
        "tug_overtaking: front scanner only / with the rear scanner",
        HEADER,
        table(runs),
        caption=f"{n_seeds} seeds ({active_profile()} profile); "
        "python -m properties.second_lidar_study --seeds 10",
    )
    for run in runs:
        assert run.moving_contacts == 0, run
    for seed in range(n_seeds):
        front, both = (r for r in runs if r.seed == seed)
        assert math.isfinite(both.seen_s), both
        assert both.seen_s <= front.seen_s - EARLIER_S, (front, both)
        assert both.second_left_out == 0, both
