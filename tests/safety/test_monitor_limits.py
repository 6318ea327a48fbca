"""The monitors at their exact limits, and the fold of their verdicts into the final command.

Each limit is checked on both sides of its threshold (the value itself and the next float
past it), so a comparison that moves by one step, or a limit added where it is subtracted,
fails here; the mutation campaign (SR-EVD-5, docs/findings/mutation.md) showed these
boundaries unwatched.
"""

from __future__ import annotations

import math
from dataclasses import fields

import pytest

from pipeline.config import MonitorSection, default_config
from pipeline.types import Action, Command, DriverState
from safety.model.monitors import MonitorVerdict, Observation, combine, run_monitors

MONITORS = ["safety/model/monitors.py"]
M = default_config().monitors


def _verdict(obs: Observation, cfg: MonitorSection = M, name: str = "") -> MonitorVerdict:
    return {v.monitor: v for v in run_monitors(obs, cfg)}[name]


def _obs(**changes: object) -> Observation:
    base: dict[str, object] = {
        "now_s": 10.0,
        "previous_now_s": 9.9,
        "scan_stamp_s": 9.9,
        "previous_scan_stamp_s": 9.8,
        "n_beams": 1000,
        "cycle_duration_s": 0.004,
    }
    base.update(changes)
    return Observation(**base)  # type: ignore[arg-type]


def _below(x: float) -> float:
    return math.nextafter(x, -math.inf)


def _above(x: float) -> float:
    return math.nextafter(x, math.inf)


# -- clock ---------------------------------------------------------------------------------------


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_the_clock_may_step_back_by_its_limit_and_not_one_float_more() -> None:
    cfg = M.model_copy(update={"max_clock_jump_back_s": 0.25})
    assert _verdict(_obs(previous_now_s=10.1), cfg, "clock").action is Action.PROCEED
    assert _verdict(_obs(previous_now_s=10.25), cfg, "clock").action is Action.PROCEED
    jumped = _verdict(_obs(previous_now_s=_above(10.25)), cfg, "clock")
    assert jumped.action is Action.STOP
    assert jumped.reason.startswith("clock jumped back 0.250000 s (from 10.250000000000002 to")
    assert jumped.reason.endswith("allowed 0.25 s)")
    stamps = _obs(scan_stamp_s=9.75, previous_scan_stamp_s=10.0, now_s=9.9)
    assert _verdict(stamps, cfg, "clock").action is Action.PROCEED
    back = _verdict(_obs(scan_stamp_s=_below(9.75), previous_scan_stamp_s=10.0), cfg, "clock")
    assert back.action is Action.STOP
    assert back.reason.startswith("scan stamps went back 0.250000 s (from 10.0 to 9.7499")


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_with_no_allowance_the_clock_may_stand_still_but_not_step_back() -> None:
    assert M.max_clock_jump_back_s == 0.0
    assert _verdict(_obs(previous_now_s=10.0), name="clock").action is Action.PROCEED
    assert _verdict(_obs(previous_now_s=_above(10.0)), name="clock").action is Action.STOP
    same = _obs(scan_stamp_s=9.9, previous_scan_stamp_s=9.9)
    assert _verdict(same, name="clock").action is Action.PROCEED
    back = _obs(scan_stamp_s=9.9, previous_scan_stamp_s=_above(9.9))
    assert _verdict(back, name="clock").action is Action.STOP


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_the_first_cycle_has_no_previous_time_and_draws_no_clock_objection() -> None:
    first = _obs(previous_now_s=None, previous_scan_stamp_s=None)
    assert _verdict(first, name="clock") == MonitorVerdict.ok("clock")
    no_scan = _obs(scan_stamp_s=None)
    assert _verdict(no_scan, name="clock") == MonitorVerdict.ok("clock")
    for bad in (math.nan, math.inf, -math.inf):
        verdict = _verdict(_obs(now_s=bad, previous_now_s=None), name="clock")
        assert verdict == MonitorVerdict.stop(
            "clock", f"decision time {bad!r} is not a finite time"
        )


