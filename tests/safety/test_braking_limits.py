"""The braking watch at its exact limits (SR-RUN-6; assumption A-1).

Each condition of :meth:`safety.model.braking.BrakingWatch.observe` is checked at its threshold
and one step past it, with stamps and positions that are exact binary fractions so the
threshold is hit exactly; motion along y and with unequal intervals shows every term of the
measured deceleration. The mutation campaign (SR-EVD-5, docs/findings/mutation.md) asks for
these: a comparison that moves by one step must fail a test.
"""

from __future__ import annotations

import math

import pytest

from safety.model.braking import BrakingWatch

BRAKING = ["safety/model/braking.py"]


def _measure(
    watch: BrakingWatch,
    samples: list[tuple[float, float, float]],
    stop_since_s: float | None = -10.0,
) -> list[float | None]:
    return [watch.observe(t, (x, y, 0.0), stop_since_s) for t, x, y in samples]


@pytest.mark.requirement("SR-RUN-6", kind="example", code=BRAKING)
def test_the_deceleration_over_unequal_intervals_along_either_axis() -> None:
    # 1.0 m/s over 0.5 s, then 0.5 m/s over 0.25 s: a drop of 0.5 m/s over 0.375 s.
    expected = 0.5 / 0.375
    along_x = _measure(
        BrakingWatch(0.125, 2.0), [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.75, 0.625, 0.0)]
    )
    along_y = _measure(
        BrakingWatch(0.125, 2.0), [(0.0, 0.0, 0.0), (0.5, 0.0, 0.5), (0.75, 0.0, 0.625)]
    )
    assert along_x == [None, None, expected]
    assert along_y == [None, None, expected]
    diagonal = _measure(
        BrakingWatch(0.125, 2.0), [(0.0, 0.0, 0.0), (0.5, 0.3, 0.4), (0.75, 0.375, 0.5)]
    )
    assert diagonal[:2] == [None, None]
    assert diagonal[2] == pytest.approx(expected, rel=1e-12)


@pytest.mark.requirement("SR-RUN-6", kind="example", code=BRAKING)
def test_measured_from_the_first_span_that_starts_once_the_stop_reached_the_actuator() -> None:
    samples = [(1.0, 0.0, 0.0), (1.5, 0.5, 0.0), (2.0, 0.875, 0.0)]
    # The STOP reached the actuator at 0.75 + 0.25 = 1.0 s, exactly when the span starts.
    assert _measure(BrakingWatch(0.25, 2.0), samples, stop_since_s=0.75)[2] == 0.5
    later = 0.75 + 2.0**-40  # the span then starts just before the STOP reached the actuator
    assert _measure(BrakingWatch(0.25, 2.0), samples, stop_since_s=later)[2] is None
    assert _measure(BrakingWatch(0.25, 2.0), samples, stop_since_s=None) == [None] * 3


@pytest.mark.requirement("SR-RUN-6", kind="example", code=BRAKING)
def test_intervals_of_one_millisecond_are_measured_and_shorter_ones_not() -> None:
    # 0.0 -> 0.001 -> 0.002 s: both intervals exactly 1 ms (a power-of-two multiple).
    exact = _measure(
        BrakingWatch(0.125, 2.0), [(0.0, 0.0, 0.0), (0.001, 0.001, 0.0), (0.002, 0.0019, 0.0)]
    )
    assert exact[2] == pytest.approx(100.0)
    shorter = 0.001 - 1e-6
    for samples in (
        [(0.0, 0.0, 0.0), (shorter, 0.001, 0.0), (shorter + 0.001, 0.0019, 0.0)],
        [(0.0, 0.0, 0.0), (0.001, 0.001, 0.0), (0.001 + shorter, 0.0019, 0.0)],
    ):
        assert _measure(BrakingWatch(0.125, 2.0), samples)[2] is None


@pytest.mark.requirement("SR-RUN-6", kind="example", code=BRAKING)
def test_a_robot_that_may_have_come_to_rest_is_not_measured() -> None:
    # decel_max 2 m/s^2 over a 0.5 s interval: at 0.5 m/s or less it may have stopped inside.
    at_limit = [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (1.0, 0.75, 0.0)]
    assert _measure(BrakingWatch(0.125, 2.0), at_limit)[2] is None
    beyond = [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (1.0, 0.75 + 2.0**-20, 0.0)]
    assert _measure(BrakingWatch(0.125, 2.0), beyond)[2] == pytest.approx(1.0, abs=1e-5)


@pytest.mark.requirement("SR-RUN-6", kind="example", code=BRAKING)
def test_bad_stamps_and_poses_and_a_reset_start_the_measurement_afresh() -> None:
    watch = BrakingWatch(0.125, 2.0)
    assert watch.observe(None, (0.0, 0.0, 0.0), -10.0) is None
    for pose in ((math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, math.nan)):
        assert watch.observe(0.0, pose, -10.0) is None
    assert watch.observe(math.inf, (0.0, 0.0, 0.0), -10.0) is None
    good = [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.75, 0.625, 0.0)]
    assert _measure(watch, good)[2] is not None  # the bad ones were not kept
    # A bad pose between two good samples is skipped, not kept in the window.
    watch = BrakingWatch(0.125, 2.0)
    _measure(watch, good[:2])
    assert watch.observe(0.75, (math.nan, 0.625, 0.0), -10.0) is None
    assert _measure(watch, good[2:]) == [0.5 / 0.375]
    watch.reset()
    assert _measure(watch, [(1.0, 0.625, 0.0), (1.5, 0.75, 0.0)]) == [None, None]
    # A stamp that does not advance forgets what came before it.
    watch = BrakingWatch(0.125, 2.0)
    _measure(watch, good[:2])
    assert _measure(watch, [(0.5, 0.5, 0.0), (0.75, 0.625, 0.0)]) == [None, None]


@pytest.mark.requirement("SR-RUN-6", kind="example", code=BRAKING)
def test_the_measurement_does_not_depend_on_where_the_robot_is() -> None:
    # The same motion as above, 100 m along x and -50 m along y from the origin.
    x0, y0 = 100.0, -50.0
    moved = [(0.0, x0, y0), (0.5, x0, y0 + 0.5), (0.75, x0, y0 + 0.625)]
    assert _measure(BrakingWatch(0.125, 2.0), moved) == [None, None, 0.5 / 0.375]
    backwards = [(0.0, x0, y0), (0.5, x0 - 0.5, y0), (0.75, x0 - 0.625, y0)]
    assert _measure(BrakingWatch(0.125, 2.0), backwards) == [None, None, 0.5 / 0.375]
