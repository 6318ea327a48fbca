"""The track heading in prediction: ``predict.heading_source`` "motion" against "track" on
ray-cast ``vehicle_headings`` runs (SR-PRED-4).

Every run keeps the robot standing and feeds every scan through the tracking half of the chain
(:func:`properties.airside_runs.airside_frames`, the scanner's true pose as odometry), with the
box or the L-shape as shape estimator. Each cycle's tracks are predicted twice, once per
heading source, with every track given one class at confidence 1, so that the geometry is
compared and not the classifier: ``vehicle`` (moving class: cone rows) or
``forklift_near_reversal`` (STOP and REVERSE rows). The features, and so whether a track may be
a person, are the chain's own.

Scored: confirmed tracks updated this cycle by a cluster that one box-like vehicle owns (80 % of
its points; tug, covered cart, platform cart, robot, the nearly square containers left out, as
in :mod:`properties.heading_cases`). For each, at every ``predict.step_s`` of the horizon
(0 included) the object's true centre at that time is *contained* when it lies within the
row's body radius of the hull of one of the track's reach regions (the reach grown by the body,
as the envelopes grow it before their margin). The reach area is that of the track's largest
row (REVERSE holds STOP). *Slow*: the object's true speed below 0.3 m/s at the cycle.

The first test mixes the motion with the body model (a cluster that shows one face has its
centroid on that face, far from the true centre). The second isolates the motion: the object's
true displacement since the cycle, added to the track's position, inside one of the reach hulls
(no body), as SR-PRED-1's properties judge it. Beside them, how often the true centre lies
farther than the body radius from the track's position at the cycle itself.

``python -m properties.heading_prediction_study --seeds N`` prints the table that
docs/findings/tracking-airside.md shows; with ``--closed-loop SCENARIO`` it runs that scenario's
seeds in closed loop under both sources instead and counts the cycles whose envelopes differ
(:func:`closed_loop`).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely

from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.frames import checked_pose
from pipeline.perception import Perception
from pipeline.predict import predict
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import SimFrame
from pipeline.sources.sim.truth import KIND_NAMES
from pipeline.types import FloatArray, Frame, Predictions, TrackStatus
from properties.airside_runs import airside_frames, cluster_owners
from properties.heading_cases import BOX_KINDS, SQUARE_KINDS
from properties.prediction_cases import classification
from safety.cycle import CycleInput, CycleOutput
from safety.run import run_simulation

__all__ = [
    "CLASSES",
    "ESTIMATORS",
    "HEADER",
    "SLOW_MPS",
    "SOURCES",
    "Scores",
    "closed_loop",
    "run_scores",
    "study",
    "table",
]

SOURCES = ("motion", "track")
ESTIMATORS = ("box", "lshape")
CLASSES = ("vehicle", "forklift_near_reversal")
SLOW_MPS = 0.3
SCENARIO = "vehicle_headings"
_VEHICLES = tuple(k for k in BOX_KINDS if k not in SQUARE_KINDS)
HEADER = (
    "shape estimator",
    "class given",
    "vehicles",
    "track cycles",
    "axis used %",
    "centre beyond body now %",
    "centre in reach + body: motion %",
    "track %",
    "displacement in reach: motion %",
    "track %",
    "reach area motion m2 (median / p90)",
    "reach area track m2 (median / p90)",
)


@dataclass
class Scores:
    """Per scored track cycle: slow or not, whether the axis was used under "track", the share
    of horizon samples contained and the reach area per heading source."""

    slow: list[bool] = field(default_factory=list)
    axis: list[bool] = field(default_factory=list)
    beyond_body: list[bool] = field(default_factory=list)
    contained: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in SOURCES})
    moved: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in SOURCES})
    area_m2: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in SOURCES})

    def extend(self, other: Scores) -> None:
        """Append ``other``'s samples."""
        self.slow += other.slow
        self.axis += other.axis
        self.beyond_body += other.beyond_body
        for s in SOURCES:
            self.contained[s] += other.contained[s]
            self.moved[s] += other.moved[s]
            self.area_m2[s] += other.area_m2[s]