# -- scan freshness and the scanner link ------------------------------------------------------


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_refused_scan_is_called_stale_or_future_by_the_sign_of_its_age() -> None:
    future = _verdict(_obs(scan_stamp_s=10.3), name="scan_freshness")
    assert future.reason == (
        "stale scan: first beam stamped 0.300000 s in the future (clock skew allowed 0.0 s)"
    )
    skewed = M.model_copy(update={"clock_skew_s": 0.1, "scan_max_age_s": 0.15})
    old = _verdict(_obs(scan_stamp_s=9.93), skewed, "scan_freshness")
    assert old.reason == (
        "stale scan: first beam 0.070000 s old, more than monitors.scan_max_age_s = 0.15 s"
    )
    ahead = _verdict(_obs(scan_stamp_s=10.125), skewed, "scan_freshness")
    assert ahead.reason.startswith("stale scan: first beam stamped 0.125000 s in the future")
    # A maximum age below the 1 ns rounding guard refuses even a scan of age 0: it is old.
    tiny = M.model_copy(update={"scan_max_age_s": 1e-12})
    now = _verdict(_obs(scan_stamp_s=10.0), tiny, "scan_freshness")
    assert now.reason.startswith("stale scan: first beam 0.000000 s old")


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_lost_link_names_its_state_its_age_and_the_last_error() -> None:
    stale = _verdict(_obs(driver_state="STALE", driver_age_s=0.7), name="driver")
    assert stale == MonitorVerdict.stop("driver", "scanner link STALE: no valid frame for 0.700 s")
    failed = _obs(driver_state="FAILED", driver_age_s=None, driver_error="port closed")
    assert _verdict(failed, name="driver") == MonitorVerdict.stop(
        "driver", "scanner link FAILED: no valid frame for unknown time, last error: port closed"
    )
    for state in (DriverState.OK, DriverState.DEGRADED):
        fine = _obs(driver_state=state.value, driver_age_s=None, driver_error="old")
        assert _verdict(fine, name="driver") == MonitorVerdict.ok("driver")
    assert _verdict(_obs(driver_state=None), name="driver") == MonitorVerdict.ok("driver")


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_failing_monitor_stops_under_its_own_name() -> None:
    def broken(obs: Observation, cfg: MonitorSection) -> MonitorVerdict:
        raise KeyError("x")

    (verdict,) = run_monitors(_obs(), M, [("mine", broken)])
    assert verdict == MonitorVerdict.stop("mine", "monitor mine failed (KeyError): 'x'")


# -- deadline and braking ----------------------------------------------------------------------


@pytest.mark.requirement("SR-TIM-2", kind="example", code=MONITORS)
def test_the_deadline_holds_at_its_value_and_stops_one_float_past_it() -> None:
    deadline = M.cycle_deadline_s
    assert _verdict(_obs(cycle_duration_s=deadline), name="deadline").action is Action.PROCEED
    late = _verdict(_obs(cycle_duration_s=_above(deadline)), name="deadline")
    assert late == MonitorVerdict.stop(
        "deadline", "cycle took 100.000 ms, over monitors.cycle_deadline_s = 100 ms"
    )
    for bad in (math.nan, math.inf):
        verdict = _verdict(_obs(cycle_duration_s=bad), name="deadline")
        assert verdict == MonitorVerdict.stop("deadline", f"cycle duration not measured ({bad!r})")


@pytest.mark.requirement("SR-RUN-6", kind="example", code=MONITORS)
def test_braking_exactly_at_the_tolerance_passes_and_weaker_stops() -> None:
    least = 1.5
    at = M.braking_tolerance * least
    assert _verdict(_obs(braking_decel_mps2=at, braking_min_mps2=least), name="braking") == (
        MonitorVerdict.ok("braking")
    )
    weak = _verdict(_obs(braking_decel_mps2=_below(at), braking_min_mps2=least), name="braking")
    assert weak.action is Action.STOP
    assert weak.reason.startswith("the robot decelerated at 1.200 m/s^2 under a STOP, below")
    nan = _verdict(_obs(braking_decel_mps2=math.nan, braking_min_mps2=least), name="braking")
    assert nan.action is Action.STOP
    for decel, minimum in ((None, least), (0.1, None)):
        only_one = _obs(braking_decel_mps2=decel, braking_min_mps2=minimum)
        assert _verdict(only_one, name="braking") == MonitorVerdict.ok("braking")


# -- operating domain: caps, a covered window, gaps ---------------------------------------------


