"""The chain on the labelled leg_tracker bags, per bag: people found, people's closing speeds.

Shared by ``properties/test_classify_real.py`` (SR-CLS-5, SR-CLS-9, SR-CLS-10) and
``python -m properties.real_legs`` (the table of docs/findings/classification.md).

``positive_N_extracted.bag`` (leg_tracker, Leigh et al. ICRA 2015, BSD-3-Clause) holds scans on
``/training_scan`` and, recorded just before each scan, the hand-labelled leg positions of that
scan on ``/leg_cluster_positions`` (a PoseArray in the laser's frame; the header stamps are zero,
so labels pair with scans in recording order). ``negative_2.bag`` holds three lasers' scans with
nobody in view. Each scan stream goes through the runtime's perception chain (clustering,
tracking in the laser's own frame: the bags carry no odometry, features, the configured
classifier, prediction) and the envelope builder's closing speeds.

Per labelled leg: whether a kept cluster holds a point within ``cluster.eps_m`` of the label,
whether a scored track follows it, its class, and the smallest closing speed of that track's
envelopes, with the person floor (SR-CLS-8) and without it (``person_compatible`` cleared).
A leg that no kept cluster holds is a loose point (the worst closing speed, ``runtime.
loose_points = "worst"``); a track not yet scored is predicted as unknown (the worst closing
speed): neither is a safety-relevant error. A **safety-relevant error** is a labelled leg whose
track's smallest closing speed is below ``stopping.person_speed_mps``.
"""

from __future__ import annotations

import dataclasses
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.classify.model import PERSON_CLASS, Classifier
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.perception import Perception
from pipeline.sources.logs.bags import laserscan_topics
from pipeline.sources.logs.source import LogSource
from pipeline.types import FloatArray, Frame, Predictions
from safety.geometry.envelopes import EnvelopeBuilder
from safety.model.freshness import is_fresh

__all__ = [
    "LEGS",
    "BagLegs",
    "NegativeTopic",
    "SimPeople",
    "bag_frames",
    "leg_labels",
    "negative_topics",
    "perception_chain",
    "positive_bags",
    "simulated_people",
]

# The labelled bags are BSD-3 and copied into the repository (source in the folder's SOURCE.md).
LEGS = Path(__file__).resolve().parents[1] / "tests" / "data" / "leg_tracker"


@dataclass
class BagLegs:
    """Per positive bag: what happened to its labelled legs (module docstring)."""

    bag: str
    scans: int = 0
    outcome: Counter[str] = field(default_factory=Counter)
    called: Counter[str] = field(default_factory=Counter)
    # Labelled legs whose track's smallest closing speed is below the person speed.
    errors_with_floor: int = 0
    errors_without_floor: int = 0
    # Scans with two labelled legs both in kept clusters: one cluster for both, or two.
    pair_one_cluster: int = 0
    pair_two_clusters: int = 0
    # The box of the cluster at each labelled leg (longer side) [m].
    extent_m: list[float] = field(default_factory=list)

    @property
    def legs(self) -> int:
        """Labelled legs read."""
        return sum(self.outcome.values())

    @property
    def person(self) -> int:
        """Labelled legs in a cluster whose track is classified person."""
        return self.outcome["scored person"]


@dataclass
class NegativeTopic:
    """One laser of ``negative_2.bag`` (nobody in view)."""

    topic: str
    scans: int = 0
    scored_rows: int = 0
    person_rows: int = 0
    tracks: int = 0
    person_tracks: int = 0
    # Scored track rows that the person floor raises (the rule's cost on these scans).
    raised_rows: int = 0


def leg_labels(bag: Path) -> list[FloatArray]:
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


def perception_chain(config: SafecaseConfig, classifier: Classifier) -> Perception:
    """The runtime's perception chain for one scan stream (laser frame, no odometry)."""
    return Perception.from_config(config, classifier=classifier, guard=is_fresh)


