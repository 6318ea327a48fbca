"""Direction-aware closing speed (SR-AVL-5): proved with z3, checked against true motions.

The formula (:func:`safety.model.stopping.directed_closing_mps`) is proved in three lemmas
(properties/availability_obligations.py) and never above the undirected closing speed; a
weakened copy is refuted. The runtime's use of it (:mod:`safety.closing`) is checked against
objects whose true motion satisfies the prediction model (the prediction campaign's cases,
integrated by the simulator): no step of a true path closes in along the path faster than the
speed the governor is given.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig
from pipeline.constructive import sector_points
from pipeline.predict import predict
from pipeline.types import PredictionMode
from properties.availability_obligations import (
    closing_bound_obligation,
    closing_combination_obligation,
    closing_never_above_obligation,
    closing_obligations,
)
from properties.prediction_cases import classification, features_for, make_case
from properties.smt import ProofVerdict, prove
from safety.closing import cone_half_angles_rad, directed_closing
from safety.geometry.envelopes import EnvelopeBuilder
from safety.geometry.path import PathAhead
from safety.model.readings import Real, maximum, select
from safety.model.stopping import StoppingParams, directed_closing_mps

CODE = ["safety/model/stopping.py", "safety/closing.py"]
angle = st.floats(-math.pi, math.pi, allow_nan=False)


@pytest.mark.requirement("SR-AVL-5", kind="proof", code=CODE)
def test_directed_closing_speed_is_proved(evidence: Recorder) -> None:
    results = [prove(o) for o in (*closing_obligations(), closing_never_above_obligation())]
    for result in results:
        result.attach(required=True)
    assert all(r.proved for r in results), [(r.name, r.verdict, r.reason) for r in results]
    evidence.note(
        "directed closing speed: the three lemmas and the never-above bound PROVED in "
        f"{sum(r.time_s for r in results):.2f} s"
    )


def _forgets_the_sine(
    speed: Real, c: Real, x: Real, cos_half: Real, sin_half: Real, static: Real
) -> Real:
    """A plausible slip: the cone's nearer edge taken as cos(theta) cos(gamma) alone."""
    edge = c * cos_half
    along = select(c >= cos_half, 1 + 0 * edge, edge)
    return maximum(static, speed * maximum(along, 0 * along))


@pytest.mark.requirement("SR-AVL-5", kind="example", code=CODE)
def test_a_weakened_closing_formula_is_refuted() -> None:
    whole = prove(closing_bound_obligation(_forgets_the_sine))
    lemma = prove(closing_combination_obligation(_forgets_the_sine))
    assert whole.verdict is ProofVerdict.REFUTED, whole
    assert lemma.verdict is ProofVerdict.REFUTED, lemma
    current().note(f"weakened copy refuted: {whole.describe_model()}")


@pytest.mark.requirement("SR-AVL-5", kind="property", code=CODE)
@settings(max_examples=examples(200), deadline=None)
@given(
    heading=angle,
    towards=angle,
    half=st.floats(0.0, math.pi),
    speed=st.floats(0.0, 5.0),
    static=st.floats(0.0, 0.5),
)
def test_the_float_reading_is_the_largest_sampled_component(
    heading: float, towards: float, half: float, speed: float, static: float
) -> None:
    """Sampled velocities in the cone never exceed the formula, which they reach to 1e-4."""
    turns = np.linspace(-half, half, 2001)
    components = speed * np.cos(heading + turns - towards)
    largest = max(static, float(np.max(np.maximum(components, 0.0))))
    offset = towards - heading
    value = float(
        directed_closing_mps(
            speed, math.cos(offset), abs(math.sin(offset)), math.cos(half), math.sin(half), static
        )
    )
    assert largest <= value + 1e-9
    assert value - largest <= 1e-4 * max(speed, 1.0)


@pytest.mark.requirement("SR-AVL-5", kind="property", code=["safety/closing.py"])
@settings(max_examples=examples(200), deadline=None)
@given(heading=angle, half=st.floats(0.0, math.pi), radius=st.floats(0.01, 8.0))
def test_the_cone_read_off_a_sector_holds_the_drawn_one(
    heading: float, half: float, radius: float
) -> None:
    """The half-angle read off the predictor's own polygon is at least the one drawn, and the
    whole circle from 90 degrees on (where the predictor draws a disc)."""
    reach = sector_points(
        np.array([1.0]),
        np.array([-2.0]),
        np.array([heading]),
        np.array([half]),
        np.array([radius]),
        math.radians(5.0),
        16,
    )
    read = float(cone_half_angles_rad(reach, np.array([[1.0, -2.0]]), np.array([heading]))[0])
    if half >= 0.5 * math.pi:
        assert read == math.pi
    else:
        assert half <= read <= half + 1e-6


@pytest.mark.requirement("SR-AVL-5", kind="property", code=CODE)
@settings(max_examples=examples(150), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), path_heading=angle)
def test_no_true_motion_closes_in_faster_than_the_governor_is_told(
    safecase_config: SafecaseConfig, seed: int, path_heading: float
) -> None:
    """Cone cases whose true motion satisfies the prediction model: every step of the true path
    closes in along the path (minus its direction) at most at the directed closing speed."""
    config = safecase_config
    case = make_case(np.random.default_rng(seed), "cone", config)
    tracks = case.tracks
    klass = classification(tracks, case.class_name, case.confidence)
    pred = predict(
        tracks,
        features_for(tracks, False),
        klass,
        config.predict,
        config.classify.medium_confidence_min,
    )
    params = StoppingParams.from_config(config)
    env = EnvelopeBuilder(config.predict, params).build(pred, klass.class_names)
    rc = config.runtime
    path = PathAhead.straight((0.0, 0.0, path_heading), rc.path_lookahead_m, rc.path_step_m)
    free = np.full(pred.track_id.shape[0], rc.path_lookahead_m)
    closing = directed_closing(env, pred, tracks, klass.class_names, path, free, params)
    assert np.all(closing <= env.closing_speed_mps + 1e-12)
    cone_rows = pred.mode == int(PredictionMode.CONE)
    assert cone_rows.any()
    dt = np.diff(case.true_t_s)
    steps = np.stack([np.diff(case.true_x_m), np.diff(case.true_y_m)], axis=1)
    moving = dt > 1e-9
    velocity = steps[moving] / dt[moving, None]
    towards = np.array([-math.cos(path_heading), -math.sin(path_heading)])
    fastest = float(np.max(velocity @ towards, initial=0.0))
    assert fastest <= float(closing[cone_rows][0]) + 1e-6, (fastest, closing, env.closing_speed_mps)
    current().count(
        "cases",
        "directed below undirected"
        if closing[cone_rows][0] < env.closing_speed_mps[cone_rows][0] - 1e-9
        else "unchanged",
    )
