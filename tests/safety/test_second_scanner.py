"""A robot with two scanners in the runtime (SR-LID-2, SR-LID-3): what is merged, what is left
out, what the robot does meanwhile, and that it is all in the audit log and replays."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.sources.sim.rig import sim_source
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.second_lidar import SecondLidarSource
from pipeline.types import Action, Scan, SecondScan
from properties.second_lidar_study import front_rear_config
from safety.audit.replay import replay
from safety.run import run_audited
from safety.runtime import CycleInput, Runtime

CODE = [
    "safety/model/second_scanner.py",
    "safety/runtime.py",
    "safety/cycle.py",
    "pipeline/scanners.py",
]
CONFIG = overridden(default_config(), {"scan2": {"enabled": True}})


@pytest.fixture(scope="module")
def classifier() -> Classifier:
    """The committed model, loaded once."""
    return Classifier.from_config(CONFIG.classify)


def _scan(stamp_s: float, range_m: float = math.inf) -> Scan:
    angles = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1080)
    return Scan(stamp_s, angles, np.full(1080, range_m))


def _step(
    config: SafecaseConfig,
    classifier: Classifier,
    first_stamp_s: float,
    second_stamp_s: float | None,
    *,
    delay_s: float = 0.0,
) -> tuple[Action, float, dict[str, object], list[str]]:
    """One cycle at now = 10.0 s (charged 10 ms): action, speed, the audit record's
    ``second_scan`` part and the monitors that objected."""
    second = None if second_stamp_s is None else SecondScan(_scan(second_stamp_s))
    inp = CycleInput.standing(
        _scan(first_stamp_s), 10.0, config, charge_s=0.01, delay_s=delay_s, second=second
    )
    out = Runtime(config, classifier=classifier).step(inp)
    objections = [v.monitor for v in out.decision.verdicts if v.action is not Action.PROCEED]
    part = out.record.inputs.get("second_scan", {})
    return out.command.action, out.command.speed_mps, part, objections


@pytest.mark.requirement("SR-LID-2", kind="example", code=CODE)
def test_a_fresh_second_scan_is_merged_and_objects_to_nothing(classifier: Classifier) -> None:
    action, speed, part, objections = _step(CONFIG, classifier, 9.95, 9.95)
    assert part["state"] == "merged"
    assert part["n_points"] == 0  # an empty world: merged, nothing seen
    assert objections == []
    assert action is Action.PROCEED
    assert speed == CONFIG.stopping.robot_max_speed_mps


@pytest.mark.requirement("SR-LID-2", kind="example", code=CODE)
def test_merged_points_that_age_past_the_bound_by_decision_time_stop_the_robot(
    classifier: Classifier,
) -> None:
    # 0.15 s old when merged (at 10.01 s), 0.20 s old at decision (at 10.06 s): STOP.
    action, _, part, objections = _step(CONFIG, classifier, 9.95, 9.86, delay_s=0.05)
    assert part["state"] == "merged"
    assert objections == ["second_scanner"]
    assert action is Action.STOP


@pytest.mark.parametrize(
    ("on_stale", "action", "objections"),
    [
        ("report", Action.PROCEED, []),
        ("slow", Action.SLOW, ["second_scanner"]),
        ("stop", Action.STOP, ["second_scanner"]),
    ],
)
@pytest.mark.requirement("SR-LID-2", kind="example", code=CODE)
def test_a_stale_second_scan_is_left_out_and_the_robot_does_what_on_stale_says(
    classifier: Classifier, on_stale: str, action: Action, objections: list[str]
) -> None:
    config = overridden(CONFIG, {"scan2": {"on_stale": on_stale}})
    got, speed, part, objected = _step(config, classifier, 9.95, 9.5)
    assert part["state"] == "stale"
    assert part["age_s"] == pytest.approx(0.51)
    assert objected == objections
    assert got is action
    if action is Action.SLOW:
        assert speed == config.monitors.degraded_speed_mps
    # No second scan at all is left out the same way.
    got, _, part, _ = _step(config, classifier, 9.95, None)
    assert (part["state"], got) == ("absent", action)


@pytest.mark.requirement("SR-LID-3", kind="example", code=CODE)
def test_the_first_scanner_stale_stops_the_robot_whatever_the_second_delivers(
    classifier: Classifier,
) -> None:
    action, _, part, objections = _step(CONFIG, classifier, 9.7, 9.95)
    assert part["state"] == "merged"
    assert objections == ["scan_freshness"]
    assert action is Action.STOP


@pytest.mark.requirement(
    "SR-LID-3", kind="campaign", code=[*CODE, "pipeline/sources/sim/second_lidar.py"]
)
def test_a_stalled_second_scanner_is_left_out_while_stale_in_the_closed_loop(
    tmp_path: Path,
) -> None:
    config = front_rear_config(default_config(), rear=True)
    bound = config.monitors.scan_max_age_s
    sim = make_simulation(config, "tug_overtaking", 3, 4.0)
    plain = sim_source(config, sim)
    assert isinstance(plain, SecondLidarSource)
    source = SecondLidarSource(
        plain.inner, plain.lidar.spec, plain.mount, np.random.default_rng(0), outages=[(1.0, 2.0)]
    )
    log = tmp_path / "stall.jsonl"
    states = []
    for out in run_audited(config, source, audit_path=log):
        part = out.record.inputs["second_scan"]
        now = out.decision.command.stamp_s
        assert out.record.inputs["scan"]["stamp_s"] < now
        if part["state"] == "merged":
            assert now - part["stamp_s"] <= bound
        else:
            # Left out only for being stale: its newest revolution is older than the bound.
            assert part["state"] == "stale"
            assert part["age_s"] > bound - 0.05
            assert out.command.speed_mps <= config.monitors.degraded_speed_mps
        states.append(part["state"])
    # Merged before the stall, left out during it, merged again after.
    assert states[0] == "merged"
    assert states[-1] == "merged"
    assert 5 <= states.count("stale") <= 11
    report = replay(log)
    assert report.ok, report.mismatches[:3]
