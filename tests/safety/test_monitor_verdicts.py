"""The second scanner's and the acoustic caution's verdicts, as the audit log shows them: the
monitor's name on every branch and reasons that state the age and the cause (SR-LID-2, SR-ACU-3).
A verdict without its name, or a reason with a wrong age, misleads whoever reads the log."""

from __future__ import annotations

import math

import pytest

from pipeline.config import SecondScanSection, default_config, overridden
from pipeline.scanners import SecondScanReport, SecondScanState
from pipeline.types import Action
from pipeline.types.acoustic import AcousticAlert, AlertKind
from safety.model.caution import CAUTION_MONITOR, caution_verdict
from safety.model.second_scanner import SECOND_SCANNER_MONITOR, second_scanner_verdict

CONFIG = default_config()
MONITORS = CONFIG.monitors


def _second(on_stale: str) -> SecondScanSection:
    return overridden(CONFIG, {"scan2": {"on_stale": on_stale}}).scan2


@pytest.mark.requirement("SR-LID-2", kind="example", code=["safety/model/second_scanner.py"])
def test_second_scanner_verdicts_carry_their_name_and_the_scans_age() -> None:
    fresh = SecondScanReport(SecondScanState.MERGED, stamp_s=10.0, age_s=0.05, n_points=3)
    ok = second_scanner_verdict(fresh, 10.05, _second("stop"), MONITORS)
    assert (ok.monitor, ok.action) == (SECOND_SCANNER_MONITOR, Action.PROCEED)
    # Merged at 0.05 s, decided 0.25 s after its stamp: older than the 0.18 s bound.
    aged = second_scanner_verdict(fresh, 10.25, _second("report"), MONITORS)
    assert aged.monitor == SECOND_SCANNER_MONITOR
    assert aged.action is Action.STOP
    assert aged.reason.startswith("second scanner's points in this decision are 0.250000 s old")
    stale = SecondScanReport(SecondScanState.STALE, stamp_s=9.0, age_s=1.25)
    reported = second_scanner_verdict(stale, 10.25, _second("report"), MONITORS)
    assert (reported.monitor, reported.action) == (SECOND_SCANNER_MONITOR, Action.PROCEED)
    slow = second_scanner_verdict(stale, 10.25, _second("slow"), MONITORS)
    assert slow.monitor == SECOND_SCANNER_MONITOR
    assert slow.action is Action.SLOW
    assert slow.speed_limit_mps == MONITORS.degraded_speed_mps
    assert slow.reason == "second scanner left out: stale (1.250 s old)"
    absent = SecondScanReport(SecondScanState.ABSENT)
    stop = second_scanner_verdict(absent, 10.25, _second("stop"), MONITORS)
    assert (stop.monitor, stop.action) == (SECOND_SCANNER_MONITOR, Action.STOP)
    assert stop.reason == "second scanner left out: absent"


def _alert(stamp_s: float) -> AcousticAlert:
    return AcousticAlert(AlertKind.BEEPER, math.radians(90.0), 0.8, stamp_s)


@pytest.mark.requirement("SR-ACU-3", kind="example", code=["safety/model/caution.py"])
def test_caution_verdicts_carry_their_name_the_alerts_age_and_a_failures_cause() -> None:
    section = CONFIG.acoustic
    none = caution_verdict(5.0, None, section, 2.0)
    assert (none.monitor, none.action) == (CAUTION_MONITOR, Action.PROCEED)
    heard = caution_verdict(5.0, _alert(4.9), section, 2.0)
    assert heard.monitor == CAUTION_MONITOR
    assert heard.action is Action.SLOW
    assert heard.speed_limit_mps == section.caution_speed_mps
    assert heard.reason.startswith("beeper heard at bearing 90 deg (0.100 s ago, confidence 0.80)")
    old = caution_verdict(50.0, _alert(4.9), section, 2.0)
    assert (old.monitor, old.action) == (CAUTION_MONITOR, Action.PROCEED)
    broken = caution_verdict(5.0, _alert(4.9), section, "fast")  # type: ignore[arg-type]
    assert broken.monitor == CAUTION_MONITOR
    assert broken.action is Action.STOP
    assert broken.reason.startswith("caution failed (TypeError): ")
