"""Runtime monitors and the final decision: staleness, clock, driver, deadline, operating domain.

Requirements served: SR-FUS-2 (a stale scan or a clock that jumps back gives STOP with the
reason), SR-TIM-2 (a cycle over its deadline gives STOP with the reason), SR-FUS-1 (scan
freshness uses the same guard as fusion, :func:`safety.model.freshness.is_fresh`).

Each monitor is a small pure function of one :class:`Observation` (what the cycle saw, with
the previous cycle's clock readings) and the ``monitors`` configuration section, returning a
:class:`MonitorVerdict`: no objection, SLOW to a speed, or STOP, always with a reason when it
objects.
:func:`run_monitors` never raises: a monitor that fails yields STOP naming the failure.
:func:`combine` folds the governor's command and every verdict into the final command (the
most restrictive wins, every reason is kept); :mod:`safety.model.decision` chains governor, monitors
and :func:`combine` into the decision step that the audit replay re-runs (SR-AUD-2).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from pipeline.config import MonitorSection
from pipeline.types import Action, Command, DriverState
from safety.model.freshness import is_fresh

__all__ = [
    "DEFAULT_MONITORS",
    "Monitor",
    "MonitorVerdict",
    "Observation",
    "combine",
    "run_monitors",
]


@dataclass(frozen=True, slots=True)
class MonitorVerdict:
    """One monitor's demand for this cycle: PROCEED (no objection), SLOW or STOP.

    ``speed_limit_mps`` is the largest speed the monitor allows (``inf`` for no objection, 0 for
    STOP); ``reason`` says why and is never empty for SLOW or STOP.
    """

    monitor: str
    action: Action
    speed_limit_mps: float = math.inf
    reason: str = ""

    def __post_init__(self) -> None:
        if self.action is Action.STOP and self.speed_limit_mps != 0.0:
            raise ValueError(f"MonitorVerdict {self.monitor}: STOP must limit the speed to 0")
        if self.action is not Action.PROCEED and not self.reason:
            raise ValueError(f"MonitorVerdict {self.monitor}: {self.action.value} needs a reason")
        if not self.speed_limit_mps >= 0.0:
            raise ValueError(f"MonitorVerdict {self.monitor}: speed_limit_mps must be >= 0")

    @classmethod
    def ok(cls, monitor: str) -> MonitorVerdict:
        """No objection."""
        return cls(monitor, Action.PROCEED)

    @classmethod
    def stop(cls, monitor: str, reason: str) -> MonitorVerdict:
        """A STOP demand with its reason."""
        return cls(monitor, Action.STOP, 0.0, reason)

    @classmethod
    def slow(cls, monitor: str, speed_mps: float, reason: str) -> MonitorVerdict:
        """A speed limit [m/s] with its reason (0 counts as STOP)."""
        if speed_mps <= 0.0:
            return cls.stop(monitor, reason)
        return cls(monitor, Action.SLOW, float(speed_mps), reason)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``speed_limit_mps`` None for no limit)."""
        limit = None if math.isinf(self.speed_limit_mps) else self.speed_limit_mps
        return {
            "monitor": self.monitor,
            "action": self.action.value,
            "speed_limit_mps": limit,
            "reason": self.reason,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> MonitorVerdict:
        """Inverse of :meth:`to_dict`."""
        limit = data["speed_limit_mps"]
        return cls(
            str(data["monitor"]),
            Action(data["action"]),
            math.inf if limit is None else float(limit),
            str(data["reason"]),
        )


@dataclass(frozen=True, slots=True)
class Observation:
    """What the monitors look at in one cycle; recorded in the audit log and replayable.

    Times in seconds on the decision clock. ``previous_now_s`` / ``previous_scan_stamp_s`` are
    the largest decision time and scan stamp seen before this cycle (None on the first cycle).
    ``scan_stamp_s`` is None when no scan arrived. ``driver_state`` is a
    :class:`~pipeline.types.DriverState` value, or None for a source without a serial link
    (simulator, recorded log). ``cycle_duration_s`` is the measured time from the start of the
    cycle to the decision. ``over_cap`` names every per-cycle cap that dropped something this
    cycle, with how many items it dropped.
    """

    now_s: float
    previous_now_s: float | None = None
    scan_stamp_s: float | None = None
    previous_scan_stamp_s: float | None = None
    scan_complete: bool = True
    n_beams: int = 0
    n_below_min: int = 0
    driver_state: str | None = None
    driver_age_s: float | None = None
    driver_error: str = ""
    cycle_duration_s: float | None = None
    over_cap: tuple[tuple[str, int], ...] = field(default_factory=tuple)
    braking_decel_mps2: float | None = None
    braking_min_mps2: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``over_cap`` as a mapping; non-finite floats as text)."""
        data = asdict(self)
        data["over_cap"] = dict(self.over_cap)
        for key, value in data.items():
            if isinstance(value, float) and not math.isfinite(value):
                data[key] = repr(value)
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Observation:
        """Inverse of :meth:`to_dict`."""
        values = dict(data)
        for key in (
            "now_s",
            "previous_now_s",
            "scan_stamp_s",
            "previous_scan_stamp_s",
            "driver_age_s",
            "cycle_duration_s",
            "braking_decel_mps2",
            "braking_min_mps2",
        ):
            if isinstance(values.get(key), str):
                values[key] = float(values[key])
        over_cap = values["over_cap"]
        if not isinstance(over_cap, Mapping):
            raise ValueError(f"over_cap: expected a mapping of cap name to count, got {over_cap!r}")
        values["over_cap"] = tuple((str(k), int(v)) for k, v in over_cap.items())
        return cls(**values)


Monitor = Callable[[Observation, MonitorSection], MonitorVerdict]


def scan_freshness(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
    """STOP unless a scan arrived whose first beam is fresh at decision time (SR-FUS-2)."""
    name = "scan_freshness"
    if obs.scan_stamp_s is None:
        return MonitorVerdict.stop(name, "no scan this cycle")
    if is_fresh(obs.now_s, obs.scan_stamp_s, cfg.scan_max_age_s, cfg.clock_skew_s):
        return MonitorVerdict.ok(name)
    age = obs.now_s - obs.scan_stamp_s
    if age < -cfg.clock_skew_s:
        why = f"stamped {-age:.6f} s in the future (clock skew allowed {cfg.clock_skew_s} s)"
    else:
        why = f"{age:.6f} s old, more than monitors.scan_max_age_s = {cfg.scan_max_age_s} s"
    return MonitorVerdict.stop(name, f"stale scan: first beam {why}")


def clock(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
    """STOP when the decision clock or the scan stamps run backwards (SR-FUS-2)."""
    name = "clock"
    if not math.isfinite(obs.now_s):
        return MonitorVerdict.stop(name, f"decision time {obs.now_s!r} is not a finite time")
    limit = cfg.max_clock_jump_back_s
    if obs.previous_now_s is not None and obs.now_s < obs.previous_now_s - limit:
        return MonitorVerdict.stop(
            name,
            f"clock jumped back {obs.previous_now_s - obs.now_s:.6f} s (from "
            f"{obs.previous_now_s!r} to {obs.now_s!r}; allowed {limit} s)",
        )
    if (
        obs.scan_stamp_s is not None
        and obs.previous_scan_stamp_s is not None
        and obs.scan_stamp_s < obs.previous_scan_stamp_s - limit
    ):
        return MonitorVerdict.stop(
            name,
            f"scan stamps went back {obs.previous_scan_stamp_s - obs.scan_stamp_s:.6f} s (from "
            f"{obs.previous_scan_stamp_s!r} to {obs.scan_stamp_s!r}; allowed {limit} s)",
        )
    return MonitorVerdict.ok(name)


def driver_health(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
    """STOP unless the scanner link reads OK or DEGRADED (fresh frames arriving)."""
    name = "driver"
    if obs.driver_state is None:
        return MonitorVerdict.ok(name)
    state = DriverState(obs.driver_state)
    if state in (DriverState.OK, DriverState.DEGRADED):
        return MonitorVerdict.ok(name)
    detail = f", last error: {obs.driver_error}" if obs.driver_error else ""
    age = f"{obs.driver_age_s:.3f} s" if obs.driver_age_s is not None else "unknown time"
    return MonitorVerdict.stop(
        name, f"scanner link {state.value}: no valid frame for {age}{detail}"
    )


def deadline(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
    """STOP when the cycle took longer than ``monitors.cycle_deadline_s`` (SR-TIM-2)."""
    name = "deadline"
    duration = obs.cycle_duration_s
    if duration is None or not math.isfinite(duration):
        return MonitorVerdict.stop(name, f"cycle duration not measured ({duration!r})")
    if duration > cfg.cycle_deadline_s:
        return MonitorVerdict.stop(
            name,
            f"cycle took {duration * 1e3:.3f} ms, over monitors.cycle_deadline_s = "
            f"{cfg.cycle_deadline_s * 1e3:g} ms",
        )
    return MonitorVerdict.ok(name)


def operating_domain(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
    """STOP outside the operating domain: caps overflowed or the window covered; SLOW on an
    incomplete scan (frames the driver rejected left gaps)."""
    name = "operating_domain"
    dropped = [f"{key} dropped {n}" for key, n in obs.over_cap if n > 0]
    if dropped:
        return MonitorVerdict.stop(
            name, "too many objects for the configured caps: " + "; ".join(dropped)
        )
    if obs.n_beams > 0 and obs.n_below_min > cfg.max_blocked_fraction * obs.n_beams:
        return MonitorVerdict.stop(
            name,
            f"{obs.n_below_min} of {obs.n_beams} beams below the minimum range (window "
            f"covered?), more than monitors.max_blocked_fraction = {cfg.max_blocked_fraction}",
        )
    if not obs.scan_complete:
        return MonitorVerdict.slow(
            name,
            cfg.degraded_speed_mps,
            f"incomplete scan (rejected frames left gaps): speed limited to "
            f"monitors.degraded_speed_mps = {cfg.degraded_speed_mps} m/s",
        )
    return MonitorVerdict.ok(name)


def braking(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
    """STOP, naming the broken assumption, when the robot brakes under a STOP more weakly than
    ``monitors.braking_tolerance`` times the deceleration the stopping proof assumes (A-1)."""
    name = "braking"
    decel, least = obs.braking_decel_mps2, obs.braking_min_mps2
    if decel is None or least is None:
        return MonitorVerdict.ok(name)
    if not decel >= cfg.braking_tolerance * least:
        return MonitorVerdict.stop(
            name,
            f"the robot decelerated at {decel:.3f} m/s^2 under a STOP, below "
            f"monitors.braking_tolerance x stopping.decel_min_mps2 = "
            f"{cfg.braking_tolerance} x {least} m/s^2: the stopping proof's braking "
            "assumption (A-1) does not hold",
        )
    return MonitorVerdict.ok(name)


DEFAULT_MONITORS: tuple[tuple[str, Monitor], ...] = (
    ("clock", clock),
    ("scan_freshness", scan_freshness),
    ("driver", driver_health),
    ("deadline", deadline),
    ("operating_domain", operating_domain),
    ("braking", braking),
)


def run_monitors(
    obs: Observation,
    cfg: MonitorSection,
    monitors: Sequence[tuple[str, Monitor]] = DEFAULT_MONITORS,
) -> tuple[MonitorVerdict, ...]:
    """Every monitor's verdict on ``obs``; never raises (a failing monitor gives STOP)."""
    verdicts = []
    for name, monitor in monitors:
        try:
            verdict = monitor(obs, cfg)
            if not isinstance(verdict, MonitorVerdict):
                raise TypeError(f"returned {type(verdict).__name__}, not a MonitorVerdict")
        except Exception as exc:  # fail safe: whatever went wrong in a monitor stops the robot
            verdict = MonitorVerdict.stop(
                name, f"monitor {name} failed ({type(exc).__name__}): {exc}"
            )
        verdicts.append(verdict)
    return tuple(verdicts)