def bag_frames(bag: Path, topic: str) -> Iterator[Frame]:
    """The bag's frames through the stamp rule every log source follows."""
    return LogSource(bag, scan_topic=topic).frames()


def _track_closing(
    builder: EnvelopeBuilder, pred: Predictions, names: tuple[str, ...], floor: bool
) -> dict[int, float]:
    """Smallest closing speed [m/s] of each track's envelopes, with or without the floor."""
    rows = pred if floor else dataclasses.replace(pred, person_compatible=np.zeros(pred.n, bool))
    closing = builder.closing_speeds(rows, names)
    out: dict[int, float] = {}
    for track, value in zip(pred.track_id.tolist(), closing.tolist(), strict=True):
        out[track] = min(out.get(track, np.inf), value)
    return out


def positive_bags(config: SafecaseConfig, classifier: Classifier) -> list[BagLegs]:
    """Every ``positive_*_extracted.bag``, through the chain (module docstring)."""
    person = classifier.class_index(PERSON_CLASS)
    builder = EnvelopeBuilder.from_config(config)
    walk = float(builder.params.person_speed_mps)
    names = classifier.class_names
    eps = config.cluster.eps_m
    out = []
    for bag in sorted(LEGS.glob("positive_*_extracted.bag")):
        labels = leg_labels(bag)
        chain = perception_chain(config, classifier)
        res = BagLegs(bag.name, scans=len(labels))
        for frame, legs in zip(bag_frames(bag, "/training_scan"), labels, strict=False):
            seen = chain.perceive(frame)
            points, clusters, tracks = seen.points, seen.clusters, seen.tracked.tracks
            result = seen.classification
            with_floor = _track_closing(builder, seen.predictions, names, floor=True)
            without = _track_closing(builder, seen.predictions, names, floor=False)
            xy = np.stack([points.x_m, points.y_m], axis=1)
            held: list[int] = []
            for leg in legs:
                kept = clusters.point_labels[np.hypot(*(xy - leg).T) <= eps]
                kept = kept[kept >= 0]
                if not kept.size:
                    res.outcome["no kept cluster at the label"] += 1
                    continue
                cluster = int(np.bincount(kept).argmax())
                held.append(cluster)
                res.extent_m.append(
                    float(max(clusters.width_m[cluster], clusters.length_m[cluster]))
                )
                follow = np.flatnonzero(tracks.detection_index == cluster)
                if follow.size:
                    track = int(tracks.track_id[follow[0]])
                    res.errors_with_floor += with_floor.get(track, np.inf) < walk
                    res.errors_without_floor += without.get(track, np.inf) < walk
                if not follow.size or result.class_index[follow[0]] < 0:
                    res.outcome["cluster, track not yet scored"] += 1
                    continue
                k = int(result.class_index[follow[0]])
                res.outcome["scored person" if k == person else "scored other class"] += 1
                res.called[names[k]] += 1
            if len(legs) == 2 and len(held) == 2:
                if held[0] == held[1]:
                    res.pair_one_cluster += 1
                else:
                    res.pair_two_clusters += 1
        out.append(res)
    return out


def negative_topics(config: SafecaseConfig, classifier: Classifier) -> list[NegativeTopic]:
    """Each laser of ``negative_2.bag``: person false positives and the floor's reach."""
    person = classifier.class_index(PERSON_CLASS)
    negative = LEGS / "negative_2.bag"
    builder = EnvelopeBuilder.from_config(config)
    names = classifier.class_names
    out = []
    for topic in laserscan_topics(negative):
        chain = perception_chain(config, classifier)
        res = NegativeTopic(topic)
        ids: set[int] = set()
        person_ids: set[int] = set()
        for frame in bag_frames(negative, topic):
            seen = chain.perceive(frame)
            res.scans += 1
            tracks, result, pred = seen.tracked.tracks, seen.classification, seen.predictions
            scored = result.class_index >= 0
            res.scored_rows += int(scored.sum())
            hit = scored & (result.class_index == person)
            res.person_rows += int(hit.sum())
            ids.update(tracks.track_id[scored].tolist())
            person_ids.update(tracks.track_id[hit].tolist())
            # A scored row is raised when the floor lifts one of its envelopes.
            lifted = _track_closing(builder, pred, names, True)
            plain = _track_closing(builder, pred, names, False)
            scored_ids = set(tracks.track_id[scored].tolist())
            res.raised_rows += sum(1 for t in scored_ids if lifted.get(t, 0.0) > plain.get(t, 0.0))
        res.tracks, res.person_tracks = len(ids), len(person_ids)
        out.append(res)
    return out


