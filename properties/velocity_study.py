"""How good is a track's velocity, and what does its uncertainty cost? (SR-AVL-3, SR-PRED-1)

A moving object's cone (:mod:`pipeline.predict`) has radius ``(|v| + k sigma_v) H`` and
half-angle ``cone + asin(k sigma_v / |v|)``: once ``k sigma_v`` nears the object's speed, its
heading is unknown and the cone opens towards a disc. This study runs named scenarios in closed
loop with the runtime as configured and compares, every cycle, each confirmed track's filtered
velocity with the true velocity of the object it follows, to say whether ``sigma_v`` could be
smaller (the filter tuned tighter) without the speed bound losing the truth.

Scored: confirmed tracks updated this cycle by a cluster of which one object owns at least
:data:`OWNED_SHARE` of the beams (the simulator's per-beam truth), that object moving (its true
speed at least :data:`MOVING_MPS`); the truth is the velocity of the object's reference point
(the centre of its true box, :class:`~pipeline.oracle.GroundTruthPerception`). Per row: the
error ``|v - v_true|`` [m/s], ``sigma_v`` (the largest standard deviation of the velocity
estimate, as the prediction reads it), the true speed, whether the speed bound
``|v| + k sigma_v`` holds the true speed, and the cone's half-angle [deg] (180 once it is a
disc).

``python -m properties.velocity_study --seeds 3`` prints the table that
docs/findings/availability.md shows, for the configured process noise and the alternatives
given by ``--accel`` (``track.process_accel_std_mps2`` values).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.oracle import GroundTruthPerception
from pipeline.perception import Perceived
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import SimFrame
from pipeline.track.kalman import largest_std
from pipeline.types import FloatArray, IntArray, TrackStatus
from safety.cycle import CycleInput, CycleOutput
from safety.run import run_simulation, site_map
from safety.runtime import Runtime

__all__ = [
    "HEADER",
    "MOVING_MPS",
    "OWNED_SHARE",
    "SCENARIOS",
    "VelocityRows",
    "main",
    "run_rows",
    "score_cycle",
    "study",
    "table_row",
    "table_rows",
]

OWNED_SHARE = 0.8
"""A track is scored against the object that owns at least this share of its cluster's beams."""
MOVING_MPS = 0.05
"""Objects slower than this [m/s] are not scored (their heading is undefined)."""
SCENARIOS = (
    "reversing_forklift_aisle",
    "crossing_pedestrian",
    "pallet_jack_slow",
    "occlusion_behind_cart",
    "forklift_pass_by",
)
HEADER = (
    "| track.process_accel_std_mps2 | object | rows | error p50 / p90 / p95 [m/s] "
    "| sigma_v p50 [m/s] "
    "| error within 2 sigma_v | speed bound holds the true speed | cone half-angle p50 "
    "| rows whose cone is a disc |\n|---|---|---|---|---|---|---|---|---|"
)


@dataclass(frozen=True)
class VelocityRows:
    """Scored track rows (module docstring): per row the true object's class name, the
    velocity error [m/s], ``sigma_v`` [m/s], the true and the filtered speed [m/s], whether the
    speed bound holds the true speed, and the cone's half-angle [deg]."""

    class_name: tuple[str, ...]
    error_mps: FloatArray
    sigma_v_mps: FloatArray
    true_speed_mps: FloatArray
    speed_mps: FloatArray
    bound_holds: np.ndarray
    cone_half_deg: FloatArray

    def where(self, keep: np.ndarray) -> VelocityRows:
        """The rows where ``keep`` is true."""
        return VelocityRows(
            tuple(name for name, k in zip(self.class_name, keep, strict=True) if k),
            self.error_mps[keep],
            self.sigma_v_mps[keep],
            self.true_speed_mps[keep],
            self.speed_mps[keep],
            self.bound_holds[keep],
            self.cone_half_deg[keep],
        )

    @classmethod
    def join(cls, parts: Sequence[VelocityRows]) -> VelocityRows:
        """All rows of ``parts``, in order."""
        if not parts:
            empty = np.zeros(0)
            return cls((), empty, empty, empty, empty, np.zeros(0, dtype=bool), empty)
        return cls(
            tuple(name for p in parts for name in p.class_name),
            np.concatenate([p.error_mps for p in parts]),
            np.concatenate([p.sigma_v_mps for p in parts]),
            np.concatenate([p.true_speed_mps for p in parts]),
            np.concatenate([p.speed_mps for p in parts]),
            np.concatenate([p.bound_holds for p in parts]),
            np.concatenate([p.cone_half_deg for p in parts]),
        )