def combine(
    command: Command | None,
    verdicts: Sequence[MonitorVerdict],
    *,
    stamp_s: float,
    min_moving_mps: float,
) -> Command:
    """The final command: the governor's ``command`` made as restrictive as any verdict demands.

    The speed is the smallest of the governor's and every verdict's limit; STOP when any party
    says STOP or the speed is below ``min_moving_mps``; SLOW when any limit binds. Reasons: the
    governor's, then ``"<monitor>: <reason>"`` for each objecting verdict, in order. Never
    raises: a missing or malformed governor command counts as STOP with the reason.
    """
    try:
        reasons: list[str] = []
        if isinstance(command, Command):
            speed = command.speed_mps
            stop = command.action is Action.STOP
            slow = command.action is Action.SLOW
            reasons.extend(command.reasons)
        else:
            speed, stop, slow = 0.0, True, False
            reasons.append(f"governor: no command ({command!r})")
        for verdict in verdicts:
            if verdict.action is Action.PROCEED:
                continue
            reasons.append(f"{verdict.monitor}: {verdict.reason}")
            stop = stop or verdict.action is Action.STOP
            slow = slow or verdict.action is Action.SLOW
            speed = min(speed, verdict.speed_limit_mps)
        if not math.isfinite(speed) or speed < 0.0:
            stop = True
            reasons.append(f"combine: speed {speed!r} is not a finite speed")
        if stop or speed < min_moving_mps:
            if not stop:
                reasons.append(f"combine: limit {speed:.3f} m/s below {min_moving_mps} m/s")
            return Command(Action.STOP, 0.0, float(stamp_s), tuple(reasons))
        if slow:
            return Command(Action.SLOW, float(speed), float(stamp_s), tuple(reasons))
        return Command(Action.PROCEED, float(speed), float(stamp_s), tuple(reasons))
    except Exception as exc:  # fail safe, whatever was handed in
        return Command(Action.STOP, 0.0, _stamp(stamp_s), (f"combine failed: {exc}",))


def _stamp(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
