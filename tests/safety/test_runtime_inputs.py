"""The runtime reads what its input carries besides the scan: the scanner link's health
(SR-DRV-3), an acoustic alert (SR-ACU-3); a standing robot's path (SR-RUN-1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.classify.model import Classifier
from pipeline.config import default_config
from pipeline.types import Action, DriverHealth, DriverState, Scan
from pipeline.types.acoustic import AcousticAlert, AlertKind
from safety.runtime import CycleInput, Runtime

CONFIG = default_config()
CODE = ["safety/runtime.py", "safety/cycle.py", "safety/model/monitors.py"]


@pytest.fixture(scope="module")
def classifier() -> Classifier:
    """The committed model, loaded once."""
    return Classifier.from_config(CONFIG.classify)


def _empty_scan(stamp_s: float) -> Scan:
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    return Scan(stamp_s, angles, np.full(1080, np.inf))


@pytest.mark.requirement("SR-DRV-3", kind="example", code=CODE)
@pytest.mark.parametrize("state", list(DriverState))
def test_a_scanner_link_that_is_not_fresh_stops_the_robot_and_says_why(
    classifier: Classifier, state: DriverState
) -> None:
    """An empty world with the link in each state: OK and DEGRADED proceed at full speed;
    every other state commands STOP naming the state, the time since the last valid frame and
    the driver's last error, and the record's observation holds all three."""
    health = DriverHealth(state, 10.05, 0.75, last_error="read timeout")
    inp = CycleInput.standing(_empty_scan(10.0), 10.1, CONFIG, charge_s=0.01, driver=health)
    out = Runtime(CONFIG, classifier=classifier).step(inp)
    observation = out.record.observation
    assert (observation.driver_state, observation.driver_age_s) == (state.value, 0.75)
    assert observation.driver_error == "read timeout"
    if state in (DriverState.OK, DriverState.DEGRADED):
        assert out.command.action is Action.PROCEED
        return
    assert out.command.action is Action.STOP
    want = f"scanner link {state.value}: no valid frame for 0.750 s, last error: read timeout"
    assert any(want in reason for reason in out.command.reasons), out.command.reasons


@pytest.mark.requirement("SR-ACU-3", kind="example", code=CODE)
@pytest.mark.parametrize(("stamp_s", "caution"), [(10.05, True), (0.0, False)])
def test_the_record_holds_the_acoustic_alert_and_whether_it_capped_the_speed(
    classifier: Classifier, stamp_s: float, caution: bool
) -> None:
    """A fresh alert caps the speed and an old one does not; either way the record holds the
    alert's kind, bearing, confidence and stamp, and whether it capped the speed."""
    alert = AcousticAlert(AlertKind.HORN, 0.5, 0.8, stamp_s)
    inp = CycleInput.standing(_empty_scan(10.0), 10.1, CONFIG, charge_s=0.01, acoustic=alert)
    out = Runtime(CONFIG, classifier=classifier).step(inp)
    assert out.record.inputs["acoustic"] == {
        "kind": "horn",
        "bearing_rad": 0.5,
        "confidence": 0.8,
        "stamp_s": stamp_s,
        "caution": caution,
    }
    assert (out.command.action is not Action.PROCEED) is caution


@pytest.mark.requirement("SR-RUN-1", kind="example", code=CODE)
def test_a_standing_robot_s_path_runs_straight_ahead_from_its_origin() -> None:
    """CycleInput.standing: the robot at the origin of the tracking frame, its path along +x
    for the configured lookahead in the configured steps."""
    rc = CONFIG.runtime
    inp = CycleInput.standing(None, 3.0, CONFIG)
    assert (inp.scan, inp.now_s, inp.robot_pose) == (None, 3.0, (0.0, 0.0, 0.0))
    path = inp.path
    assert path.arc_m[-1] == pytest.approx(rc.path_lookahead_m)
    assert np.allclose(np.diff(path.arc_m), rc.path_step_m)
    np.testing.assert_allclose(path.x_m, path.arc_m, rtol=0, atol=1e-12)
    assert not path.y_m.any()
    assert not path.theta_rad.any()
