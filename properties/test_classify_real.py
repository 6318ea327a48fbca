"""Campaign: people on the real, labelled leg_tracker bags (SR-CLS-5, SR-CLS-9, SR-CLS-10).

The chain and the per-leg bookkeeping are :mod:`properties.real_legs` (its docstring says what
counts as what). No bag here was used in training (the classifier is trained on the simulator
alone), so every figure is on scans the model never saw. Reported per bag: the share of
labelled legs in a cluster classified person, the safety-relevant errors (a labelled leg whose
track's closing speed is below the person speed) with the person floor (SR-CLS-8) and without
it, whether a leg pair is one cluster or two; on ``negative_2.bag`` the person false positives
per scan and how many scored track rows the floor raises (its reach on scans without people).
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from evidence.record import Recorder
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from properties.real_legs import LEGS, BagLegs, NegativeTopic, negative_topics, positive_bags

CODE = ["pipeline/classify/model.py", "pipeline/features.py"]
FLOOR_CODE = [*CODE, "pipeline/predict.py", "safety/geometry/envelopes.py"]
# SR-CLS-9 and SR-CLS-10 targets (issue 26).
PERSON_SHARE_MIN = 0.90
SAFETY_ERROR_SHARE_MAX = 0.01


@pytest.fixture(scope="module")
def bags(safecase_config: SafecaseConfig) -> list[BagLegs]:
    assert LEGS.is_dir(), f"{LEGS} is part of the repository"
    return positive_bags(safecase_config, Classifier.from_config(safecase_config.classify))


@pytest.fixture(scope="module")
def negatives(safecase_config: SafecaseConfig) -> list[NegativeTopic]:
    return negative_topics(safecase_config, Classifier.from_config(safecase_config.classify))


def _share(n: int, of: int) -> str:
    return f"{n / max(of, 1):.1%}"


@pytest.mark.requirement("SR-CLS-5", kind="campaign", code=CODE)
def test_labelled_legs_and_person_false_positives(
    bags: list[BagLegs], negatives: list[NegativeTopic], evidence: Recorder
) -> None:
    rows = []
    outcome: Counter[str] = Counter()
    called: Counter[str] = Counter()
    for b in bags:
        scored = b.person + b.outcome["scored other class"]
        rows.append(
            [
                b.bag,
                b.scans,
                b.legs,
                _share(b.person, b.legs),
                _share(b.person, scored),
                b.outcome["no kept cluster at the label"],
                b.outcome["cluster, track not yet scored"],
                f"{b.errors_without_floor} ({_share(b.errors_without_floor, b.legs)})",
                f"{b.errors_with_floor} ({_share(b.errors_with_floor, b.legs)})",
            ]
        )
        outcome.update(b.outcome)
        called.update(b.called)
    evidence.table(
        "labelled legs (positive bags): person clusters and safety-relevant errors",
        [
            "bag",
            "scans",
            "labelled legs",
            "person (of all legs)",
            "person (of scored legs)",
            "no kept cluster",
            "not yet scored",
            "closing below the person speed, no floor",
            "with the person floor (SR-CLS-8)",
        ],
        rows,
        caption="a leg counts as person when a kept cluster has a point within cluster.eps_m of "
        "the label and the track it updates is classified person; a safety-relevant error is a "
        "leg whose track's smallest envelope closing speed is below stopping.person_speed_mps",
    )
    evidence.counts("labelled legs", dict(outcome))
    evidence.counts("classes given to scored legs", dict(called))
    evidence.table(
        "labelled leg pairs (scans with two labelled legs, both in kept clusters)",
        ["bag", "one cluster", "two clusters"],
        [[b.bag, b.pair_one_cluster, b.pair_two_clusters] for b in bags],
        caption="768 beams over 270 deg (the bags' laser); eps 0.15 m",
    )
    extent = np.concatenate([np.asarray(b.extent_m) for b in bags])
    evidence.counts(
        "box of the cluster at a labelled leg (longer side) [m]",
        {f"p{q}": round(float(np.percentile(extent, q)), 3) for q in (50, 90, 99)}
        | {"max": round(float(extent.max()), 3), "clusters": int(extent.size)},
    )
    evidence.table(
        "negative_2.bag (nobody in view): person false positives and the floor's reach",
        [
            "topic",
            "scans",
            "scored track rows",
            "called person",
            "person per scan",
            "tracks ever called person",
            "rows raised by the person floor",
        ],
        [
            [
                n.topic,
                n.scans,
                n.scored_rows,
                _share(n.person_rows, n.scored_rows),
                f"{n.person_rows / max(n.scans, 1):.2f}",
                f"{n.person_tracks} of {n.tracks}",
                _share(n.raised_rows, n.scored_rows),
            ]
            for n in negatives
        ],
        caption="laser-frame tracking, no odometry in the bag",
    )
    assert sum(b.legs for b in bags) > 0, "no labelled legs were read"


@pytest.mark.requirement("SR-CLS-9", kind="campaign", code=CODE)
@pytest.mark.xfail(
    reason="the classifier, trained on the simulator's people alone, calls about 55 % of the "
    "labelled legs person (docs/findings/classification.md); strict: reaching 90 % fails this "
    "marker, and SR-CLS-9 can then be claimed",
    strict=True,
)
def test_labelled_legs_are_in_person_clusters(bags: list[BagLegs]) -> None:
    """Over the given bags (pooled, as the target is stated); per bag in the SR-CLS-5 table."""
    person, legs = sum(b.person for b in bags), sum(b.legs for b in bags)
    assert person >= PERSON_SHARE_MIN * legs, (
        f"labelled legs in person clusters: {person} of {legs} ({person / legs:.1%}) < "
        f"{PERSON_SHARE_MIN:.0%}"
    )


@pytest.mark.requirement("SR-CLS-10", kind="campaign", code=FLOOR_CODE)
def test_labelled_people_close_at_least_at_the_person_speed(
    bags: list[BagLegs], evidence: Recorder
) -> None:
    """With the person floor, at most 1 % of the labelled legs of the given bags (pooled, as
    the target is stated; per bag in the SR-CLS-5 table) belong to a track given a closing
    speed below the person speed."""
    legs = sum(b.legs for b in bags)
    errors = sum(b.errors_with_floor for b in bags)
    evidence.counts(
        "safety-relevant person errors (all positive bags)",
        {
            "labelled legs": legs,
            "errors without the floor": sum(b.errors_without_floor for b in bags),
            "errors with the floor": errors,
        }
        | {f"{b.bag}: errors with the floor": b.errors_with_floor for b in bags},
    )
    assert legs > 0, "no labelled legs were read"
    assert errors <= SAFETY_ERROR_SHARE_MAX * legs, (
        f"safety-relevant person errors: {errors} of {legs} ({errors / legs:.2%}) > "
        f"{SAFETY_ERROR_SHARE_MAX:.0%}"
    )
