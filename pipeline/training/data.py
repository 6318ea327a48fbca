"""Labelled feature rows from the simulator, for training and testing the classifier (SR-CLS-2).

A run goes through the run-time chain itself (:class:`pipeline.perception.Perception`, its
tracking half): every scan is filtered, clustered and shaped, the clusters are moved into the
world frame with the scanner's true pose (as odometry would place them), tracked and turned
into features. Rows are kept for the tracks the classifier scores (confirmed and lost,
:data:`pipeline.classify.model.SCORED_STATUSES`).

The robot follows the scenario's route at a cruise speed drawn per run from 0.7-1.0 m/s and
stops while an object is in its lane within a gap drawn from 1-2.5 m (:class:`GapKeeper`, a
ground-truth data generator, not the governor), so runs are not cut short by collisions and
the robot's own speed varies.

Labels come from the ground truth. A track updated by a cluster this cycle takes the owner of
the majority of that cluster's beams (``beam_owner``: an object id, or static structure); the
owner must hold at least :data:`MIN_MAJORITY` of the beams, else the row is ambiguous and
dropped. The object's label at the scan's stamp is the row's class (forklifts carry their
state: moving, stationary, near reversal), static structure is ``static``. A coasting track
(no cluster this cycle) keeps the object of its last labelled update and takes that object's
current label. Dropped rows are counted by reason.

Near-reversal rows are rare in the named scenarios (about 2 % of forklift rows: a reversal
lasts a second or two of a 20 s run), so the data plan adds *reversal drills*
(:func:`reversal_drill`): forklifts shuttling back and forth in the aisle and a cross aisle,
each stop either a reversal or a plain stop-and-go, while the robot keeps its distance. Training
also weights classes inversely to their frequency (:mod:`pipeline.training.train`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.classify.model import MODEL_CLASSES, SCORED_STATUSES
from pipeline.config import SafecaseConfig
from pipeline.features import FEATURE_NAMES
from pipeline.frames import checked_pose, to_child
from pipeline.perception import Perceived, Perception, Stopwatch, Tracked
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import EgoObservation, Route
from pipeline.sources.sim.layouts import warehouse_aisle
from pipeline.sources.sim.objects import counterbalance_forklift, person, reach_truck
from pipeline.sources.sim.scenarios import ScenarioSpec, make_simulation, place, simulation_for_spec
from pipeline.sources.sim.simulation import SimFrame, Simulation
from pipeline.sources.sim.truth import CLASS_NAMES, ObjectClass
from pipeline.sources.sim.world import World
from pipeline.types import (
    BoolArray,
    FloatArray,
    Frame,
    IntArray,
)

__all__ = [
    "DRILL",
    "MIN_MAJORITY",
    "SIM_TO_MODEL_CLASS",
    "STATIC_OWNER",
    "Cycle",
    "GapKeeper",
    "Rows",
    "RunSpec",
    "load_rows",
    "perceive",
    "reversal_drill",
    "run_rows",
    "save_rows",
    "simulation_of",
]

DRILL = "reversal_drill"
# Simulator class -> classifier class (pipeline.classify.model.MODEL_CLASSES): AMRs, baggage tugs
# and dollies are "vehicle"; a parked ULD container, an unpowered load carrier like a cart, "cart".
SIM_TO_MODEL_CLASS = {
    **{name: name for name in MODEL_CLASSES if name in CLASS_NAMES},
    "amr": "vehicle",
    "baggage_tug": "vehicle",
    "dolly": "vehicle",
    "uld_container": "cart",
}
_SIM_TO_MODEL_CODE = np.array(
    [MODEL_CLASSES.index(SIM_TO_MODEL_CLASS[name]) for name in CLASS_NAMES], dtype=np.int64
)
MIN_MAJORITY = 0.6
STATIC_OWNER = -2  # beam_owner code of static structure
_NO_OBJECT = -1


@dataclass(frozen=True, slots=True)
class RunSpec:
    """One simulator run of the data plan: a scenario (or :data:`DRILL`), a seed, a length."""

    scenario: str
    seed: int
    duration_s: float


@dataclass(frozen=True, slots=True)
class GapKeeper:
    """Ego policy for data runs: cruise at ``speed_mps``, stand while an object's centre is in
    the lane ahead closer than ``gap_m`` plus half its length (ground truth; a data generator,
    not a governor)."""

    speed_mps: float
    gap_m: float = 3.0
    lane_half_width_m: float = 0.5

    def __call__(self, observation: EgoObservation) -> float:
        truth = observation.truth
        pose = (truth.ego_pose[0], truth.ego_pose[1], truth.ego_pose[2])
        ahead, side = to_child(pose, truth.x_m, truth.y_m)
        near = (
            (ahead > 0.0)
            & (ahead < self.gap_m + 0.5 * truth.length_m + 0.5)
            & (np.abs(side) < self.lane_half_width_m + 0.5 * truth.width_m)
        )
        return 0.0 if bool(near.any()) else self.speed_mps


def _shuttle(rng: np.random.Generator, cycles: int) -> mo.Motion:
    """Forwards, slow to rest, (reverse or wait), ... ``cycles`` times, from rest."""
    kt, kv = [0.0], [0.0]
    t = 0.0
    direction = 1.0
    for _ in range(cycles):
        speed = float(rng.uniform(0.5, 1.2))
        t += speed / float(rng.uniform(0.6, 1.2))  # accelerate
        kt.append(t)
        kv.append(direction * speed)
        t += float(rng.uniform(1.0, 3.5))  # cruise
        kt.append(t)
        kv.append(direction * speed)
        t += 0.1 * int(rng.integers(3, 8))  # slow to rest over 3-7 frames
        kt.append(t)
        kv.append(0.0)
        t += float(rng.uniform(0.05, 1.5))  # dwell
        kt.append(t)
        kv.append(0.0)
        # Mostly a reversal (the next leg goes the other way), sometimes stop-and-go.
        if rng.random() < 0.75:
            direction = -direction
    return mo.Motion(np.array(kt), np.array(kv), np.zeros(1), np.zeros(1), "shuttle")


def reversal_drill(rng: np.random.Generator, duration_s: float) -> ScenarioSpec:
    """Forklifts shuttling in the main aisle and a cross aisle, and a person standing by.

    The aisle forklift starts 9-20 m ahead of the robot and its cross-aisle partner shuttles
    across the main aisle; the robot follows the aisle and keeps its distance (:class:`GapKeeper`).
    """
    c1 = float(rng.uniform(24.0, 27.0))
    layout = warehouse_aisle(rng, length_m=40.0, cross_aisles_m=((c1, c1 + 3.5),))
    trucks = (counterbalance_forklift, reach_truck)
    objects = [
        place(
            1,
            "aisle_forklift",
            trucks[int(rng.integers(0, 2))](),
            _shuttle(rng, 8),
            (float(rng.uniform(9.0, 20.0)), float(rng.uniform(-0.3, 0.3)), 0.0),
            duration_s,
        ),
        place(
            2,
            "cross_forklift",
            trucks[int(rng.integers(0, 2))](),
            _shuttle(rng, 8),
            (c1 + 1.75, float(rng.uniform(-4.5, -2.5)), math.pi / 2),
            duration_s,
        ),
        place(
            3,
            "bystander",
            person(),
            mo.stationary(),
            (c1 - 1.2, float(rng.uniform(1.0, 1.4)), 0.0),
            duration_s,
        ),
    ]
    world = World(DRILL, layout.structure, tuple(objects), layout.bounds_m)
    return ScenarioSpec(world, Route(np.array([[0.0, 0.0], [34.0, 0.0]])), initial_speed_mps=0.0)


@dataclass
class Rows:
    """Labelled feature rows (struct of arrays) and why rows were dropped.

    ``label`` holds the simulator's class codes (:data:`pipeline.sources.sim.truth.CLASS_NAMES`);
    :attr:`model_label` maps them to the classifier's (:data:`SIM_TO_MODEL_CLASS`).
    """

    features: FloatArray
    label: IntArray
    run: IntArray
    stamp_s: FloatArray
    track_id: IntArray
    object_id: IntArray
    range_m: FloatArray
    runs: list[RunSpec] = field(default_factory=list)
    dropped: dict[str, int] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of rows."""
        return int(self.label.shape[0])

    @property
    def model_label(self) -> IntArray:
        """Each row's class in the classifier's classes (``MODEL_CLASSES`` codes)."""
        codes: IntArray = _SIM_TO_MODEL_CODE[self.label]
        return codes

    def model_counts(self) -> dict[str, int]:
        """Rows per classifier class."""
        counts = np.bincount(self.model_label, minlength=len(MODEL_CLASSES))
        return {name: int(counts[i]) for i, name in enumerate(MODEL_CLASSES)}

    def counts(self) -> dict[str, int]:
        """Rows per class name."""
        counts = np.bincount(self.label, minlength=len(CLASS_NAMES))
        return {name: int(counts[i]) for i, name in enumerate(CLASS_NAMES)}

    def take(self, mask: np.ndarray) -> Rows:
        """The rows selected by ``mask``."""
        return Rows(
            self.features[mask],
            self.label[mask],
            self.run[mask],
            self.stamp_s[mask],
            self.track_id[mask],
            self.object_id[mask],
            self.range_m[mask],
            list(self.runs),
            dict(self.dropped),
        )


