"""Campaign: the whole perception chain on simulator runs, envelopes against the future (SR-PRED-1).

Each scan goes through the perception chain (:class:`pipeline.perception.Perception`: tracking
in the world frame, the configured classifier, fusion, prediction) and the envelopes. For every
simulated object followed by one or more tracks, the object's LiDAR returns during the next
``predict.horizon_s`` (the surfaces the robot will see) are checked against the union of the
envelopes (all modes) of the tracks that followed it at the earlier scan: the costmap holds all of
them, and a body the clustering splits (a dolly train's trailers, a forklift's tines apart from its
mast) is covered by its parts' envelopes together, not by any one part's. Reported, not asserted:
outside the property's assumptions (a reversal faster than the configured 0.6 m/s, which the
simulator's forklifts do at up to 0.9 m/s; a body seen from one side, so its box underestimates it;
a track still converging) a return may fall outside, and the campaign shows how often. The exact
claim is the property in ``test_prediction.py``.
"""

from __future__ import annotations

import time
from collections import defaultdict, deque
from dataclasses import dataclass

import numpy as np
import pytest
import shapely

from evidence.profiles import active_profile, certifying
from evidence.record import Recorder
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.frames import to_parent
from pipeline.perception import Perception
from pipeline.sources.sim.truth import CLASS_NAMES
from pipeline.training.data import Cycle, RunSpec, perceive
from pipeline.types import Envelopes, PredictionMode
from properties.ahead import ahead
from properties.oracles.geometry import shapely_polygons
from safety.geometry.costmap import CostmapBuilder
from safety.geometry.envelopes import EnvelopeBuilder
from safety.model.freshness import is_fresh

RUNS_CI = (
    RunSpec("reversing_forklift_aisle", 7, 12.0),
    RunSpec("reversal_drill", 7, 12.0),
    RunSpec("crossing_pedestrian", 7, 12.0),
)
RUNS_CERTIFY = tuple(
    RunSpec(name, seed, 20.0)
    for seed in range(200_000, 200_004)
    for name in (
        "reversing_forklift_aisle",
        "reversal_drill",
        "crossing_pedestrian",
        "pallet_jack_slow",
        "forklift_pass_by",
        "dolly_train_turn",
        "random_encounter",
    )
)


def _returns_world(cycle: Cycle) -> dict[int, np.ndarray]:
    """Each object's returns of this scan in the world frame, by object id."""
    truth, points = cycle.frame.truth, cycle.tracked.points
    owner = truth.beams.owner_id[points.beam_index]
    wx, wy = to_parent(cycle.tracked.pose, points.x_m, points.y_m)
    return {
        int(o): np.stack([wx[owner == o], wy[owner == o]], axis=1)
        for o in np.unique(owner[owner >= 0])
    }


@dataclass(frozen=True, slots=True)
class _Followed:
    """A simulated object at one scan: its true class, the prediction modes of the tracks that
    followed it, the union of their envelopes (world frame) and how many tracks they were."""

    object_id: int
    label: str
    modes: str
    union: shapely.Geometry
    n_tracks: int


def _followed_objects(cycle: Cycle, env: Envelopes) -> list[_Followed]:
    """Group one scan's envelopes by the simulated object each track follows."""
    shapes = shapely_polygons(env.polygons)
    rows_of: defaultdict[int, list[np.ndarray]] = defaultdict(list)
    label_of: dict[int, int] = {}
    for i, tid in enumerate(cycle.tracked.tracks.track_id):
        obj = int(cycle.object_of[i])
        rows = np.flatnonzero(env.track_id == tid)
        if obj < 0 or not rows.size or cycle.label[i] < 0:
            continue
        rows_of[obj].append(rows)
        label_of[obj] = int(cycle.label[i])  # the object's class: alike for all its tracks
    out = []
    for obj, parts in rows_of.items():
        rows = np.concatenate(parts)
        modes = "+".join(sorted({PredictionMode(int(m)).name for m in env.mode[rows]}))
        union = shapely.union_all(shapes[rows]).buffer(1e-9)
        out.append(_Followed(obj, CLASS_NAMES[label_of[obj]], modes, union, len(parts)))
    return out


@pytest.mark.requirement(
    "SR-PRED-1", kind="campaign", code=["pipeline/predict.py", "safety/geometry/envelopes.py"]
)
@ahead
def test_future_returns_fall_inside_the_envelopes(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    config = safecase_config
    classifier = Classifier.from_config(config.classify)
    chain = Perception.from_config(config, classifier=classifier, guard=is_fresh)
    builder = EnvelopeBuilder.from_config(config)
    steps = round(config.predict.horizon_s / config.track.frame_period_s)
    runs = RUNS_CERTIFY if certifying() else RUNS_CI
    costmap = CostmapBuilder(config.costmap)
    stage_s: dict[str, list[float]] = {
        "classify": [],
        "predict": [],
        "envelopes": [],
        "costmap": [],
    }
    inside: defaultdict[tuple[str, str], int] = defaultdict(int)
    total: defaultdict[tuple[str, str], int] = defaultdict(int)
    tracks_x_returns: defaultdict[tuple[str, str], int] = defaultdict(int)
    for spec in runs:
        window: deque[list[_Followed]] = deque(maxlen=steps)
        chain.reset()
        for cycle in perceive(config, spec, {}, chain):
            returns = _returns_world(cycle)
            for past in window:  # envelopes of earlier scans within the horizon
                for followed in past:
                    pts = returns.get(followed.object_id)
                    if pts is None or not len(pts):
                        continue
                    hit = shapely.intersects_xy(followed.union, pts[:, 0], pts[:, 1])
                    key = (followed.label, followed.modes)
                    inside[key] += int(hit.sum())
                    total[key] += int(hit.shape[0])
                    tracks_x_returns[key] += followed.n_tracks * int(hit.shape[0])
            assert cycle.perceived is not None  # a full chain perceives
            pred = cycle.perceived.predictions
            t2 = time.perf_counter()
            robot = builder.build(pred, classifier.class_names, cycle.tracked.pose)
            t3 = time.perf_counter()
            costmap.rasterize(robot.polygons)
            t4 = time.perf_counter()
            stage_s["classify"].append(cycle.wall_s["classify"])
            stage_s["predict"].append(cycle.wall_s["predict"])
            stage_s["envelopes"].append(t3 - t2)
            stage_s["costmap"].append(t4 - t3)
            env = builder.build(pred, classifier.class_names)  # world frame, for the check
            window.append(_followed_objects(cycle, env))
    table = []
    for key in sorted(total, key=lambda k: -total[k]):
        label, mode = key
        table.append(
            [
                label,
                mode,
                total[key],
                f"{inside[key] / total[key]:.1%}",
                f"{tracks_x_returns[key] / total[key]:.2f}",
            ]
        )
    all_in, all_n = sum(inside.values()), sum(total.values())
    evidence.table(
        "future LiDAR returns inside the envelopes built up to 1.5 s earlier",
        [
            "true class then",
            "prediction modes",
            "returns checked",
            "inside",
            "tracks on the object",
        ],
        table,
        caption=f"{len(runs)} simulator runs ({active_profile()} profile); overall "
        f"{all_in / max(all_n, 1):.2%} of {all_n} returns inside the union of the envelopes of "
        "the tracks that followed the object (tracks on the object: mean over the returns "
        "checked; above 1 where the clustering split the body)",
    )
    evidence.counts("future returns", {"checked": all_n, "inside": all_in})
    for stage, values in stage_s.items():
        evidence.samples(f"per scan: {stage}", values, unit="s")
    assert all_n > 0, "no returns were checked"
