"""The cautious mode: a fresh acoustic alert caps the commanded speed (SR-ACU-3).

:func:`cautious_speed_mps` is the ONE definition, written with
:func:`~safety.model.readings.select`, :func:`~safety.model.readings.minimum` and the freshness
guard (:func:`safety.model.freshness.is_fresh`), so it evaluates with floats and z3 reals alike
(``properties/test_acoustic_caution.py`` proves the z3 reading). While an alert stamped
``alert_stamp_s`` is fresh at ``now_s`` (``acoustic.max_age_s``, ``acoustic.clock_skew_s``), a
speed ``v`` becomes ``min(v, caution_mps)``; otherwise it stays ``v``. So caution only ever lowers
the speed, never below what the cap allows, and a stale alert changes nothing. An alert is a
bearing, never a position: it creates no obstacle and no free distance.

The runtime applies it as a verdict (:func:`caution_verdict`) whose limit is the formula at the
robot's maximum speed; :func:`safety.model.monitors.combine` takes the smallest limit, and
``min(v, cautious(v_max)) = cautious(v)`` for every governor speed ``v <= v_max`` (proved too),
so the command is the formula applied to the governor's speed.
"""

from __future__ import annotations

import math
from typing import Any

from pipeline.config import AcousticSection
from pipeline.types.acoustic import AcousticAlert
from safety.model.freshness import FRESHNESS_GUARD_S, is_fresh
from safety.model.monitors import MonitorVerdict
from safety.model.readings import Real, minimum, select

__all__ = ["CAUTION_MONITOR", "caution_verdict", "cautious_speed_mps"]

# The name of the caution verdict in a decision's verdicts and the audit log.
CAUTION_MONITOR = "acoustic_caution"


def cautious_speed_mps(
    speed_mps: Real,
    now_s: Real,
    alert_stamp_s: Real,
    max_age_s: Real,
    skew_s: Real,
    caution_mps: Real,
    guard_s: Any = FRESHNESS_GUARD_S,
) -> Real:
    """``min(speed_mps, caution_mps)`` while the alert is fresh at ``now_s``, else
    ``speed_mps`` [m/s] (SR-ACU-3); one definition, every reading."""
    fresh = is_fresh(now_s, alert_stamp_s, max_age_s, skew_s, guard_s)
    return select(fresh, minimum(speed_mps, caution_mps), speed_mps)


def caution_verdict(
    now_s: float, alert: AcousticAlert | None, section: AcousticSection, max_speed_mps: float
) -> MonitorVerdict:
    """The cautious mode's verdict at decision time ``now_s`` [s]: a speed limit while
    ``alert`` is fresh, no objection otherwise (SR-ACU-3). Never raises: a verdict that cannot
    be computed is a STOP with the reason."""
    if alert is None:
        return MonitorVerdict.ok(CAUTION_MONITOR)
    try:
        limit = float(
            cautious_speed_mps(
                max_speed_mps,
                now_s,
                alert.stamp_s,
                section.max_age_s,
                section.clock_skew_s,
                section.caution_speed_mps,
            )
        )
        if not math.isfinite(limit) or limit >= max_speed_mps:
            return MonitorVerdict.ok(CAUTION_MONITOR)
        return MonitorVerdict.slow(
            CAUTION_MONITOR,
            limit,
            f"{alert.kind.value} heard at bearing {math.degrees(alert.bearing_rad):.0f} deg "
            f"({now_s - alert.stamp_s:.3f} s ago, confidence {alert.confidence:.2f}): speed "
            f"limited to acoustic.caution_speed_mps = {section.caution_speed_mps} m/s",
        )
    except Exception as exc:  # fail safe: a caution that cannot be evaluated stops the robot
        return MonitorVerdict.stop(CAUTION_MONITOR, f"caution failed ({type(exc).__name__}): {exc}")