def simulation_of(config: SafecaseConfig, spec: RunSpec) -> Simulation:
    """The simulation a run spec names (the drill or a named scenario), not yet run."""
    if spec.scenario == DRILL:
        rng = np.random.default_rng(np.random.SeedSequence(spec.seed).spawn(3)[0])
        built = reversal_drill(rng, spec.duration_s)
        return simulation_for_spec(config, built, DRILL, spec.seed, spec.duration_s)
    return make_simulation(config, spec.scenario, spec.seed, spec.duration_s)


def _majority(owners: IntArray, labels: IntArray, n_clusters: int) -> tuple[IntArray, FloatArray]:
    """Per cluster: the most frequent beam owner and its share of the cluster's points."""
    if n_clusters == 0 or owners.shape[0] == 0:
        return np.full(n_clusters, _NO_OBJECT, dtype=np.int64), np.zeros(n_clusters)
    keys, inverse = np.unique(owners, return_inverse=True)
    table = np.zeros((n_clusters, keys.shape[0]), dtype=np.int64)
    np.add.at(table, (labels, inverse), 1)
    best = table.argmax(axis=1)
    share = table[np.arange(n_clusters), best] / np.maximum(table.sum(axis=1), 1)
    return keys[best].astype(np.int64), share


def _labels(object_of: IntArray, ids: IntArray, labels: IntArray) -> IntArray:
    """Class code per row: static structure, the object's label, or -1 (no such object)."""
    out = np.full(object_of.shape[0], -1, dtype=np.int64)
    out[object_of == STATIC_OWNER] = int(ObjectClass.STATIC)
    lookup = {int(i): int(lab) for i, lab in zip(ids, labels, strict=True)}
    for row in np.flatnonzero(object_of >= 0):
        out[row] = lookup.get(int(object_of[row]), -1)
    return out