@pytest.mark.requirement("SR-TIM-3", kind="example", code=MONITORS)
def test_a_cap_that_dropped_one_item_stops_and_one_that_dropped_none_does_not() -> None:
    quiet = _obs(over_cap=(("track.max_tracks", 0), ("cluster.max_clusters", 0)))
    assert _verdict(quiet, name="operating_domain") == MonitorVerdict.ok("operating_domain")
    one = _verdict(_obs(over_cap=(("track.max_tracks", 1),)), name="operating_domain")
    assert one == MonitorVerdict.stop(
        "operating_domain", "too many objects for the configured caps: track.max_tracks dropped 1"
    )
    two = _verdict(_obs(over_cap=(("a", 2), ("b", 0), ("c", 5))), name="operating_domain")
    assert two.reason == "too many objects for the configured caps: a dropped 2; c dropped 5"


@pytest.mark.requirement("SR-RUN-2", kind="example", code=MONITORS)
def test_a_covered_window_stops_just_past_the_blocked_fraction() -> None:
    assert M.max_blocked_fraction == 0.5
    half = _obs(n_beams=1000, n_below_min=500)
    assert _verdict(half, name="operating_domain") == MonitorVerdict.ok("operating_domain")
    covered = _verdict(_obs(n_beams=1000, n_below_min=501), name="operating_domain")
    assert covered == MonitorVerdict.stop(
        "operating_domain",
        "501 of 1000 beams below the minimum range (window covered?), more than "
        "monitors.max_blocked_fraction = 0.5",
    )
    few = _obs(n_beams=1080, n_below_min=10)
    assert _verdict(few, name="operating_domain") == MonitorVerdict.ok("operating_domain")
    single = _verdict(_obs(n_beams=1, n_below_min=1), name="operating_domain")
    assert single.action is Action.STOP
    empty = _obs(n_beams=0, n_below_min=0)
    assert _verdict(empty, name="operating_domain") == MonitorVerdict.ok("operating_domain")
    strict = M.model_copy(update={"max_blocked_fraction": 0.1})
    assert _verdict(_obs(n_below_min=100), strict, "operating_domain").action is Action.PROCEED
    assert _verdict(_obs(n_below_min=101), strict, "operating_domain").action is Action.STOP


@pytest.mark.requirement("SR-RUN-2", kind="example", code=MONITORS)
def test_an_incomplete_scan_limits_the_speed_and_a_covered_window_outranks_it() -> None:
    gaps = _verdict(_obs(scan_complete=False), name="operating_domain")
    assert gaps == MonitorVerdict(
        "operating_domain",
        Action.SLOW,
        0.3,
        "incomplete scan (rejected frames left gaps): speed limited to "
        "monitors.degraded_speed_mps = 0.3 m/s",
    )
    both = _verdict(_obs(scan_complete=False, n_below_min=900), name="operating_domain")
    assert both.action is Action.STOP


# -- the verdicts themselves -------------------------------------------------------------------


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_slow_verdict_to_zero_or_less_is_the_stop_verdict() -> None:
    for speed in (0.0, -0.0, -1.0):
        assert MonitorVerdict.slow("m", speed, "why") == MonitorVerdict.stop("m", "why")
    assert MonitorVerdict.slow("m", 5e-324, "why") == MonitorVerdict(
        "m", Action.SLOW, 5e-324, "why"
    )
    with pytest.raises(ValueError, match="STOP must limit the speed to 0"):
        MonitorVerdict("m", Action.STOP, 0.1, "why")
    with pytest.raises(ValueError, match="STOP needs a reason"):
        MonitorVerdict("m", Action.STOP, 0.0)
    for bad in (-0.1, math.nan):
        with pytest.raises(ValueError, match="speed_limit_mps must be >= 0"):
            MonitorVerdict("m", Action.SLOW, bad, "why")
    assert MonitorVerdict("m", Action.SLOW, 0.0, "why").speed_limit_mps == 0.0


