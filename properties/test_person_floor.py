"""The person floor: a track that may be a person closes in at least at the person speed (SR-CLS-8).

Whatever the classifier says, a track whose cluster's box is not larger than a person can be
(:func:`pipeline.predict.person_compatible`) is given at least ``stopping.person_speed_mps``
(1.6 m/s, ISO 13855) as its closing speed: :func:`safety.model.stopping.person_floor_mps`,
applied last in :meth:`safety.geometry.envelopes.EnvelopeBuilder.closing_speeds`, and such rows
are never made direction-aware (:func:`safety.closing.directed_rows`). Proved with z3 on the
formula (a weakened copy is refuted), checked on the runtime path from random tracks of every
prediction mode, class and box; the real-data figures are in properties/test_classify_real.py.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import z3
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import Recorder, current
from pipeline.classify.model import MODEL_CLASSES
from pipeline.config import SafecaseConfig
from pipeline.features import feature_index
from pipeline.predict import person_compatible, predict
from properties.prediction_cases import classification, features_for, make_case
from properties.smt import Obligation, ProofVerdict, prove
from safety.closing import directed_rows
from safety.geometry.envelopes import EnvelopeBuilder
from safety.model.readings import Real, select
from safety.model.stopping import person_floor_mps

CODE = [
    "safety/model/stopping.py",
    "safety/geometry/envelopes.py",
    "safety/closing.py",
    "pipeline/predict.py",
]


def floor_obligation(fn: object = person_floor_mps) -> Obligation:
    """SR-CLS-8: for every class closing speed ``c`` and person speed ``k >= 0``: a
    person-compatible obstacle is given at least ``k``; any other keeps ``c`` exactly."""
    c, k = z3.Reals("class_closing_mps person_mps")
    compatible = z3.Bool("person_compatible")
    used = fn(c, compatible, k)  # type: ignore[operator]
    return Obligation(
        name="SR-CLS-8 person floor",
        statement=(
            "for every class closing speed c and person speed k >= 0: person_compatible => "
            "closing >= k; not person_compatible => closing = c"
        ),
        hypotheses=(k >= 0,),
        goal=z3.And(z3.Implies(compatible, used >= k), z3.Implies(z3.Not(compatible), used == c)),
        variables=(c, k),
    )


def _floor_on_moving_only(closing: Real, compatible: object, person: Real) -> Real:
    """A plausible slip: the floor written as 'a moving object gets at least the person speed'
    (only where the class speed is already above zero), so a still class keeps 0."""
    return select(compatible, select(closing > 0, closing + 0 * person, closing), closing)


@pytest.mark.requirement("SR-CLS-8", kind="proof", code=CODE)
def test_the_person_floor_is_proved(evidence: Recorder) -> None:
    result = prove(floor_obligation())
    result.attach(required=True)
    assert result.proved, (result.verdict, result.reason)
    weakened = prove(floor_obligation(_floor_on_moving_only))
    assert weakened.verdict is ProofVerdict.REFUTED, weakened
    evidence.note(
        f"person floor PROVED in {result.time_s:.3f} s; a copy that floors moving classes only "
        f"is REFUTED: {weakened.describe_model()}"
    )


_BOX = st.one_of(st.floats(0.0, 3.0), st.just(math.nan), st.sampled_from([1.0, 1.0 + 1e-9]))


@pytest.mark.requirement("SR-CLS-8", kind="property", code=CODE)
@settings(max_examples=examples(150), deadline=None)
@given(
    mode=st.sampled_from(["cone", "footprint", "near_reversal", "unknown"]),
    class_name=st.one_of(st.none(), st.sampled_from(MODEL_CLASSES)),
    confidence=st.floats(0.0, 1.0),
    width=_BOX,
    length=_BOX,
    seed=st.integers(0, 2**32 - 1),
)
def test_every_person_sized_track_closes_at_least_at_the_person_speed(
    safecase_config: SafecaseConfig,
    mode: str,
    class_name: str | None,
    confidence: float,
    width: float,
    length: float,
    seed: int,
) -> None:
    """Through predict() and the envelope builder: the runtime's closing speeds."""
    config = safecase_config
    case = make_case(np.random.default_rng(seed), mode, config)
    tracks = case.tracks
    features = features_for(tracks, near_reversal=mode == "near_reversal")
    values = features.values.copy()
    values[:, feature_index("bbox_width_m")] = width
    values[:, feature_index("bbox_length_m")] = length
    features = dataclasses.replace(features, values=values)
    klass = classification(tracks, class_name, confidence)
    pred = predict(tracks, features, klass, config.predict, config.classify.medium_confidence_min)
    bound = config.predict.person_max_extent_m
    expected = not (width > bound or length > bound)
    assert person_compatible(features, config.predict).tolist() == [expected]
    assert pred.person_compatible.tolist() == [expected] * pred.n
    builder = EnvelopeBuilder.from_config(config)
    closing = builder.closing_speeds(pred, MODEL_CLASSES)
    plain = builder.closing_speeds(
        dataclasses.replace(pred, person_compatible=np.zeros(pred.n, dtype=bool)), MODEL_CLASSES
    )
    walk = float(builder.params.person_speed_mps)
    if expected:
        assert (closing >= walk).all(), (closing, walk)
        assert not directed_rows(pred, MODEL_CLASSES).any()
        raised = int((closing > plain).sum())
    else:
        assert np.array_equal(closing, plain)
        raised = 0
    rec = current()
    rec.count("tracks", "person-compatible" if expected else "larger than a person", 1)
    rec.count("envelopes", "raised to the person speed", raised)
