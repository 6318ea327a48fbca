"""Braking as the stopping proof assumes it, measured at run time (assumption A-1; SR-STOP-2).

The stopping proof assumes the robot brakes at no less than ``stopping.decel_min_mps2`` once a
STOP reaches its actuator. In the spirit of ModelPlex (Mitsch and Platzer, 2016: check at run
time that the world stays inside the model the proof is about), :class:`BrakingWatch` measures
the deceleration from the robot's odometry while a STOP is in force and hands it to the
``braking`` monitor (:mod:`safety.model.monitors`), which records a STOP naming the broken
assumption when the robot brakes more weakly.

The speed over an interval is the odometry displacement between two scan stamps divided by
their time apart; the deceleration is the drop between the speeds of two consecutive
intervals divided by the time between their midpoints. It is measured only when it means
something: the STOP was in force (and had reached the actuator: one control cycle) before the
earlier interval began, the robot was still moving in the later interval fast enough that it
cannot have come to rest inside it even braking at ``decel_max`` (a robot at rest would read as
weak braking), and both intervals are long enough to measure.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from pipeline.frames import Pose

__all__ = ["BrakingWatch"]

# Intervals shorter than this carry more odometry noise than speed [s].
_MIN_INTERVAL_S = 1e-3


@dataclass
class BrakingWatch:
    """The deceleration to check against ``decel_min`` per cycle (module docstring).

    ``control_cycle_s`` is the time a command takes to reach the actuator [s]; ``decel_max_mps2``
    the strongest braking the proof allows [m/s^2].
    """

    control_cycle_s: float
    decel_max_mps2: float

    def __post_init__(self) -> None:
        self._odometry: deque[tuple[float, float, float]] = deque(maxlen=3)

    def reset(self) -> None:
        """Forget the odometry (a source that restarted, a pose that jumped)."""
        self._odometry.clear()

    def observe(
        self, stamp_s: float | None, pose: Pose, stop_since_s: float | None
    ) -> float | None:
        """The measured deceleration [m/s^2] over the last two intervals ending at ``stamp_s``,
        or None when it is not measured this cycle. ``stop_since_s`` is when the STOP in force
        was decided (None when none is)."""
        if stamp_s is None or not (math.isfinite(stamp_s) and all(map(math.isfinite, pose))):
            return None
        if self._odometry and stamp_s <= self._odometry[-1][0]:
            self._odometry.clear()  # a clock that stood still or ran back: start afresh
        self._odometry.append((stamp_s, pose[0], pose[1]))
        if stop_since_s is None or len(self._odometry) < 3:
            return None
        (t0, x0, y0), (t1, x1, y1), (t2, x2, y2) = self._odometry
        if t0 < stop_since_s + self.control_cycle_s:
            return None  # the STOP had not reached the actuator for the whole span
        dt_a, dt_b = t1 - t0, t2 - t1
        if dt_a < _MIN_INTERVAL_S or dt_b < _MIN_INTERVAL_S:
            return None
        v_a = math.hypot(x1 - x0, y1 - y0) / dt_a
        v_b = math.hypot(x2 - x1, y2 - y1) / dt_b
        if v_b <= 0.5 * self.decel_max_mps2 * dt_b:
            return None  # it may have come to rest inside the later interval
        return (v_a - v_b) / (0.5 * (dt_a + dt_b))
