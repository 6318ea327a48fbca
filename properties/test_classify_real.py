"""Campaign: the classifier on the real, labelled leg_tracker bags (SR-CLS-5; no target yet).

``positive_N_extracted.bag`` (leg_tracker, Leigh et al. ICRA 2015, BSD-3-Clause) holds scans on
``/training_scan`` and, recorded just before each scan, the hand-labelled leg positions of
that scan on ``/leg_cluster_positions`` (a PoseArray in the laser's frame; the header stamps
are zero, so labels pair with scans in recording order). ``negative_2.bag`` holds three
lasers' scans with nobody in view. Each scan stream goes through clustering, tracking (in the
laser's own frame: the bags carry no odometry), features and the configured classifier.

Reported: per labelled leg, whether our clustering kept a cluster there (a point within
``cluster.eps_m`` of the label), whether a scored track follows it, and its class; and on the
negative bag the share of scored track rows (and of tracks) called person.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from evidence.record import Recorder
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.perception import Perception
from pipeline.sources.logs.bags import laserscan_topics
from pipeline.sources.logs.source import LogSource
from pipeline.types import FloatArray, Frame
from safety.model.freshness import is_fresh

# The labelled bags are BSD-3 and copied into the repository (source in the folder's SOURCE.md),
# so this campaign runs on a fresh clone too.
LEGS = Path(__file__).resolve().parents[1] / "tests" / "data" / "leg_tracker"
CODE = ["pipeline/classify/model.py", "pipeline/features.py"]


def _leg_labels(bag: Path) -> list[FloatArray]:
    """The labelled leg positions (k, 2) of each scan, in recording order."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    out: list[FloatArray] = []
    with Reader(bag) as reader:
        chosen = [c for c in reader.connections if c.topic == "/leg_cluster_positions"]
        for connection, _, raw in reader.messages(connections=chosen):
            msg: Any = store.deserialize_ros1(raw, connection.msgtype)
            out.append(
                np.array(
                    [[p.position.x, p.position.y] for p in msg.poses], dtype=np.float64
                ).reshape(-1, 2)
            )
    return out


def _chain(config: SafecaseConfig, classifier: Classifier) -> Perception:
    """The perception chain for one scan stream (laser frame: the bags carry no odometry)."""
    return Perception.from_config(config, classifier=classifier, guard=is_fresh)


def _frames(bag: Path, topic: str) -> Iterator[Frame]:
    """The bag's frames through the stamp rule every log source follows."""
    return LogSource(bag, scan_topic=topic).frames()


@pytest.mark.requirement("SR-CLS-5", kind="campaign", code=CODE)
def test_labelled_legs_and_person_false_positives(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    assert LEGS.is_dir(), f"{LEGS} is part of the repository"
    config = safecase_config
    classifier = Classifier.from_config(config.classify)
    person = classifier.class_index("person")
    eps = config.cluster.eps_m
    outcome: Counter[str] = Counter()
    called: Counter[str] = Counter()
    rows = []
    for bag in sorted(LEGS.glob("positive_*_extracted.bag")):
        labels = _leg_labels(bag)
        chain = _chain(config, classifier)
        per_bag: Counter[str] = Counter()
        for frame, legs in zip(_frames(bag, "/training_scan"), labels, strict=False):
            seen = chain.perceive(frame)
            points, clusters, tracks = seen.points, seen.clusters, seen.tracked.tracks
            result = seen.classification
            xy = np.stack([points.x_m, points.y_m], axis=1)
            for leg in legs:
                near = np.hypot(*(xy - leg).T) <= eps
                kept = clusters.point_labels[near]
                kept = kept[kept >= 0]
                if not kept.size:
                    per_bag["no kept cluster at the label"] += 1
                    continue
                cluster = int(np.bincount(kept).argmax())
                follow = np.flatnonzero(tracks.detection_index == cluster)
                if not follow.size or result.class_index[follow[0]] < 0:
                    per_bag["cluster, track not yet scored"] += 1
                    continue
                k = int(result.class_index[follow[0]])
                per_bag["scored person" if k == person else "scored other class"] += 1
                called[classifier.class_names[k]] += 1
        n_legs = sum(per_bag.values())
        scored = per_bag["scored person"] + per_bag["scored other class"]
        rows.append(
            [
                bag.name,
                len(labels),
                n_legs,
                f"{per_bag['scored person'] / max(n_legs, 1):.1%}",
                f"{per_bag['scored person'] / max(scored, 1):.1%}",
                per_bag["no kept cluster at the label"],
                per_bag["cluster, track not yet scored"],
            ]
        )
        outcome.update(per_bag)
    evidence.table(
        "labelled legs (positive bags): share in a cluster classified person",
        [
            "bag",
            "scans",
            "labelled legs",
            "person (of all legs)",
            "person (of scored legs)",
            "no kept cluster",
            "not yet scored",
        ],
        rows,
        caption="a leg counts when a kept cluster has a point within cluster.eps_m of the "
        "label and the track it updates is classified person",
    )
    evidence.counts("labelled legs", dict(outcome))
    evidence.counts("classes given to scored legs", dict(called))

    negative = LEGS / "negative_2.bag"
    fp_rows = []
    totals: Counter[str] = Counter()
    for topic in laserscan_topics(negative):
        chain = _chain(config, classifier)
        n_rows = n_person = 0
        ids: set[int] = set()
        person_ids: set[int] = set()
        for frame in _frames(negative, topic):
            seen = chain.perceive(frame)
            tracks, result = seen.tracked.tracks, seen.classification
            is_scored = result.class_index >= 0
            n_rows += int(is_scored.sum())
            hit = is_scored & (result.class_index == person)
            n_person += int(hit.sum())
            ids.update(tracks.track_id[is_scored].tolist())
            person_ids.update(tracks.track_id[hit].tolist())
        fp_rows.append(
            [
                topic,
                n_rows,
                f"{n_person / max(n_rows, 1):.2%}",
                len(ids),
                f"{len(person_ids) / max(len(ids), 1):.1%}",
            ]
        )
        totals.update({"scored rows": n_rows, "person rows": n_person})
    evidence.table(
        "negative_2.bag (nobody in view): person false positives",
        ["topic", "scored track rows", "called person", "tracks", "tracks ever called person"],
        fp_rows,
        caption="laser-frame tracking, no odometry in the bag",
    )
    evidence.counts("negative_2.bag", dict(totals))
    assert sum(outcome.values()) > 0, "no labelled legs were read"