def score_cycle(
    ours: Perceived,
    truth: Perceived,
    owner_id: IntArray,
    object_ids: IntArray,
    config: SafecaseConfig,
) -> VelocityRows:
    """The scored rows of one cycle: ``ours`` the chain's result, ``truth`` the oracle's on the
    same frame (its first rows are the world's objects, in order), ``owner_id`` the simulator's
    per-beam owner of the scan and ``object_ids`` the world's object ids, in order."""
    k = config.predict.velocity_sigmas
    mine, real = ours.fused.tracks, truth.fused.tracks
    labels = ours.clusters.point_labels
    owners = owner_id[ours.points.beam_index]
    names = truth.classification.class_names
    parts = []
    updated = (mine.status == int(TrackStatus.CONFIRMED)) & (mine.detection_index >= 0)
    for i in np.flatnonzero(updated):
        hit = owners[labels == mine.detection_index[i]]
        ids, count = np.unique(hit, return_counts=True)
        if count.size == 0 or count.max() < OWNED_SHARE * hit.size or ids[count.argmax()] < 0:
            continue
        j = int(np.flatnonzero(object_ids == ids[count.argmax()])[0])
        true_speed = float(np.hypot(*real.state[j, 2:4]))
        if true_speed < MOVING_MPS:
            continue
        sigma_v = float(largest_std(mine.covariance[i : i + 1, 2:, 2:])[0])
        speed = float(np.hypot(*mine.state[i, 2:4]))
        spread = math.degrees(math.asin(min(k * sigma_v / speed, 1.0))) if speed > 0 else 90.0
        half = config.predict.cone_half_angle_deg + spread
        parts.append(
            VelocityRows(
                (names[int(truth.classification.class_index[j])],),
                np.array([float(np.hypot(*(mine.state[i, 2:4] - real.state[j, 2:4])))]),
                np.array([sigma_v]),
                np.array([true_speed]),
                np.array([speed]),
                np.array([true_speed <= speed + k * sigma_v]),
                np.array([180.0 if half >= 90.0 else half]),
            )
        )
    return VelocityRows.join(parts)


def run_rows(
    config: SafecaseConfig, classifier: Classifier, name: str, seed: int, duration_s: float
) -> VelocityRows:
    """The scored rows of one closed-loop run of scenario ``name`` with ``seed``."""
    sim = make_simulation(config, name, seed, duration_s)
    truth = GroundTruthPerception.for_simulation(config, sim)
    runtime = Runtime(config, classifier=classifier, static_map=site_map(config, sim))
    object_ids = sim.world.object_ids
    beams: dict[float, IntArray] = {}
    parts: list[VelocityRows] = []
    step = sim.next_frame

    def recorded() -> SimFrame | None:
        got = step()
        if got is not None:
            beams[got.scan.stamp_s] = got.truth.beams.owner_id
        return got

    def observe(inp: CycleInput, out: CycleOutput) -> None:
        seen = out.detail.perceived if out.detail is not None else None
        if seen is not None:
            owner_id = beams.pop(seen.points.stamp_s)
            real = truth.perceive(inp.frame())
            parts.append(score_cycle(seen, real, owner_id, object_ids, config))

    sim.next_frame = recorded  # type: ignore[method-assign]
    run_simulation(config, sim, runtime=runtime, observe=observe)
    return VelocityRows.join(parts)


def study(
    config: SafecaseConfig, names: Sequence[str], seeds: Sequence[int], duration_s: float
) -> VelocityRows:
    """Every scored row of the runs ``names`` x ``seeds`` (``duration_s`` each) in closed loop."""
    classifier = Classifier.from_config(config.classify)
    return VelocityRows.join(
        [run_rows(config, classifier, name, seed, duration_s) for name in names for seed in seeds]
    )


def table_rows(accel_mps2: float, rows: VelocityRows) -> list[str]:
    """Markdown rows of :data:`HEADER`: every object, then each true class apart."""
    names = np.array(rows.class_name, dtype=object)
    out = [table_row(accel_mps2, "all", rows)]
    for name in sorted(set(rows.class_name)):
        out.append(table_row(accel_mps2, name, rows.where(names == name)))
    return out


def table_row(accel_mps2: float, label: str, rows: VelocityRows) -> str:
    """One Markdown row of :data:`HEADER` (``label``: which objects)."""
    if rows.error_mps.size == 0:
        return f"| {accel_mps2:g} | {label} | 0 | | | | | | |"
    p50, p90, p95 = np.percentile(rows.error_mps, [50, 90, 95])
    within = float(np.mean(rows.error_mps <= 2.0 * rows.sigma_v_mps))
    return (
        f"| {accel_mps2:g} | {label} | {rows.error_mps.size:,} "
        f"| {p50:.3f} / {p90:.3f} / {p95:.3f} "
        f"| {np.median(rows.sigma_v_mps):.3f} | {within:.1%} | {np.mean(rows.bound_holds):.1%} "
        f"| {np.median(rows.cone_half_deg):.0f} deg | {np.mean(rows.cone_half_deg >= 180.0):.1%} |"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Print :data:`HEADER` and one row per process-noise value (module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m properties.velocity_study")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--duration", type=float, default=15.0)
    parser.add_argument("--scenario", action="append", default=[], choices=SCENARIOS)
    parser.add_argument("--accel", type=float, action="append", default=[])
    args = parser.parse_args(argv)
    base = default_config()
    values = [base.track.process_accel_std_mps2, *args.accel]
    print(HEADER)
    for accel in values:
        config = overridden(base, {"track": {"process_accel_std_mps2": accel}})
        rows = study(config, args.scenario or SCENARIOS, range(args.seeds), args.duration)
        print("\n".join(table_rows(accel, rows)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
