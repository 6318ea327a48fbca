"""The decision step's audit form and fold, field by field (SR-AUD-2, SR-FUS-2).

Replay recomputes a cycle's command from the log alone, so every field the decision reads must
come back from its JSON form as the same value, absent optional arrays as None, non-finite
values as the same float; and the decision must fold the governor, the monitors and the stage
failures in that order. The mutation campaign (SR-EVD-5, docs/findings/mutation.md) showed
these written but never read back by a test that claims safety/model/decision.py.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pipeline.config import default_config
from pipeline.types import Action, Command
from safety.model.decision import (
    Decision,
    GovernorInputs,
    command_from_dict,
    command_to_dict,
    decide,
)
from safety.model.governor import Governor
from safety.model.monitors import MonitorVerdict, Observation

DECISION = ["safety/model/decision.py"]
CONFIG = default_config()


def _observation(now_s: float = 10.0) -> Observation:
    return Observation(
        now_s=now_s,
        previous_now_s=now_s - 0.1,
        scan_stamp_s=now_s - 0.1,
        previous_scan_stamp_s=now_s - 0.2,
        n_beams=1000,
        cycle_duration_s=0.004,
    )


@pytest.mark.requirement("SR-AUD-2", kind="example", code=DECISION)
@pytest.mark.parametrize("stamp_s", [12.5, math.inf, -math.inf, math.nan])
def test_a_command_reads_back_from_its_json_form(stamp_s: float) -> None:
    command = Command(Action.SLOW, 0.25, stamp_s, ("a", "b"))
    data = json.loads(json.dumps(command_to_dict(command)))
    assert data == {
        "action": "SLOW",
        "speed_mps": 0.25,
        "stamp_s": stamp_s if math.isfinite(stamp_s) else repr(stamp_s),
        "reasons": ["a", "b"],
    }
    back = command_from_dict(data)
    assert (back.action, back.speed_mps, back.reasons) == (Action.SLOW, 0.25, ("a", "b"))
    assert repr(back.stamp_s) == repr(stamp_s)
    assert isinstance(back.speed_mps, float)


@pytest.mark.requirement("SR-AUD-2", kind="example", code=DECISION)
def test_governor_inputs_read_back_with_every_optional_array() -> None:
    inputs = GovernorInputs(
        stamp_s=3.5,
        free_distance_m=np.array([1.0, math.inf]),
        closing_speed_mps=np.array([0.5, math.nan]),
        confidence=np.array([0.9, 0.1]),
        near_reversal=np.array([False, True]),
    )
    data = json.loads(json.dumps(inputs.to_dict()))
    assert data == {
        "stamp_s": 3.5,
        "free_distance_m": [1.0, "inf"],
        "closing_speed_mps": [0.5, "nan"],
        "confidence": [0.9, 0.1],
        "near_reversal": [False, True],
    }
    back = GovernorInputs.from_dict(data)
    assert back.stamp_s == 3.5
    np.testing.assert_array_equal(back.free_distance_m, [1.0, math.inf])
    np.testing.assert_array_equal(back.closing_speed_mps, [0.5, math.nan])
    np.testing.assert_array_equal(back.confidence, [0.9, 0.1])
    assert back.near_reversal is not None
    assert back.near_reversal.dtype == np.bool_
    np.testing.assert_array_equal(back.near_reversal, [False, True])


@pytest.mark.requirement("SR-AUD-2", kind="example", code=DECISION)
def test_absent_governor_inputs_stay_absent() -> None:
    inputs = GovernorInputs(stamp_s=math.nan, free_distance_m=np.array([2.0]))
    data = json.loads(json.dumps(inputs.to_dict()))
    assert data == {
        "stamp_s": "nan",
        "free_distance_m": [2.0],
        "closing_speed_mps": None,
        "confidence": None,
        "near_reversal": None,
    }
    back = GovernorInputs.from_dict(data)
    assert math.isnan(back.stamp_s)
    assert (back.closing_speed_mps, back.confidence, back.near_reversal) == (None, None, None)


@pytest.mark.requirement("SR-FUS-2", kind="example", code=DECISION)
def test_the_decision_is_the_governors_command_folded_with_every_verdict() -> None:
    governor = Governor.from_config(CONFIG)
    inputs = GovernorInputs(stamp_s=9.9, free_distance_m=np.array([100.0]))
    expected = governor.command(9.9, np.array([100.0]), None, None, None)
    assert expected.action is Action.PROCEED
    decision = decide(governor, inputs, _observation(), CONFIG.monitors)
    assert decision.governor_command == expected
    assert decision.command.action is Action.PROCEED
    assert decision.command.stamp_s == 10.0
    assert decision.command.speed_mps == expected.speed_mps
    assert all(v.action is Action.PROCEED for v in decision.verdicts)
    stage = MonitorVerdict.slow("cluster", 0.3, "slow stage")
    slowed = decide(governor, inputs, _observation(), CONFIG.monitors, [stage])
    assert slowed.verdicts[-1] == stage
    assert slowed.verdicts[:-1] == decision.verdicts
    assert slowed.command.action is Action.SLOW
    assert slowed.command.speed_mps == min(0.3, expected.speed_mps)
    assert "cluster: slow stage" in slowed.command.reasons


@pytest.mark.requirement("SR-FUS-2", kind="example", code=DECISION)
def test_without_governor_inputs_the_decision_stops_with_the_stage_failure() -> None:
    governor = Governor.from_config(CONFIG)
    stage = MonitorVerdict.stop("track", "tracker failed")
    decision = decide(governor, None, _observation(7.0), CONFIG.monitors, [stage])
    assert decision == Decision(decision.command, None, decision.verdicts)
    assert decision.governor_command is None
    assert decision.command.action is Action.STOP
    assert decision.command.speed_mps == 0.0
    assert decision.command.stamp_s == 7.0
    assert decision.verdicts[-1] == stage
    assert "track: tracker failed" in decision.command.reasons


@pytest.mark.requirement("SR-STOP-2", kind="example", code=DECISION)
def test_the_governor_reads_every_recorded_input() -> None:
    governor = Governor.from_config(CONFIG)
    distance = np.array([1.0])
    full = GovernorInputs(
        stamp_s=1.0,
        free_distance_m=distance,
        closing_speed_mps=np.array([0.1]),
        confidence=np.array([0.95]),
        near_reversal=np.array([False]),
    )
    expected = governor.command(1.0, distance, np.array([0.1]), np.array([0.95]), np.array([False]))
    assert full.command(governor) == expected
    without = {
        "closing_speed_mps": governor.command(1.0, distance, None, np.array([0.95]), None),
        "confidence": governor.command(1.0, distance, np.array([0.1]), None, None),
    }
    for name, other in without.items():
        assert other != expected, f"{name} does not change the command in this example"
    reversing = GovernorInputs(1.0, distance, np.array([0.1]), np.array([0.95]), np.array([True]))
    assert reversing.command(governor) == governor.command(
        1.0, distance, np.array([0.1]), np.array([0.95]), np.array([True])
    )
    assert reversing.command(governor) != expected
