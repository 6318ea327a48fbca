"""The perception chain's outputs are bit-identical to the recorded golden digests.

``tests/data/golden/perception.<numerics>.json`` holds, per cycle, a SHA-256 digest (24 hex
digits) of every stage's output (points, clusters, tracks, features, classes, fusion,
predictions) and of the safety side's results (command, governor inputs, envelopes, path
distances) for three closed-loop simulator runs with thermal detections, the labelled training
rows of two runs, and the chain on 150 scans of a real bag in the laser's frame. A digest
covers every field's dtype, shape and bytes, so any change in any bit of any output fails the
test.

Bits depend on the machine's numerics as well as on the code: numpy picks its sin, cos, exp
and reductions by CPU at run time, and x86-64 with AVX-512 and with AVX2 only round differently
in the last bit (the points of a scan already differ). One set of digests is kept per
*numerics path* (:func:`numerics_path`, e.g. ``x86-64-avx512``); the outputs must equal one of
the recorded sets entirely, so a change of code fails on every machine, and a machine on a path
none was recorded on fails too, naming its path.

A machine whose outputs equal no set may still run a narrower path that was recorded: numpy's
dispatch can be narrowed at start-up (``NPY_DISABLE_CPU_FEATURES``) and OpenBLAS's kernels named
(``OPENBLAS_CORETYPE``), so an x86-64 machine with AVX-512 runs the same code as one with AVX2
only. The test then computes the digests again in a child process narrowed that way
(:data:`NARROWED`) and holds them to the narrower set, so a set regenerated on an AVX2 machine
serves both.

Regenerate (only when a change of outputs is intended and explained in its commit; on every
numerics path at hand, and delete the sets of the paths that cannot be regenerated):
``SAFECASE_GOLDEN_WRITE=1 .venv/bin/python -m pytest tests/pipeline/test_perception_golden.py``
writes this machine's set.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import importlib
import json
import os
import platform
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.frames import to_child
from pipeline.perception import Perception, PerceptionChain
from pipeline.sources.logs.bags import read_bag
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.thermal import thermal_from_truth
from pipeline.sources.sim.truth import ScanTruth
from pipeline.training.data import RunSpec, run_rows
from pipeline.types import Frame, RadarDetections
from safety.geometry.path import PathAhead
from safety.model.freshness import is_fresh
from safety.runtime import CycleInput, CycleOutput, Runtime

DATA = Path(__file__).resolve().parents[1] / "data"
GOLDEN_DIR = DATA / "golden"
BAG = DATA / "leg_tracker" / "positive_1_extracted.bag"
RUNS = (
    ("reversing_forklift_aisle", 3, 8.0),
    ("crossing_pedestrian", 5, 8.0),
    ("dolly_train_turn", 2, 8.0),
)
TRAINING = (RunSpec("reversal_drill", 11, 10.0), RunSpec("forklift_pass_by", 4, 10.0))
NARROWED: dict[str, tuple[str, dict[str, str]]] = {
    "x86-64-avx512": (
        "x86-64-avx2",
        {
            "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR AVX512F AVX512CD "
            "AVX512_SKX AVX512_CLX AVX512_CNL",
            "OPENBLAS_CORETYPE": "Haswell",
        },
    ),
}
"""Per numerics path: the narrower path it can run, and the environment that makes it."""
PERCEPTION_FIELDS = (
    "points",
    "clusters",
    "tracks",
    "features",
    "classification",
    "fused",
    "predictions",
)


def _feed(h: Any, value: Any) -> None:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            h.update(f.name.encode())
            _feed(h, getattr(value, f.name))
    elif isinstance(value, np.ndarray):
        a = np.ascontiguousarray(value)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    elif isinstance(value, enum.Enum):
        h.update(repr(value.value).encode())
    elif isinstance(value, dict):
        for k in sorted(value, key=str):
            h.update(str(k).encode())
            _feed(h, value[k])
    elif isinstance(value, list | tuple):
        h.update(b"[")
        for v in value:
            _feed(h, v)
        h.update(b"]")
    elif isinstance(value, float):
        h.update(float(value).hex().encode())
    else:
        h.update(repr(value).encode())


def digest(value: Any) -> str:
    """SHA-256 (first 24 hex digits) of every field's dtype, shape and bytes."""
    h = hashlib.sha256()
    _feed(h, value)
    return h.hexdigest()[:24]


def _spied(rt: Runtime) -> dict[str, Any]:
    """Make ``rt``'s chain report each cycle's stage outputs into the returned dict."""
    seen: dict[str, Any] = {}
    perceive = rt.perception.perceive

    def spy(frame: Frame, **kw: Any) -> Any:
        out = perceive(frame, **kw)
        seen.update(
            points=out.points,
            clusters=out.clusters,
            tracks=out.tracked.tracks,
            features=out.features,
            classification=out.classification,
            fused=out.fused,
            predictions=out.predictions,
        )
        return out

    rt.perception = _Spy(rt.perception, spy)
    return seen