@dataclass
class SimPeople:
    """The simulator's people as the chain clusters them (scans where a person returns points
    in kept clusters): in one cluster or in two, and each cluster's box (longer side) [m]."""

    scans_one_cluster: int = 0
    scans_two_clusters: int = 0
    extent_m: list[float] = field(default_factory=list)


def simulated_people(
    config: SafecaseConfig, scenario: str, seeds: range, duration_s: float
) -> SimPeople:
    """Runs of ``scenario`` through the tracking chain with the configured scanner: per scan
    and person object, how many kept clusters hold its returns."""
    from pipeline.sources.sim.truth import ObjectClass
    from pipeline.training.data import RunSpec, perceive

    person = int(ObjectClass.PERSON)
    out = SimPeople()
    for seed in seeds:
        for cycle in perceive(config, RunSpec(scenario, seed, duration_s), {}):
            truth = cycle.frame.truth
            points, clusters = cycle.tracked.points, cycle.tracked.clusters
            owner = truth.beams.owner_id[points.beam_index]
            for object_id in truth.object_id[truth.label == person].tolist():
                held = np.unique(clusters.point_labels[(owner == object_id)])
                held = held[held >= 0]
                if held.size == 1:
                    out.scans_one_cluster += 1
                elif held.size >= 2:
                    out.scans_two_clusters += 1
                out.extent_m.extend(
                    np.maximum(clusters.width_m[held], clusters.length_m[held]).tolist()
                )
    return out


def main() -> None:
    """Print the per-bag figures of docs/findings/classification.md."""
    config = default_config()
    classifier = Classifier.from_config(config.classify)
    for b in positive_bags(config, classifier):
        extent = np.asarray(b.extent_m)
        print(
            f"{b.bag}: scans {b.scans}, legs {b.legs}, person {b.person} "
            f"({b.person / max(b.legs, 1):.1%}), outcome {dict(b.outcome)}, "
            f"errors with floor {b.errors_with_floor}, without {b.errors_without_floor}, "
            f"pairs one cluster {b.pair_one_cluster}, two {b.pair_two_clusters}, "
            f"cluster extent p50/p99/max {np.percentile(extent, [50, 99, 100]).round(3)}, "
            f"called {dict(b.called)}"
        )
    for n in negative_topics(config, classifier):
        print(
            f"negative_2.bag {n.topic}: scans {n.scans}, scored rows {n.scored_rows}, person rows "
            f"{n.person_rows} ({n.person_rows / max(n.scans, 1):.2f} per scan), tracks "
            f"{n.tracks}, ever person {n.person_tracks}, rows raised by the floor {n.raised_rows}"
        )
    for beams, fov in ((768, 270.0), (config.sim.beams, config.sim.fov_deg)):
        layout = overridden(config, {"sim": {"beams": beams, "fov_deg": fov}})
        people = simulated_people(layout, "crossing_pedestrian", range(3), 10.0)
        extent = np.asarray(people.extent_m)
        print(
            f"simulator crossing_pedestrian seeds 0-2, {beams} beams over {fov:g} deg: person in "
            f"one cluster {people.scans_one_cluster} scans, two {people.scans_two_clusters}; "
            f"cluster extent p50/p99/max {np.percentile(extent, [50, 99, 100]).round(3)}"
        )


if __name__ == "__main__":
    main()
    sys.exit(0)