def _hulls(pred: Predictions) -> FloatArray:
    """Each prediction row's reach hull (shapely geometries)."""
    hulls: FloatArray = shapely.convex_hull(shapely.multipoints(pred.reach_xy_m))
    return hulls


def _score(
    pred: Predictions, track_ids: Sequence[int], centres: FloatArray, moved: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per track of ``track_ids``: the share of its true centres (k, T, 2) within the body of a
    reach hull, the share of its moved reference points (k, T, 2) inside one, and its largest
    reach area [m2] (module docstring)."""
    hulls = _hulls(pred)
    share, share_moved, area = [], [], []
    for tid, path, shifted in zip(track_ids, centres, moved, strict=True):
        rows = np.flatnonzero(pred.track_id == tid)
        d = shapely.distance(hulls[rows][:, None], shapely.points(path)[None, :])
        inside = (d <= pred.body_radius_m[rows][:, None] + 1e-9).any(axis=0)
        d_moved = shapely.distance(hulls[rows][:, None], shapely.points(shifted)[None, :])
        share.append(float(inside.mean()))
        share_moved.append(float((d_moved <= 1e-9).any(axis=0).mean()))
        area.append(float(shapely.area(hulls[rows]).max()))
    return np.array(share), np.array(share_moved), np.array(area)


def run_scores(
    config: SafecaseConfig, frames: Sequence[SimFrame], estimator: str, class_name: str
) -> Scores:
    """Score one run (its frames, in order) for one shape estimator and one class."""
    chain_config = overridden(config, {"cluster": {"shape_estimator": estimator}})
    chain = Perception.from_config(chain_config, tracking_only=True)
    pc = {s: overridden(config, {"predict": {"heading_source": s}}).predict for s in SOURCES}
    medium = config.classify.medium_confidence_min
    period = config.track.frame_period_s
    steps = np.rint(
        np.arange(0.0, pc["motion"].horizon_s + 1e-9, pc["motion"].step_s) / period
    ).astype(np.int64)
    truth_xy = np.stack(
        [np.stack([f.truth.x_m, f.truth.y_m], axis=1) for f in frames]
    )  # (frames, objects, 2): the world lists every object in every frame
    ids = frames[0].truth.object_id.tolist()
    scores = Scores()
    for i, sim_frame in enumerate(frames):
        truth = sim_frame.truth
        frame = Frame(
            sim_frame.scan, sim_frame.observation.stamp_s, pose=checked_pose(truth.scanner_pose)
        )
        tracked = chain.track(frame)
        if i + int(steps[-1]) >= len(frames) or tracked.tracks.n == 0:
            continue
        tracks = tracked.tracks
        owner, share = cluster_owners(
            tracked.points, tracked.clusters.point_labels, tracked.clusters.n, truth
        )
        chosen, objects, rows = [], [], []
        for j in range(tracks.n):
            det = int(tracks.detection_index[j])
            if det < 0 or tracks.status[j] != TrackStatus.CONFIRMED or share[det] < 0.8:
                continue
            if int(owner[det]) not in ids:
                continue
            k = ids.index(int(owner[det]))
            if KIND_NAMES[int(truth.kind[k])] in _VEHICLES:
                chosen.append(int(tracks.track_id[j]))
                objects.append(k)
                rows.append(j)
        if not chosen:
            continue
        centres = truth_xy[i + steps][:, objects].transpose(1, 0, 2)  # (k, T, 2)
        moved = centres - centres[:, :1] + tracks.state[rows, None, :2]
        klass = classification(tracks, class_name, 1.0)
        for source in SOURCES:
            pred = predict(tracks, tracked.features, klass, pc[source], medium, tracked.headings)
            contained, shifted, area = _score(pred, chosen, centres, moved)
            scores.contained[source] += contained.tolist()
            scores.moved[source] += shifted.tolist()
            scores.area_m2[source] += area.tolist()
            if source == "motion":
                body = pred.body_radius_m[np.searchsorted(pred.track_id, chosen)]
                offset = np.hypot(*(centres[:, 0] - tracks.state[rows, :2]).T)
                scores.beyond_body += (offset > body).tolist()
            if source == "track":
                motion_area = np.array(scores.area_m2["motion"][-len(chosen) :])
                scores.axis += (area < motion_area - 1e-9).tolist()
        scores.slow += [bool(truth.speed_mps[k] < SLOW_MPS) for k in objects]
    return scores


def study(
    config: SafecaseConfig, seeds: Sequence[int], duration_s: float
) -> dict[tuple[str, str], Scores]:
    """Scores per (shape estimator, class) over the seeded ``vehicle_headings`` runs."""
    out = {(e, c): Scores() for e in ESTIMATORS for c in CLASSES}
    for seed in seeds:
        frames = airside_frames(config, SCENARIO, seed, duration_s)
        for (e, c), scores in out.items():
            scores.extend(run_scores(config, frames, e, c))
    return out


def _pct(values: FloatArray) -> str:
    return "-" if values.size == 0 else f"{100.0 * float(values.mean()):.2f}"


def _area(values: FloatArray) -> str:
    if values.size == 0:
        return "-"
    return f"{float(np.median(values)):.2f} / {float(np.percentile(values, 90)):.2f}"


def table(results: dict[tuple[str, str], Scores]) -> list[list[str]]:
    """One row per (shape estimator, class, slow / all) (columns :data:`HEADER`); containment is
    the share of horizon samples, pooled."""
    rows = []
    for (estimator, class_name), s in results.items():
        slow = np.array(s.slow, dtype=bool)
        for label, m in ((f"slow (< {SLOW_MPS} m/s)", slow), ("all", np.ones_like(slow))):
            rows.append(
                [
                    estimator,
                    class_name,
                    label,
                    f"{int(m.sum()):,}",
                    _pct(np.array(s.axis, dtype=bool)[m]),
                    _pct(np.array(s.beyond_body, dtype=bool)[m]),
                    _pct(np.array(s.contained["motion"])[m]),
                    _pct(np.array(s.contained["track"])[m]),
                    _pct(np.array(s.moved["motion"])[m]),
                    _pct(np.array(s.moved["track"])[m]),
                    _area(np.array(s.area_m2["motion"])[m]),
                    _area(np.array(s.area_m2["track"])[m]),
                ]
            )
    return rows


def closed_loop(config: SafecaseConfig, scenario: str, seed: int) -> list[str]:
    """One closed-loop run of ``scenario`` per heading source: [scenario, seed, cycles, cycles
    whose envelopes' total area differs, progress under "motion" / "track" [m]]."""
    areas, progress = {}, {}
    for source in SOURCES:
        cfg = overridden(config, {"predict": {"heading_source": source}})
        got: list[float] = []

        def observe(_: CycleInput, out: CycleOutput, got: list[float] = got) -> None:
            env = out.envelopes
            shapes = (
                [] if env is None else [env.polygons.vertex_list(i) for i in range(env.polygons.n)]
            )
            got.append(sum(shapely.Polygon(v).area for v in shapes))

        summary = run_simulation(cfg, make_simulation(cfg, scenario, seed, None), observe=observe)
        assert summary.sim is not None  # run_simulation sets it
        areas[source] = np.array(got)
        progress[source] = float(summary.sim.ego_log["arc_m"][-1])
    differ = int(np.count_nonzero(np.abs(areas["motion"] - areas["track"]) > 1e-9))
    return [
        scenario,
        str(seed),
        str(areas["motion"].shape[0]),
        str(differ),
        f"{progress['motion']:.1f} / {progress['track']:.1f}",
    ]


def main() -> None:
    """Print the study's table for seeds 0..N-1."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--duration", type=float, default=10.0, help="run length [s]")
    parser.add_argument("--closed-loop", metavar="SCENARIO", help="closed-loop runs instead")
    args = parser.parse_args()
    header: tuple[str, ...]
    if args.closed_loop:
        header = ("scenario", "seed", "cycles", "envelopes differ", "progress m motion / track")
        rows = [closed_loop(default_config(), args.closed_loop, s) for s in range(args.seeds)]
    else:
        header, rows = HEADER, table(study(default_config(), range(args.seeds), args.duration))
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
