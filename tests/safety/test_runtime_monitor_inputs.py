"""The runtime hands the monitors what the cycle saw: the blocked beams of a blinded scanner,
an incomplete scan, the previous scan's stamp, and the braking the stopping proof assumes beside
the braking measured under a STOP, each read back from the record's observation and from the
command it gave (SR-FUS-2, SR-RUN-6)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipeline.classify.model import Classifier
from pipeline.config import default_config
from pipeline.types import Action, Scan
from safety.runtime import CycleInput, Runtime

CONFIG = default_config()
CODE = ["safety/runtime.py"]


@pytest.fixture(scope="module")
def classifier() -> Classifier:
    """The committed model, loaded once."""
    return Classifier.from_config(CONFIG.classify)


def _scan(stamp_s: float, ranges_m: np.ndarray | None = None) -> Scan:
    ranges = np.full(1080, np.inf) if ranges_m is None else ranges_m
    return Scan(stamp_s, np.linspace(-math.pi, math.pi, 1080, endpoint=False), ranges)


@pytest.mark.requirement("SR-FUS-2", kind="example", code=CODE)
def test_a_blinded_scanner_stops_the_robot_with_its_blocked_beams_counted(
    classifier: Classifier,
) -> None:
    """900 of 1080 beams closer than the scanner's minimum range (a covered window)."""
    ranges = np.full(1080, np.inf)
    ranges[:900] = 0.5 * CONFIG.scan.min_range_m
    out = Runtime(CONFIG, classifier=classifier).step(
        CycleInput.standing(_scan(10.0, ranges), 10.1, CONFIG, charge_s=0.01)
    )
    observation = out.record.observation
    assert (observation.n_beams, observation.n_below_min) == (1080, 900)
    assert out.command.action is Action.STOP
    assert any("900 of 1080 beams below the minimum range" in r for r in out.command.reasons)


@pytest.mark.requirement("SR-FUS-2", kind="example", code=CODE)
def test_an_incomplete_scan_limits_the_speed_and_no_scan_is_not_called_incomplete(
    classifier: Classifier,
) -> None:
    out = Runtime(CONFIG, classifier=classifier).step(
        CycleInput.standing(replace(_scan(10.0), complete=False), 10.1, CONFIG, charge_s=0.01)
    )
    assert out.record.observation.scan_complete is False
    assert out.command.action is Action.SLOW
    assert out.command.speed_mps == CONFIG.monitors.degraded_speed_mps
    assert any("incomplete scan" in r for r in out.command.reasons)
    blind = Runtime(CONFIG, classifier=classifier).step(
        CycleInput.standing(None, 10.1, CONFIG, charge_s=0.01)
    )
    assert blind.record.observation.scan_complete is True
    assert blind.command.action is Action.STOP
    assert not any("incomplete" in r for r in blind.command.reasons)


@pytest.mark.requirement("SR-FUS-2", kind="example", code=CODE)
def test_scan_stamps_that_go_back_stop_the_robot(classifier: Classifier) -> None:
    rt = Runtime(CONFIG, classifier=classifier)
    first = rt.step(CycleInput.standing(_scan(10.0), 10.1, CONFIG, charge_s=0.01))
    assert first.record.observation.previous_scan_stamp_s is None
    assert first.command.action is Action.PROCEED
    back = rt.step(CycleInput.standing(_scan(9.0), 10.2, CONFIG, charge_s=0.01))
    assert back.record.observation.previous_scan_stamp_s == 10.0
    assert back.command.action is Action.STOP
    assert any("scan stamps went back 1.000000 s" in r for r in back.command.reasons)


@pytest.mark.requirement("SR-RUN-6", kind="example", code=CODE)
def test_the_braking_the_proof_assumes_is_the_runtime_s_own(classifier: Classifier) -> None:
    rt = Runtime(CONFIG, classifier=classifier)
    out = rt.step(CycleInput.standing(_scan(10.0), 10.1, CONFIG, charge_s=0.01))
    assert out.record.observation.braking_min_mps2 == rt.params.decel_min_mps2
    assert out.record.observation.braking_min_mps2 == CONFIG.stopping.decel_min_mps2


@pytest.mark.requirement("SR-RUN-6", kind="example", code=CODE)
def test_a_robot_braking_too_weakly_under_a_stop_is_flagged_from_its_odometry(
    classifier: Classifier,
) -> None:
    """A wall 0.5 m ahead keeps a STOP in force from 10.1 s while the robot slows by only
    0.1 m/s^2: once three odometry samples lie after the STOP reached the actuator, the record
    holds the measured deceleration and the braking monitor names the assumption."""
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    with np.errstate(divide="ignore"):
        wall = np.where(np.cos(angles) > 0.05, 0.5 / np.cos(angles), np.inf)
    wall = np.where(wall < 20.0, wall, np.inf)
    rt = Runtime(CONFIG, classifier=classifier)
    first = rt.step(CycleInput.standing(_scan(10.1, wall), 10.11, CONFIG, charge_s=0.01))
    assert first.command.action is Action.STOP
    measured = []
    for k in range(1, 9):
        t = 10.1 + 0.1 * k
        x = 1.0 * (t - 10.1) - 0.05 * (t - 10.1) ** 2  # 1 m/s, slowing at 0.1 m/s^2
        inp = replace(
            CycleInput.standing(_scan(t, wall), t + 0.01, CONFIG, charge_s=0.01),
            robot_pose=(x, 0.0, 0.0),
        )
        out = rt.step(inp)
        measured.append(out.record.observation.braking_decel_mps2)
    decel = [d for d in measured if d is not None]
    assert decel, measured
    assert decel[-1] == pytest.approx(0.1, abs=1e-6)
    assert out.command.action is Action.STOP
    assert any("braking" in r for r in out.command.reasons), out.command.reasons
