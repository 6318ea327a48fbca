"""Monitors and the decision step by example: each monitor, the fold, fail-safe behaviour."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeline.config import default_config
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.types import Action, Command, DriverState
from safety.audit.log import AuditWriter
from safety.audit.replay import replay
from safety.model.decision import GovernorInputs, decide
from safety.model.governor import Governor
from safety.model.monitors import (
    DEFAULT_MONITORS,
    MonitorVerdict,
    Observation,
    combine,
    run_monitors,
)
from safety.runtime import CycleInput, Runtime

MONITORS = ["safety/model/monitors.py"]
CONFIG = default_config()
M = CONFIG.monitors


def _verdicts(obs: Observation) -> dict[str, MonitorVerdict]:
    return {v.monitor: v for v in run_monitors(obs, M)}


def _fine(**changes: object) -> Observation:
    base: dict[str, object] = {
        "now_s": 10.0,
        "previous_now_s": 9.9,
        "scan_stamp_s": 9.85,
        "previous_scan_stamp_s": 9.75,
        "n_beams": 1080,
        "cycle_duration_s": 0.004,
    }
    base.update(changes)
    return Observation(**base)  # type: ignore[arg-type]


def test_a_healthy_cycle_draws_no_objection() -> None:
    assert all(v.action is Action.PROCEED for v in run_monitors(_fine(), M))
    assert [name for name, _ in DEFAULT_MONITORS] == [
        "clock",
        "scan_freshness",
        "driver",
        "deadline",
        "operating_domain",
        "braking",
    ]


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_stale_missing_and_future_scans_stop() -> None:
    stale = _verdicts(_fine(scan_stamp_s=9.7))["scan_freshness"]
    assert stale.action is Action.STOP
    assert (
        stale.reason
        == "stale scan: first beam 0.300000 s old, more than monitors.scan_max_age_s = 0.18 s"
    )
    future = _verdicts(_fine(scan_stamp_s=10.2))["scan_freshness"]
    assert "in the future" in future.reason
    assert _verdicts(_fine(scan_stamp_s=None))["scan_freshness"].reason == "no scan this cycle"


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_clock_jumping_back_stops_with_the_jump() -> None:
    jumped = _verdicts(_fine(previous_now_s=10.5))["clock"]
    assert jumped.action is Action.STOP
    assert jumped.reason.startswith("clock jumped back 0.500000 s (from 10.5 to 10.0")
    back = _verdicts(_fine(previous_scan_stamp_s=9.9))["clock"]
    assert back.reason.startswith("scan stamps went back 0.050000 s")
    assert _verdicts(_fine(now_s=math.nan))["clock"].action is Action.STOP


def test_driver_states_other_than_ok_or_degraded_stop() -> None:
    for state in DriverState:
        verdict = _verdicts(_fine(driver_state=state.value, driver_age_s=0.7))["driver"]
        fresh = state in (DriverState.OK, DriverState.DEGRADED)
        assert (verdict.action is Action.PROCEED) is fresh, state
        if not fresh:
            assert verdict.reason.startswith(
                f"scanner link {state.value}: no valid frame for 0.700 s"
            )


@pytest.mark.requirement("SR-TIM-2", kind="example", code=MONITORS)
def test_deadline_miss_stops_and_unmeasured_cycles_too() -> None:
    late = _verdicts(_fine(cycle_duration_s=0.1005))["deadline"]
    assert late.reason == "cycle took 100.500 ms, over monitors.cycle_deadline_s = 100 ms"
    assert _verdicts(_fine(cycle_duration_s=0.1))["deadline"].action is Action.PROCEED
    assert _verdicts(_fine(cycle_duration_s=None))["deadline"].action is Action.STOP


def test_operating_domain_caps_window_and_gaps() -> None:
    over = _verdicts(_fine(over_cap=(("cluster.max_clusters", 3), ("track.max_tracks", 0))))
    assert over["operating_domain"].reason == (
        "too many objects for the configured caps: cluster.max_clusters dropped 3"
    )
    covered = _verdicts(_fine(n_below_min=600))["operating_domain"]
    assert covered.action is Action.STOP
    assert "window" in covered.reason
    gaps = _verdicts(_fine(scan_complete=False))["operating_domain"]
    assert gaps.action is Action.SLOW
    assert gaps.speed_limit_mps == M.degraded_speed_mps


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_monitor_that_raises_gives_stop_with_its_error() -> None:
    def broken(obs: Observation, cfg: object) -> MonitorVerdict:
        raise ZeroDivisionError("division by zero")

    def wrong(obs: Observation, cfg: object) -> MonitorVerdict:
        return "fine"  # type: ignore[return-value]

    verdicts = run_monitors(_fine(), M, [("broken", broken), ("wrong", wrong)])
    assert [v.reason for v in verdicts] == [
        "monitor broken failed (ZeroDivisionError): division by zero",
        "monitor wrong failed (TypeError): returned str, not a MonitorVerdict",
    ]
    assert all(v.action is Action.STOP for v in verdicts)


def test_combine_keeps_the_most_restrictive_and_every_reason() -> None:
    governor = Command(Action.SLOW, 0.6, 1.0, ("obstacle 0: limit 0.600 m/s",))
    verdicts = [
        MonitorVerdict.ok("clock"),
        MonitorVerdict.slow("operating_domain", 0.3, "incomplete scan"),
        MonitorVerdict.slow("other", 0.5, "something"),
    ]
    final = combine(governor, verdicts, stamp_s=1.0, min_moving_mps=0.05)
    assert final == Command(
        Action.SLOW,
        0.3,
        1.0,
        ("obstacle 0: limit 0.600 m/s", "operating_domain: incomplete scan", "other: something"),
    )
    stop = combine(
        governor,
        [*verdicts, MonitorVerdict.stop("deadline", "late")],
        stamp_s=1.0,
        min_moving_mps=0.05,
    )
    assert stop.action is Action.STOP
    assert stop.reasons[-1] == "deadline: late"
    proceed = Command(Action.PROCEED, 1.0, 1.0)
    slow = combine(
        proceed, [MonitorVerdict.slow("x", 0.04, "tiny")], stamp_s=1.0, min_moving_mps=0.05
    )
    assert slow.action is Action.STOP
    assert slow.reasons[-1] == "combine: limit 0.040 m/s below 0.05 m/s"
    assert (
        combine(proceed, [MonitorVerdict.ok("clock")], stamp_s=1.0, min_moving_mps=0.05) == proceed
    )


def test_combine_without_governor_command_stops() -> None:
    final = combine(None, [], stamp_s=2.0, min_moving_mps=0.05)
    assert final.action is Action.STOP
    assert final.reasons == ("governor: no command (None)",)
    odd = combine("PROCEED", [], stamp_s="x", min_moving_mps=0.05)  # type: ignore[arg-type]
    assert odd.action is Action.STOP
    assert math.isnan(odd.stamp_s)


def test_verdict_and_observation_round_trip() -> None:
    obs = _fine(driver_state="OK", over_cap=(("a", 1),), previous_now_s=math.inf)
    assert Observation.from_dict(obs.to_dict()) == obs
    for verdict in (
        MonitorVerdict.ok("a"),
        MonitorVerdict.slow("b", 0.2, "r"),
        MonitorVerdict.stop("c", "why"),
    ):
        assert MonitorVerdict.from_dict(verdict.to_dict()) == verdict
    with pytest.raises(ValueError, match="needs a reason"):
        MonitorVerdict("x", Action.SLOW, 0.2)


def test_an_observation_with_its_caps_as_a_list_is_refused_naming_the_key() -> None:
    data = _fine(over_cap=(("a", 1),)).to_dict() | {"over_cap": [["a", 1]]}
    with pytest.raises(ValueError) as refused:
        Observation.from_dict(data)
    assert str(refused.value) == (
        "over_cap: expected a mapping of cap name to count, got [['a', 1]]"
    )


def test_decide_runs_governor_and_monitors() -> None:
    governor = Governor.from_config(CONFIG)
    inputs = GovernorInputs(10.0, np.array([0.9, 5.0]), None, np.array([0.95, 0.95]), None)
    decision = decide(governor, inputs, _fine(scan_stamp_s=9.0, previous_scan_stamp_s=None), M)
    assert decision.governor_command is not None
    assert decision.governor_command.action is Action.SLOW
    assert decision.command.action is Action.STOP
    assert decision.command.reasons[0] == decision.governor_command.reasons[0]
    assert decision.command.reasons[1].startswith("scan_freshness: stale scan")
    assert GovernorInputs.from_dict(inputs.to_dict()).to_dict() == inputs.to_dict()


@pytest.mark.requirement("SR-FUS-2", kind="example", code=[*MONITORS, "safety/model/decision.py"])
def test_stale_scan_failed_stage_and_clock_jump_in_the_runtime(tmp_path: Path) -> None:
    sim = make_simulation(CONFIG, "pallet_jack_slow", seed=1, duration_s=1.0)
    scans = list(sim.scans())
    log = tmp_path / "cycles.log"

    def fail_tracking(stage: str) -> None:
        if stage == "track":
            raise RuntimeError("tracker exploded")

    with AuditWriter(log, CONFIG, model_hash=None) as writer:
        cycle = Runtime(CONFIG, writer=writer)

        def at(i: int, now_s: float, **extra: Any) -> CycleInput:
            return CycleInput.standing(scans[i], now_s, CONFIG, charge_s=0.02, **extra)

        fine = cycle.step(at(0, scans[0].stamp_s + 0.1))
        stale = cycle.step(at(1, scans[1].stamp_s + 0.5))
        failed = cycle.step(at(2, scans[2].stamp_s + 0.1, fault=fail_tracking))
        jumped = cycle.step(at(3, scans[0].stamp_s))
    assert not any("stale" in r for r in fine.command.reasons)
    assert stale.command.action is Action.STOP
    assert any(r.startswith("scan_freshness: stale scan") for r in stale.command.reasons)
    assert failed.command.action is Action.STOP
    assert "stage:track: RuntimeError: tracker exploded" in failed.command.reasons
    assert jumped.command.action is Action.STOP
    assert any(r.startswith("clock: clock jumped back") for r in jumped.command.reasons)
    report = replay(log)
    assert report.ok, report.mismatches
    assert report.n_cycles == 4