@dataclass(frozen=True)
class Cycle:
    """One scan through the perception chain, with ground-truth associations.

    ``tracked`` is the chain's tracking half (points, clusters, tracks, features; the tracking
    frame is the world frame, placed by the scanner's true pose); ``perceived`` the whole chain
    when the caller's :class:`~pipeline.perception.Perception` classifies, else None. Per track
    of ``tracked.tracks``: ``object_of`` is the object id it follows (:data:`STATIC_OWNER` for
    static structure, -1 unknown), ``label`` its class code at this scan (-1 unknown) and
    ``scored`` whether the classifier scores it. ``wall_s`` holds the chain's stage times [s].
    """

    frame: SimFrame
    tracked: Tracked
    perceived: Perceived | None
    object_of: IntArray
    label: IntArray
    scored: BoolArray
    wall_s: dict[str, float]

    @property
    def robot_xy_m(self) -> tuple[float, float]:
        """The scanner's position in the world (tracking) frame."""
        return (self.tracked.pose[0], self.tracked.pose[1])


def perceive(
    config: SafecaseConfig,
    spec: RunSpec,
    dropped: dict[str, int],
    perception: Perception | None = None,
) -> Iterator[Cycle]:
    """Run one simulation through the perception chain, labelling as it goes.

    ``perception`` defaults to the configured chain's tracking half (training needs no
    classifier); a full chain (:meth:`Perception.perceive`) also classifies, fuses and predicts.
    ``dropped`` accumulates rows left unlabelled, by reason (module docstring).
    """
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed).spawn(4)[3])
    sim = simulation_of(config, spec)
    policy = GapKeeper(float(rng.uniform(0.7, 1.0)), float(rng.uniform(1.0, 2.5)))
    chain = (
        perception if perception is not None else Perception.from_config(config, tracking_only=True)
    )
    full = chain.classifier is not None
    remembered: dict[int, int] = {}  # track id -> object id of its last labelled update
    for key in ("ambiguous", "unlabelled coasting", "object gone"):
        dropped.setdefault(key, 0)
    sim.command(policy.speed_mps)
    while (sim_frame := sim.next_frame()) is not None:
        truth = sim_frame.truth
        frame = Frame(
            sim_frame.scan,
            sim_frame.observation.stamp_s,
            pose=checked_pose(truth.scanner_pose),
        )
        watch = Stopwatch()
        perceived = chain.perceive(frame, watch=watch) if full else None
        tracked = perceived.tracked if perceived is not None else chain.track(frame, watch)
        points, clusters, tracks = tracked.points, tracked.clusters, tracked.tracks
        sim.command(policy(sim_frame.observation))
        keep = np.isin(tracks.status, [int(s) for s in SCORED_STATUSES])
        object_of = np.full(tracks.n, _NO_OBJECT, dtype=np.int64)
        label = np.full(tracks.n, -1, dtype=np.int64)
        if keep.any():
            labels = clusters.point_labels
            in_cluster = labels >= 0
            owners = truth.beams.owner_id[points.beam_index[in_cluster]]
            owner, share = _majority(owners, labels[in_cluster], clusters.n)
            det = tracks.detection_index
            updated = keep & (det >= 0)
            clear = updated.copy()
            clear[updated] = (share[det[updated]] >= MIN_MAJORITY) & (owner[det[updated]] != -1)
            dropped["ambiguous"] += int(np.count_nonzero(updated & ~clear))
            object_of[clear] = owner[det[clear]]
            for i in np.flatnonzero(clear):
                remembered[int(tracks.track_id[i])] = int(object_of[i])
            for i in np.flatnonzero(keep & (det < 0)):
                if int(tracks.track_id[i]) in remembered:
                    object_of[i] = remembered[int(tracks.track_id[i])]
                else:
                    dropped["unlabelled coasting"] += 1
            label = _labels(object_of, truth.object_id, truth.label)
            dropped["object gone"] += int(np.count_nonzero((object_of >= 0) & (label < 0)))
        yield Cycle(sim_frame, tracked, perceived, object_of, label, keep, watch.wall_s)


