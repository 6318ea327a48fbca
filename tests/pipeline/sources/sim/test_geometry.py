"""Outlines, object models and motion profiles (examples; the properties are in properties/)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.objects import (
    DOLLY_DRAWBAR_M,
    DOLLY_WHEELBASE_M,
    ObjectKind,
    counterbalance_forklift,
    model_for,
    person,
)
from pipeline.sources.sim.shapes import (
    Outline,
    chamfered_rectangle,
    edge_set_distance,
    ensure_ccw,
    rectangle,
    signed_area,
)
from pipeline.sources.sim.truth import (
    LabelRules,
    ObjectClass,
    forklift_states,
    reversal_intervals,
    stop_times,
)


def test_outline_edges_close_each_part_counter_clockwise() -> None:
    square = rectangle(0, 1, 0, 1)
    tri = np.array([[3.0, 0.0], [2.0, 1.0], [4.0, 1.0]])  # clockwise
    outline = Outline.from_parts([square, tri])
    assert outline.n_parts == 2
    assert list(outline.edge_to[:4]) == [1, 2, 3, 0]
    assert list(outline.edge_to[4:]) == [5, 6, 4]
    assert all(signed_area(p) > 0 for p in outline.parts())
    with pytest.raises(ValueError, match="zero area"):
        ensure_ccw(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))


def test_edge_set_distance_covers_gap_crossing_and_containment() -> None:
    a = Outline.from_parts([rectangle(0, 1, 0, 1)])
    far = Outline.from_parts([rectangle(3, 4, 0, 1)])
    cross = Outline.from_parts([rectangle(0.5, 0.6, -1, 2)])
    inner = Outline.from_parts([rectangle(0.4, 0.6, 0.4, 0.6)])
    assert edge_set_distance(a.vertices_m, a, far.vertices_m, far) == pytest.approx(2.0)
    assert edge_set_distance(a.vertices_m, a, cross.vertices_m, cross) == 0.0
    assert edge_set_distance(a.vertices_m, a, inner.vertices_m, inner) == 0.0
    assert edge_set_distance(inner.vertices_m, inner, a.vertices_m, a) == 0.0


def test_forklift_outline_is_irregular_and_sized_like_a_2_5_t_truck() -> None:
    fl = counterbalance_forklift()
    assert fl.outline.n_parts == 4  # body, mast, two tines
    assert fl.length_m == pytest.approx(3.45)
    assert fl.width_m == pytest.approx(1.15)
    assert abs(sum(fl.outline.extent()[:2])) < 1e-12  # centred on its bounding box
    assert chamfered_rectangle(0, 2, -1, 1, rear_chamfer_m=0.3).shape == (6, 2)


@pytest.mark.parametrize("kind", list(ObjectKind))
def test_every_kind_has_a_model_with_its_box(kind: ObjectKind) -> None:
    model = model_for(kind)
    x0, x1, y0, y1 = model.outline.extent()
    if model.gait is None:
        assert (x1 - x0, y1 - y0) == pytest.approx((model.length_m, model.width_m))
    assert model.kind is kind


def test_a_walking_person_swings_the_legs_and_a_standing_one_does_not() -> None:
    p = person()
    arc = np.array([0.0, p.gait.step_length_m / 2])  # type: ignore[union-attr]
    walking = p.body_vertices(arc, np.array([1.2, 1.2]), np.zeros(2))
    standing = p.body_vertices(arc, np.zeros(2), np.zeros(2))
    assert np.ptp(walking[1, :, 0]) > 0.45  # legs apart fore and aft mid-stride
    assert np.ptp(standing[1, :, 0]) == pytest.approx(2 * p.gait.leg_radius_m)  # type: ignore[union-attr]


def test_reversing_profile_slows_within_frames_then_reverses() -> None:
    m = mo.reversing(0.8, 2.0, 0.4, 0.1, 0.6, 1.0, reverse_s=2.0)
    t = np.array([1.0, 2.2, 2.45, 3.0, 4.0, 7.0])
    assert m.speed_at(t) == pytest.approx([0.8, 0.4, 0.0, -0.5, -0.6, 0.0])
    assert reversal_intervals(m) == pytest.approx(np.array([[2.4, 2.5]]))
    states = forklift_states(m, np.array([1.0, 2.35, 2.45, 3.0, 4.0, 7.0]), LabelRules())
    assert list(states) == [
        ObjectClass.FORKLIFT_MOVING,
        ObjectClass.FORKLIFT_NEAR_REVERSAL,
        ObjectClass.FORKLIFT_NEAR_REVERSAL,
        ObjectClass.FORKLIFT_MOVING,
        ObjectClass.FORKLIFT_MOVING,
        ObjectClass.FORKLIFT_STATIONARY,  # 1.3 s after the last stop (5.7 s)
    ]
    assert stop_times(m) == pytest.approx([2.4, 5.7])


def test_a_plain_stop_is_near_reversal_for_the_window_then_stationary() -> None:
    # Labels are causal: at a stop nobody can tell yet whether a reversal follows.
    m = mo.stop_and_go(1.0, 1.0, 2.0, 1.0, 2.0, 1)  # at rest on [1.5, 3.5], then off again
    assert reversal_intervals(m).shape == (0, 2)
    assert stop_times(m) == pytest.approx([1.5])
    states = forklift_states(m, np.array([1.4, 2.0, 2.5, 3.0, 4.5]), LabelRules())
    assert list(states) == [
        ObjectClass.FORKLIFT_NEAR_REVERSAL,  # braking at 0.2 m/s, 0.1 s before the stop
        ObjectClass.FORKLIFT_NEAR_REVERSAL,
        ObjectClass.FORKLIFT_NEAR_REVERSAL,  # the window's last instant
        ObjectClass.FORKLIFT_STATIONARY,
        ObjectClass.FORKLIFT_MOVING,
    ]
    parked = mo.stationary()
    assert stop_times(parked).shape == (0,)
    assert (
        forklift_states(parked, np.array([0.0, 5.0]), LabelRules()).tolist()
        == [ObjectClass.FORKLIFT_STATIONARY] * 2
    )


def test_integrated_straight_and_turning_paths() -> None:
    line = mo.integrate(mo.constant(1.5), 1.0, 2.0, math.pi / 2, 4.0)
    end = line.at(np.array([4.0]))
    assert (end["x_m"][0], end["y_m"][0]) == pytest.approx((1.0, 8.0))
    turn = mo.integrate(mo.turning(1.0, 1.0, math.pi / 2, 0.5), 0.0, 0.0, 0.0, 10.0, dt_s=1e-3)
    st = turn.at(np.array([10.0]))
    # 1 m straight, a quarter circle of radius 2 m (pi s), then straight north.
    assert st["heading_rad"][0] == pytest.approx(math.pi / 2, abs=1e-9)
    assert st["x_m"][0] == pytest.approx(3.0, abs=1e-4)
    assert st["y_m"][0] == pytest.approx(2.0 + (10.0 - 1.0 - math.pi), abs=1e-4)


def test_tow_train_keeps_its_drawbars_and_wheelbases() -> None:
    tug = mo.integrate(mo.turning(2.5, 2.0, math.pi / 2, 0.4), 0.0, 0.0, 0.0, 12.0)
    dollies = mo.tow_train(tug, 2)
    assert len(dollies) == 2
    for d in dollies:
        assert np.all(np.abs(d.articulation_rad) < math.pi / 2)
        assert np.all(np.diff(d.arc_m) >= 0)
    # The train cuts the corner: the last dolly's path stays inside the tug's.
    last = dollies[-1].at(np.array([7.0]))
    assert last["y_m"][0] > 0.0
    assert DOLLY_DRAWBAR_M > 0
    assert DOLLY_WHEELBASE_M > 0


def test_bad_profiles_are_rejected() -> None:
    with pytest.raises(ValueError, match="increase strictly"):
        mo.Motion(np.array([0.0, 0.0]), np.array([1.0, 2.0]), np.zeros(1), np.zeros(1), "x")
    with pytest.raises(ValueError, match="reversing"):
        mo.reversing(-0.8, 1.0, 0.3, 0.0, 0.6, 1.0)


def test_a_rounding_sized_negative_speed_is_not_a_reversal() -> None:
    # Certify found it: a knot speed of -2e-283 m/s counted as a change of direction.
    tiny = mo.Motion(
        knot_t_s=np.array([0.0, 1.0]),
        knot_v_mps=np.array([1.0, -2.0763659e-283]),
        yaw_t_s=np.array([0.0]),
        yaw_rate_rps=np.array([0.0]),
        profile="accelerate",
    )
    assert reversal_intervals(tiny).shape == (0, 2)
    real = mo.Motion(
        knot_t_s=np.array([0.0, 1.0]),
        knot_v_mps=np.array([1.0, -0.01]),
        yaw_t_s=np.array([0.0]),
        yaw_rate_rps=np.array([0.0]),
        profile="accelerate",
    )
    assert reversal_intervals(real).shape == (1, 2)
