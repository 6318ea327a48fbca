"""Labelled simulator data for training and evaluation, as one ``.npz`` file (format v1).

Written by ``safecase sim dataset`` (:func:`write_dataset`), read by :func:`load_dataset`.
All runs of a file share one scanner layout. Arrays (``F`` frames, ``B`` beams, ``R`` object
rows = one per object per frame):

================  ========  ======================================================================
key               shape     meaning
================  ========  ======================================================================
format            ()        the string ``safecase-sim-dataset``
version           ()        1
meta_json         ()        JSON: runs (scenario, seed, frames, ego braking, contact), class and
                            kind names, scanner spec, label rules, config hash, safecase version
angles_rad        (B,)      beam angles in the scanner frame
frame_run         (F,)      index into ``meta.runs``
frame_stamp_s     (F,)      scan stamp (time of the first beam)
scanner_pose      (F, 3)    scanner x, y, yaw in the world at the stamp
ego_pose          (F, 3)    robot x, y, heading; ``ego_speed_mps`` (F,) its speed
ranges_m          (F, B)    measured ranges (float32, NaN = no return)
true_range_m      (F, B)    exact geometric ranges (float32, inf = nothing in range)
beam_owner        (F, B)    object id hit, -2 static structure, -1 nothing (int32)
beam_mixed        (F, B)    mixed-pixel return (bool); ``beam_dropout`` (F, B) random dropout
obj_frame         (R,)      index into the frames
obj_id            (R,)      object id (unique within its run)
obj_kind          (R,)      index into ``meta.kind_names`` (the object model)
obj_label         (R,)      index into ``meta.class_names`` (forklift states included)
obj_x_m, obj_y_m  (R,)      world position of the body centre; ``obj_heading_rad``,
                            ``obj_speed_mps`` (signed, along the heading), ``obj_vx_mps``,
                            ``obj_vy_mps``, ``obj_accel_mps2``
obj_sx_m, obj_sy_m (R,)     the same position in the scanner frame at the stamp
obj_length_m      (R,)      nominal bounding-box length / ``obj_width_m`` width of the outline
obj_n_returns     (R,)      beams of that frame that returned from this object
================  ========  ======================================================================

Later stages may add keys (e.g. per-track features); readers must ignore keys they do not know
and refuse a ``version`` they do not know.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.config import SafecaseConfig, config_hash
from pipeline.errors import SafecaseError
from pipeline.frames import to_child
from pipeline.sources.sim.ego import ConstantSpeed
from pipeline.sources.sim.scenarios import lidar_spec_from_config, make_simulation
from pipeline.sources.sim.simulation import SimResult
from pipeline.sources.sim.truth import CLASS_NAMES, KIND_NAMES, LabelRules

__all__ = ["DATASET_FORMAT", "DATASET_VERSION", "DatasetError", "load_dataset", "write_dataset"]

DATASET_FORMAT = "safecase-sim-dataset"
DATASET_VERSION = 1


class DatasetError(SafecaseError):
    """A dataset file that is missing, of another format or of an unknown version."""


def _arrays(results: Sequence[SimResult]) -> dict[str, np.ndarray]:
    cols: dict[str, list[Any]] = {
        k: []
        for k in (
            "frame_run",
            "frame_stamp_s",
            "scanner_pose",
            "ego_pose",
            "ego_speed_mps",
            "ranges_m",
            "true_range_m",
            "beam_owner",
            "beam_mixed",
            "beam_dropout",
            "obj_frame",
            "obj_id",
            "obj_kind",
            "obj_label",
            "obj_x_m",
            "obj_y_m",
            "obj_heading_rad",
            "obj_speed_mps",
            "obj_vx_mps",
            "obj_vy_mps",
            "obj_accel_mps2",
            "obj_sx_m",
            "obj_sy_m",
            "obj_length_m",
            "obj_width_m",
            "obj_n_returns",
        )
    }
    f_index = 0
    for r_index, result in enumerate(results):
        for frame in result.frames:
            tr = frame.truth
            cols["frame_run"].append(r_index)
            cols["frame_stamp_s"].append(tr.stamp_s)
            cols["scanner_pose"].append(tr.scanner_pose)
            cols["ego_pose"].append(tr.ego_pose)
            cols["ego_speed_mps"].append(tr.ego_speed_mps)
            cols["ranges_m"].append(frame.scan.ranges_m.astype(np.float32))
            cols["true_range_m"].append(tr.beams.true_range_m.astype(np.float32))
            cols["beam_owner"].append(tr.beams.owner_id.astype(np.int32))
            cols["beam_mixed"].append(tr.beams.mixed)
            cols["beam_dropout"].append(tr.beams.dropout)
            n = tr.object_id.shape[0]
            in_scanner = to_child(
                (tr.scanner_pose[0], tr.scanner_pose[1], tr.scanner_pose[2]), tr.x_m, tr.y_m
            )
            cols["obj_frame"].append(np.full(n, f_index))
            cols["obj_id"].append(tr.object_id)
            cols["obj_kind"].append(tr.kind)
            cols["obj_label"].append(tr.label)
            for key, value in (
                ("obj_x_m", tr.x_m),
                ("obj_y_m", tr.y_m),
                ("obj_heading_rad", tr.heading_rad),
                ("obj_speed_mps", tr.speed_mps),
                ("obj_vx_mps", tr.vx_mps),
                ("obj_vy_mps", tr.vy_mps),
                ("obj_accel_mps2", tr.accel_mps2),
                ("obj_length_m", tr.length_m),
                ("obj_width_m", tr.width_m),
                ("obj_n_returns", tr.n_returns),
            ):
                cols[key].append(value)
            cols["obj_sx_m"].append(in_scanner[0])
            cols["obj_sy_m"].append(in_scanner[1])
            f_index += 1
    stacked = {
        k: np.stack(cols[k])
        for k in (
            "scanner_pose",
            "ego_pose",
            "ranges_m",
            "true_range_m",
            "beam_owner",
            "beam_mixed",
            "beam_dropout",
        )
    }
    out: dict[str, np.ndarray] = {
        "frame_run": np.array(cols["frame_run"], dtype=np.int32),
        "frame_stamp_s": np.array(cols["frame_stamp_s"]),
        "ego_speed_mps": np.array(cols["ego_speed_mps"]),
        **stacked,
    }
    int_keys = {
        "obj_frame": np.int32,
        "obj_id": np.int32,
        "obj_kind": np.int8,
        "obj_label": np.int8,
        "obj_n_returns": np.int32,
    }
    for key in cols:
        if key.startswith("obj_"):
            out[key] = np.concatenate(cols[key]).astype(int_keys.get(key, np.float64))
    return out


def write_dataset(
    path: Path,
    config: SafecaseConfig,
    scenarios: Sequence[str],
    seeds: Sequence[int],
    duration_s: float | None = None,
) -> dict[str, Any]:
    """Run every scenario with every seed (constant configured speed) and write the file.

    Returns the metadata written.
    """
    results: list[SimResult] = []
    for name in scenarios:
        for seed in seeds:
            sim = make_simulation(config, name, seed, duration_s)
            results.append(sim.run(ConstantSpeed(config.sim.ego_speed_mps)))
    spec = lidar_spec_from_config(config)
    meta = {
        "format": DATASET_FORMAT,
        "version": DATASET_VERSION,
        "safecase_version": metadata.version("safecase"),
        "config_hash": config_hash(config),
        "class_names": list(CLASS_NAMES),
        "kind_names": list(KIND_NAMES),
        "label_rules": asdict(LabelRules.from_config(config.sim)),
        "lidar": {k: getattr(spec, k) for k in spec.__slots__},
        "runs": [
            {
                "scenario": r.name,
                "seed": r.seed,
                "frames": len(r.frames),
                "ego_decel_mps2": r.decel_mps2,
                "contact": r.contact,
                "objects": [o.name for o in r.world.objects],
            }
            for r in results
        ],
    }
    arrays = _arrays(results)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays["format"] = np.array(DATASET_FORMAT)
    arrays["version"] = np.array(DATASET_VERSION)
    arrays["meta_json"] = np.array(json.dumps(meta, sort_keys=True))
    arrays["angles_rad"] = spec.angles_rad
    with path.open("wb") as fh:
        np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]
    return meta


def load_dataset(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a dataset file: ``(meta, arrays)``; raises :class:`DatasetError` if it is not one
    this version can read."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: cannot read as an .npz dataset: {exc}") from None
    fmt = str(arrays.get("format", ""))
    if fmt != DATASET_FORMAT:
        raise DatasetError(f"{path}: format {fmt!r}, expected {DATASET_FORMAT!r}")
    version = int(arrays["version"])
    if version != DATASET_VERSION:
        raise DatasetError(f"{path}: version {version}, this reader knows {DATASET_VERSION}")
    meta = json.loads(str(arrays.pop("meta_json")))
    return meta, arrays