def run_rows(config: SafecaseConfig, spec: RunSpec, run_index: int = 0) -> Rows:
    """Labelled rows of one simulation (tracks the classifier scores, with a label)."""
    out: dict[str, list[np.ndarray]] = {k: [] for k in ("x", "y", "t", "tid", "oid", "r")}
    dropped: dict[str, int] = {}
    for cycle in perceive(config, spec, dropped):
        tracks = cycle.tracked.tracks
        rows = cycle.scored & (cycle.label >= 0)
        if not rows.any():
            continue
        sx, sy = cycle.robot_xy_m
        out["x"].append(cycle.tracked.features.values[rows])
        out["y"].append(cycle.label[rows])
        out["t"].append(np.full(int(rows.sum()), cycle.frame.truth.stamp_s))
        out["tid"].append(tracks.track_id[rows])
        out["oid"].append(cycle.object_of[rows])
        out["r"].append(np.hypot(tracks.state[rows, 0] - sx, tracks.state[rows, 1] - sy))
    n = sum(a.shape[0] for a in out["y"])
    return Rows(
        features=np.concatenate(out["x"]) if n else np.zeros((0, len(FEATURE_NAMES))),
        label=np.concatenate(out["y"]).astype(np.int64) if n else np.zeros(0, np.int64),
        run=np.full(n, run_index, dtype=np.int64),
        stamp_s=np.concatenate(out["t"]) if n else np.zeros(0),
        track_id=np.concatenate(out["tid"]).astype(np.int64) if n else np.zeros(0, np.int64),
        object_id=np.concatenate(out["oid"]).astype(np.int64) if n else np.zeros(0, np.int64),
        range_m=np.concatenate(out["r"]) if n else np.zeros(0),
        runs=[spec],
        dropped=dropped,
    )


def save_rows(path: Path, rows: Rows) -> None:
    """Write rows compactly (features as float32, the classifier's input precision)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        np.savez_compressed(
            fh,
            features=rows.features.astype(np.float32),
            label=rows.label.astype(np.int8),
            run=rows.run.astype(np.int32),
            stamp_s=rows.stamp_s.astype(np.float32),
            track_id=rows.track_id.astype(np.int32),
            object_id=rows.object_id.astype(np.int32),
            range_m=rows.range_m.astype(np.float32),
            runs=np.array([[r.scenario, str(r.seed), repr(r.duration_s)] for r in rows.runs]),
            feature_names=np.array(FEATURE_NAMES),
            class_names=np.array(CLASS_NAMES),
            dropped_json=np.array(json.dumps(rows.dropped, sort_keys=True)),
        )


def load_rows(path: Path) -> Rows:
    """Read rows written by :func:`save_rows` (features widened back to float64)."""
    with np.load(path, allow_pickle=False) as data:
        if tuple(str(n) for n in data["feature_names"]) != FEATURE_NAMES:
            raise ValueError(f"{path}: feature names differ from {FEATURE_NAMES}")
        if tuple(str(n) for n in data["class_names"]) != CLASS_NAMES:
            raise ValueError(f"{path}: class names differ from {CLASS_NAMES}")
        runs = [RunSpec(str(s), int(seed), float(d)) for s, seed, d in data["runs"]]
        return Rows(
            features=data["features"].astype(np.float64),
            label=data["label"].astype(np.int64),
            run=data["run"].astype(np.int64),
            stamp_s=data["stamp_s"].astype(np.float64),
            track_id=data["track_id"].astype(np.int64),
            object_id=data["object_id"].astype(np.int64),
            range_m=data["range_m"].astype(np.float64),
            runs=runs,
            dropped=json.loads(str(data["dropped_json"])),
        )
