"""Would real labelled scans in training help? Leave-one-bag-out, never scored on a training bag.

An experiment for SR-CLS-9, not a packaged model (nothing is written). Rows of the real bags come
from the runtime's chain (:mod:`properties.real_legs`): on a positive bag, every scored track
whose cluster holds a labelled leg is a ``person`` row (other clusters there are unlabelled and
left out); on ``negative_2.bag`` every scored track is a ``static`` row (nobody in view). The
simulated rows are the stored held-out rows (``tests/data/classify/heldout.npz``, 104,358 rows):
the committed model's training rows are not kept on disk, and a full simulation of them takes
about an hour (docs/findings/classification.md). Fold ``k`` trains on the simulated rows, the
positive bags but the ``k``-th and the negative bag's lasers but the ``k``-th, with the
committed model's options (depth 6, 150 rounds, eta 0.3, 64 bins, classes weighted inversely to
their counts), and scores the left-out positive bag and laser only.

    .venv/bin/python -m properties.real_legs_cv
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.classify.model import MODEL_CLASSES, PERSON_CLASS, Classifier
from pipeline.config import SafecaseConfig, default_config
from pipeline.sources.logs.bags import laserscan_topics
from pipeline.training.data import load_rows
from pipeline.types import FloatArray
from properties.real_legs import LEGS, bag_frames, leg_labels, perception_chain

__all__ = ["main", "negative_rows", "positive_rows"]

HELDOUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "classify" / "heldout.npz"


def positive_rows(
    config: SafecaseConfig, classifier: Classifier, bag: str
) -> tuple[FloatArray, np.ndarray]:
    """Feature rows of every scored track of ``bag`` and whether its cluster holds a leg."""
    path = LEGS / bag
    chain = perception_chain(config, classifier)
    rows: list[FloatArray] = []
    leg: list[np.ndarray] = []
    eps = config.cluster.eps_m
    for frame, legs in zip(bag_frames(path, "/training_scan"), leg_labels(path), strict=False):
        seen = chain.perceive(frame)
        points, clusters, tracks = seen.points, seen.clusters, seen.tracked.tracks
        xy = np.stack([points.x_m, points.y_m], axis=1)
        held = set()
        for position in legs:
            kept = clusters.point_labels[np.hypot(*(xy - position).T) <= eps]
            kept = kept[kept >= 0]
            if kept.size:
                held.add(int(np.bincount(kept).argmax()))
        scored = seen.classification.class_index >= 0
        rows.append(seen.features.values[scored])
        leg.append(np.isin(tracks.detection_index[scored], sorted(held)))
    return np.concatenate(rows), np.concatenate(leg)


def negative_rows(
    config: SafecaseConfig, classifier: Classifier, topic: str
) -> tuple[FloatArray, int]:
    """Feature rows of every scored track of one laser of ``negative_2.bag``, and its scans."""
    chain = perception_chain(config, classifier)
    rows: list[FloatArray] = []
    scans = 0
    for frame in bag_frames(LEGS / "negative_2.bag", topic):
        seen = chain.perceive(frame)
        rows.append(seen.features.values[seen.classification.class_index >= 0])
        scans += 1
    return np.concatenate(rows), scans


def main() -> None:
    """Print one line per fold (module docstring)."""
    import xgboost as xgb

    config = default_config()
    classifier = Classifier.from_config(config.classify)
    person = MODEL_CLASSES.index(PERSON_CLASS)
    static = MODEL_CLASSES.index("static")
    bags = sorted(p.name for p in LEGS.glob("positive_*_extracted.bag"))
    topics = laserscan_topics(LEGS / "negative_2.bag")
    positive = {bag: positive_rows(config, classifier, bag) for bag in bags}
    negative = {topic: negative_rows(config, classifier, topic) for topic in topics}
    sim = load_rows(HELDOUT)
    params = {
        "objective": "multi:softprob",
        "num_class": len(MODEL_CLASSES),
        "max_depth": 6,
        "eta": 0.3,
        "max_bin": 64,
        "seed": 0,
        "nthread": 1,
        "tree_method": "hist",
    }
    for k, (bag, topic) in enumerate(zip(bags, topics, strict=False)):
        x, y = [sim.features], [sim.model_label]
        for other in bags:
            if other != bag:
                rows, leg = positive[other]
                x.append(rows[leg])
                y.append(np.full(int(leg.sum()), person))
        for other in topics:
            if other != topic:
                x.append(negative[other][0])
                y.append(np.full(negative[other][0].shape[0], static))
        features, label = np.concatenate(x), np.concatenate(y)
        counts = np.bincount(label, minlength=len(MODEL_CLASSES))
        weight = (label.shape[0] / (len(MODEL_CLASSES) * np.maximum(counts, 1)))[label]
        booster = xgb.train(params, xgb.DMatrix(features, label, weight=weight), 150)
        rows, leg = positive[bag]
        ours = booster.predict(xgb.DMatrix(rows[leg])).argmax(axis=1)
        committed = classifier.probabilities(rows[leg]).argmax(axis=1)
        empty, scans = negative[topic]
        fp = booster.predict(xgb.DMatrix(empty)).argmax(axis=1)
        fp_committed = classifier.probabilities(empty).argmax(axis=1)
        print(
            f"fold {k}: scored on {bag} and negative_2.bag {topic}: scored leg rows "
            f"{int(leg.sum())}, called person {np.mean(ours == person):.1%} (committed model "
            f"{np.mean(committed == person):.1%}); person per scan with nobody in view "
            f"{np.sum(fp == person) / scans:.2f} "
            f"(committed {np.sum(fp_committed == person) / scans:.2f})",
            flush=True,
        )


if __name__ == "__main__":
    main()
