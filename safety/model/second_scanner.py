"""The second scanner's monitor: what the robot does while it is left out (SR-LID-2, SR-LID-3).

The points stage (:mod:`pipeline.scanners`) merges a second scanner's points only while its
scan is fresh by the first scanner's bound and its window is not covered. This verdict, one per
cycle of a robot with a second scanner configured (``scan2.enabled``), judges again at decision
time, the moment the stopping proof's latency bound refers to (SR-STOP-5):

- merged and still fresh at decision time: no objection;
- merged but no longer fresh at decision time (the cycle took the rest of its age): STOP, since
  this decision rests on points older than the proof allows;
- left out (stale, blocked, absent): what ``scan2.on_stale`` says: ``report`` (no objection,
  the audit log has the report), ``slow`` (``monitors.degraded_speed_mps``) or ``stop``.

The first scanner needs no verdict here: the scan-freshness monitor already stops the robot
when it is stale (:func:`safety.model.monitors.scan_freshness`).
"""

from __future__ import annotations

from pipeline.config import MonitorSection, SecondScanSection
from pipeline.scanners import SecondScanReport
from safety.model.freshness import is_fresh
from safety.model.monitors import MonitorVerdict

__all__ = ["SECOND_SCANNER_MONITOR", "second_scanner_verdict"]

# The verdict's name in a decision's verdicts and the audit log.
SECOND_SCANNER_MONITOR = "second_scanner"


def second_scanner_verdict(
    report: SecondScanReport,
    now_s: float,
    second: SecondScanSection,
    monitors: MonitorSection,
) -> MonitorVerdict:
    """The second scanner's demand at decision time ``now_s`` [s] (module docstring)."""
    name = SECOND_SCANNER_MONITOR
    if report.merged:
        assert report.stamp_s is not None  # a merged scan has a stamp
        if is_fresh(now_s, report.stamp_s, monitors.scan_max_age_s, monitors.clock_skew_s):
            return MonitorVerdict.ok(name)
        age = now_s - report.stamp_s
        return MonitorVerdict.stop(
            name,
            f"second scanner's points in this decision are {age:.6f} s old at decision time, "
            f"more than monitors.scan_max_age_s = {monitors.scan_max_age_s} s",
        )
    if second.on_stale == "report":
        return MonitorVerdict.ok(name)
    old = "" if report.age_s is None else f" ({report.age_s:.3f} s old)"
    why = f"second scanner left out: {report.state.value}{old}"
    if second.on_stale == "slow":
        return MonitorVerdict.slow(name, monitors.degraded_speed_mps, why)
    return MonitorVerdict.stop(name, why)