# -- the fold ------------------------------------------------------------------------------------


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_monitor_slow_turns_a_proceed_into_slow_at_its_limit() -> None:
    proceed = Command(Action.PROCEED, 1.0, 3.0)
    final = combine(
        proceed, [MonitorVerdict.slow("od", 0.3, "gaps")], stamp_s=3.0, min_moving_mps=0.05
    )
    assert final == Command(Action.SLOW, 0.3, 3.0, ("od: gaps",))
    at_floor = combine(
        proceed, [MonitorVerdict.slow("od", 0.05, "gaps")], stamp_s=3.0, min_moving_mps=0.05
    )
    assert at_floor == Command(Action.SLOW, 0.05, 3.0, ("od: gaps",))
    loose = combine(
        proceed, [MonitorVerdict.slow("od", 2.0, "loose")], stamp_s=3.0, min_moving_mps=0.05
    )
    assert loose == Command(Action.SLOW, 1.0, 3.0, ("od: loose",))
    noted = Command(Action.PROCEED, 1.0, 3.0, ("path clear to 30 m",))
    kept = combine(noted, [MonitorVerdict.ok("clock")], stamp_s=3.0, min_moving_mps=0.05)
    assert kept == noted
    stop_then_ok = combine(
        proceed,
        [MonitorVerdict.stop("clock", "back"), MonitorVerdict.ok("deadline")],
        stamp_s=3.0,
        min_moving_mps=0.05,
    )
    assert stop_then_ok == Command(Action.STOP, 0.0, 3.0, ("clock: back",))


def _corrupted(limit: float) -> MonitorVerdict:
    verdict = MonitorVerdict.slow("od", 0.3, "gaps")
    object.__setattr__(verdict, "speed_limit_mps", limit)
    return verdict


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_non_finite_or_negative_limit_in_the_fold_stops_with_the_reason() -> None:
    proceed = Command(Action.PROCEED, 1.0, 3.0)
    # A NaN limit cannot be built (MonitorVerdict refuses it), and min() would pass it over.
    for limit in (-math.inf, -0.5):
        final = combine(proceed, [_corrupted(limit)], stamp_s=3.0, min_moving_mps=0.05)
        assert final == Command(
            Action.STOP,
            0.0,
            3.0,
            ("od: gaps", f"combine: speed {limit!r} is not a finite speed"),
        )


@pytest.mark.requirement("SR-FUS-2", kind="example", code=MONITORS)
def test_a_fold_that_fails_stops_and_keeps_the_stamp() -> None:
    proceed = Command(Action.PROCEED, 1.0, 3.0)
    broken = combine(proceed, [object()], stamp_s=2.5, min_moving_mps=0.05)  # type: ignore[list-item]
    assert broken.action is Action.STOP
    assert broken.stamp_s == 2.5
    assert broken.reasons[0].startswith("combine failed: ")
    no_command = combine(None, [], stamp_s=4.0, min_moving_mps=0.05)
    assert no_command == Command(Action.STOP, 0.0, 4.0, ("governor: no command (None)",))
    slow_limits = combine(
        None, [MonitorVerdict.slow("od", 0.3, "gaps")], stamp_s=4.0, min_moving_mps=0.05
    )
    assert slow_limits == Command(
        Action.STOP, 0.0, 4.0, ("governor: no command (None)", "od: gaps")
    )


# -- the audit record of an observation ---------------------------------------------------------

_FLOATS = [f.name for f in fields(Observation) if f.name.endswith(("_s", "_mps2"))]


@pytest.mark.requirement("SR-AUD-2", kind="example", code=MONITORS)
def test_an_observation_is_recorded_with_plain_numbers_where_finite() -> None:
    obs = _obs(driver_age_s=0.25, braking_decel_mps2=1.25, braking_min_mps2=1.5)
    data = obs.to_dict()
    assert data["now_s"] == 10.0
    assert data["braking_min_mps2"] == 1.5
    assert data["cycle_duration_s"] == 0.004
    assert Observation.from_dict(data) == obs


@pytest.mark.requirement("SR-AUD-2", kind="example", code=MONITORS)
@pytest.mark.parametrize(
    "name",
    _FLOATS,
)
@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_a_non_finite_time_or_rate_reads_back_as_the_same_float(name: str, value: float) -> None:
    obs = _obs(**{name: value})
    data = obs.to_dict()
    assert data[name] == repr(value)
    back = getattr(Observation.from_dict(data), name)
    assert isinstance(back, float)
    assert repr(back) == repr(value)