def _row(seen: dict[str, Any], out: CycleOutput, fusion: Counter[str]) -> dict[str, Any]:
    """One cycle's digests; ``fusion`` accumulates the cycle's fusion counts."""
    c = out.command
    row: dict[str, Any] = {k: digest(v) for k, v in seen.items()}
    row["command"] = [c.action.value, c.speed_mps.hex(), list(c.reasons)]
    row["inputs"] = digest(out.record.inputs)
    row["envelopes"] = digest(out.envelopes)
    row["distances"] = digest(out.distances)
    fusion.update(out.record.inputs.get("fusion", {}))
    return row


def _runtime_cycles(
    config: SafecaseConfig, name: str, seed: int, duration_s: float, fusion: Counter[str]
) -> list[dict[str, Any]]:
    """A closed-loop run with thermal detections (every 7th frame stale), digested."""
    sim = make_simulation(config, name, seed, duration_s)
    rt = Runtime(config)
    seen = _spied(rt)
    rng = np.random.default_rng(seed)
    route, rc = sim.ego_spec.route, config.runtime
    sim.command(sim.ego_spec.initial_speed_mps)
    busy = -np.inf
    rows: list[dict[str, Any]] = []
    i = -1
    while (frame := sim.next_frame()) is not None:
        i += 1
        seen.clear()
        delivered = max(frame.observation.stamp_s, busy)
        at = sim.ego.poses_at(np.array([frame.scan.stamp_s]))[0]
        path = PathAhead.along_polyline(
            route.points_m, sim.ego.arc_m, rc.path_lookahead_m, rc.path_step_m
        )
        out = rt.step(
            CycleInput(
                scan=frame.scan,
                now_s=delivered,
                robot_pose=(float(at[0]), float(at[1]), float(at[2])),
                path=path,
                thermal=thermal_from_truth(frame.truth, rng, delay_s=0.3 if i % 7 == 0 else 0.0),
                charge_s=rc.sim_cycle_s,
            )
        )
        busy = out.record.observation.now_s
        sim.ego.command(out.command.speed_mps, busy)
        rows.append(_row(seen, out, fusion))
    return rows


def _radar_from_truth(truth: ScanTruth) -> RadarDetections:
    """Radar returns of every object within 30 m of the robot: range, bearing, range rate."""
    pose = (float(truth.ego_pose[0]), float(truth.ego_pose[1]), float(truth.ego_pose[2]))
    x, y = to_child(pose, truth.x_m, truth.y_m)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    vx, vy = c * truth.vx_mps + s * truth.vy_mps, -s * truth.vx_mps + c * truth.vy_mps
    r = np.hypot(x, y)
    keep = r < 30.0
    x, y, vx, vy, r = x[keep], y[keep], vx[keep], vy[keep], r[keep]
    rate = (x * vx + y * vy) / np.maximum(r, 1e-9)
    return RadarDetections(np.full(r.shape[0], truth.stamp_s), r, np.arctan2(y, x), rate)


def _bench_cycles(config: SafecaseConfig, fusion: Counter[str]) -> list[dict[str, Any]]:
    """A robot standing on a test bench (robot frame tracking) with thermal and radar."""
    bench = overridden(config, {"sim": {"ego_speed_mps": 0.0}})
    sim = make_simulation(bench, "reversing_forklift_aisle", 8, 6.0)
    rt = Runtime(bench)
    seen = _spied(rt)
    rng = np.random.default_rng(8)
    rows: list[dict[str, Any]] = []
    sim.command(0.0)
    while (frame := sim.next_frame()) is not None:
        seen.clear()
        out = rt.step(
            CycleInput.standing(
                frame.scan,
                frame.observation.stamp_s,
                bench,
                charge_s=0.02,
                thermal=thermal_from_truth(frame.truth, rng, delay_s=0.0),
                radar=_radar_from_truth(frame.truth),
            )
        )
        rows.append(_row(seen, out, fusion))
    return rows


class _Spy:
    """A perception chain whose ``perceive`` goes through ``spy`` (everything else as is)."""

    def __init__(self, chain: PerceptionChain, spy: Any) -> None:
        self._chain = chain
        self.perceive = spy

    def reset(self) -> None:
        self._chain.reset()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._chain, name)


def _log_cycles(config: SafecaseConfig) -> list[dict[str, str]]:
    """The chain on a real bag (laser frame, no odometry): 150 scans, each stage digested."""
    chain = Perception.from_config(
        config, classifier=Classifier.from_config(config.classify), guard=is_fresh
    )
    rows = []
    for i, scan in enumerate(read_bag(BAG, "/training_scan")):
        if i >= 150:
            break
        p = chain.perceive(Frame(scan, scan.stamp_s))
        rows.append(
            {
                "points": digest(p.points),
                "clusters": digest(p.clusters),
                "tracks": digest(p.tracked.tracks),
                "features": digest(p.features),
                "classification": digest(p.classification),
            }
        )
    return rows


def _training(config: SafecaseConfig) -> dict[str, Any]:
    out = {}
    for spec in TRAINING:
        rows = run_rows(config, spec)
        arrays = [
            rows.features,
            rows.label,
            rows.stamp_s,
            rows.track_id,
            rows.object_id,
            rows.range_m,
        ]
        out[f"{spec.scenario}/{spec.seed}/{spec.duration_s}"] = {
            "n": rows.n,
            "digest": digest(arrays),
            "dropped": rows.dropped,
        }
    return out


def _compute(fusion: Counter[str]) -> dict[str, Any]:
    config = default_config()
    runtime = {f"{n}/{s}/{d}": _runtime_cycles(config, n, s, d, fusion) for n, s, d in RUNS}
    runtime["bench/reversing_forklift_aisle/8/6.0"] = _bench_cycles(config, fusion)
    return {
        "runtime": runtime,
        "training": _training(config),
        "log": {"positive_1_extracted.bag:/training_scan": _log_cycles(config)},
    }


def numerics_path() -> str:
    """The machine and the widest SIMD extension numpy dispatches to here (``x86-64-avx512``,
    ``x86-64-avx2``, ``aarch64-asimd``, ...): the golden sets' names."""
    features = importlib.import_module("numpy._core._multiarray_umath").__cpu_features__
    machine = platform.machine().lower().replace("_", "-").replace("amd64", "x86-64")
    for feature in ("AVX512_SKX", "AVX2", "SVE", "ASIMD", "VSX", "VX"):
        if features.get(feature):
            return f"{machine}-{feature.lower().split('_')[0]}"
    return machine


def compute_narrowed(env: dict[str, str], out: Path) -> Any:
    """The digests computed in a child process started with ``env`` added (written to ``out``,
    JSON), e.g. a narrower numerics path's (:data:`NARROWED`)."""
    root = Path(__file__).resolve().parents[2]
    child = {**os.environ, **env, "PYTHONPATH": str(root)}
    subprocess.run([sys.executable, __file__, str(out)], env=child, cwd=root, check=True)
    return json.loads(out.read_text())


def _first_difference(want: Any, got: Any, where: str = "") -> str | None:
    if isinstance(want, dict) and isinstance(got, dict):
        for key in sorted(set(want) | set(got)):
            diff = _first_difference(want.get(key), got.get(key), f"{where}/{key}")
            if diff:
                return diff
        return None
    if isinstance(want, list) and isinstance(got, list) and len(want) == len(got):
        for i, (w, g) in enumerate(zip(want, got, strict=True)):
            diff = _first_difference(w, g, f"{where}[{i}]")
            if diff:
                return diff
        return None
    return None if want == got else f"{where}: golden {want!r}, now {got!r}"


@pytest.mark.requirement(
    "SR-RUN-1", kind="example", code=["pipeline/perception.py", "safety/runtime.py"]
)
def test_the_chain_reproduces_the_golden_digests_bit_for_bit(tmp_path: Path) -> None:
    fusion: Counter[str] = Counter()
    got = _compute(fusion)
    # The runs exercise every fusion path: matched, thermal-only, stale, radar updates.
    for key in ("n_thermal_matched", "n_thermal_only", "n_thermal_stale", "n_radar_matched"):
        assert fusion[key] > 0, (key, dict(fusion))
    path = numerics_path()
    if os.environ.get("SAFECASE_GOLDEN_WRITE"):
        out = GOLDEN_DIR / f"perception.{path}.json"
        out.write_text(json.dumps(got, indent=0, sort_keys=True))
        pytest.skip(f"wrote {out}")
    sets = sorted(GOLDEN_DIR.glob("perception.*.json"))
    assert sets, f"no golden digests in {GOLDEN_DIR}"
    now = json.loads(json.dumps(got))
    differences = {s.name: _first_difference(json.loads(s.read_text()), now) for s in sets}
    narrower, env = NARROWED.get(path, ("", {}))
    recorded = GOLDEN_DIR / f"perception.{narrower}.json"
    if None not in differences.values() and recorded in sets:
        narrowed = compute_narrowed(env, tmp_path / "narrowed.json")
        name = f"{recorded.name} (numerics narrowed to {narrower})"
        differences[name] = _first_difference(json.loads(recorded.read_text()), narrowed)
    assert None in differences.values(), (
        f"this machine's numerics path is {path}; the outputs equal none of the recorded sets: "
        + "; ".join(f"{name}: {diff}" for name, diff in differences.items())
    )
    want = now
    assert sum(len(v) for v in want["runtime"].values()) == 300
    every_stage = set(PERCEPTION_FIELDS)
    assert all(every_stage <= set(row) for rows in want["runtime"].values() for row in rows)


if __name__ == "__main__":  # compute_narrowed's child: the digests to the file named
    Path(sys.argv[1]).write_text(json.dumps(_compute(Counter())))
