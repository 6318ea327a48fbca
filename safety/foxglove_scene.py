"""What one runtime cycle shows in a recording: :class:`CycleScene` and :func:`scene_of`
(SR-RUN-7; written by :mod:`safety.foxglove`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.types import Action, FloatArray, IntArray, Scan
from safety.runtime import CycleOutput

__all__ = ["CycleScene", "scene_of"]


@dataclass(frozen=True)
class CycleScene:
    """What one cycle shows. Poses are (x_m, y_m, yaw_rad); ``robot_pose`` and the tracks and
    path are in the tracking frame (odom), points, envelopes and costmap in the robot frame
    (base_link), the scan in the scanner's frame (laser, at ``mount`` on the robot).

    ``points_xy_m`` (2, P) with ``point_labels`` (P,) (-1 loose); tracks ``track_xy_m`` and
    ``track_v_mps`` (2, T), ``track_id`` (T,), ``track_radius_m`` (T,), ``track_class`` (T
    names, "" unscored); envelopes as a list of (K, 2) outlines with their ``envelope_tier``
    and ``envelope_track``; the costmap's ``occupied`` (rows along y) with its origin and
    resolution; the command, the verdicts (monitor, action, reason) and the audit ``record``
    body."""

    stamp_s: float
    robot_pose: tuple[float, float, float]
    mount: tuple[float, float, float]
    scan: Scan | None
    points_xy_m: FloatArray
    point_labels: IntArray
    track_id: IntArray
    track_xy_m: FloatArray
    track_v_mps: FloatArray
    track_radius_m: FloatArray
    track_class: tuple[str, ...]
    envelopes: tuple[FloatArray, ...]
    envelope_tier: IntArray
    envelope_track: IntArray
    path_xy_m: FloatArray
    occupied: np.ndarray[Any, np.dtype[np.bool_]] | None
    costmap_origin_m: tuple[float, float]
    costmap_resolution_m: float
    action: Action
    speed_mps: float
    reasons: tuple[str, ...]
    verdicts: tuple[tuple[str, Action, str], ...]
    record: dict[str, Any]


def scene_of(out: CycleOutput, config: SafecaseConfig) -> CycleScene:
    """What :class:`McapRecorder` writes of one runtime cycle (its :class:`CycleDetail`;
    a cycle that stopped before a stage shows nothing of it)."""
    empty_f, empty_i = np.zeros((2, 0)), np.zeros(0, dtype=np.int64)
    detail = out.detail
    inp = None if detail is None else detail.inp
    perceived = None if detail is None else detail.perceived
    points, labels = empty_f, empty_i
    ids, xy, v, radius = empty_i, empty_f, empty_f, np.zeros(0)
    names: tuple[str, ...] = ()
    if perceived is not None:
        points = np.vstack([perceived.points.x_m, perceived.points.y_m])
        labels = perceived.clusters.point_labels
        tracks = perceived.fused.tracks
        ids = tracks.track_id
        xy, v = tracks.state[:, :2].T, tracks.state[:, 2:4].T
        pred = perceived.predictions
        by_id = dict(zip(pred.track_id.tolist(), pred.body_radius_m.tolist(), strict=True))
        radius = np.array([by_id.get(i, 0.2) for i in ids.tolist()])
        cls = perceived.classification
        chosen = dict(zip(cls.track_id.tolist(), cls.class_index.tolist(), strict=True))
        names = tuple(
            cls.class_names[chosen[i]] if chosen.get(i, -1) >= 0 else "" for i in ids.tolist()
        )
    outlines: tuple[FloatArray, ...] = ()
    tiers = tracks_of = empty_i
    if out.envelopes is not None:
        polys = out.envelopes.polygons
        outlines = tuple(polys.vertices_m[:, : int(polys.counts[n]), n].T for n in range(polys.n))
        tiers, tracks_of = out.envelopes.tier, out.envelopes.track_id
    grid = None if detail is None else detail.costmap
    mount = config.scan
    path = np.zeros((0, 2)) if inp is None else np.column_stack([inp.path.x_m, inp.path.y_m])
    record = out.record
    return CycleScene(
        stamp_s=record.observation.now_s,
        robot_pose=(0.0, 0.0, 0.0) if inp is None else inp.robot_pose,
        mount=(mount.mount_x_m, mount.mount_y_m, mount.mount_yaw_rad),
        scan=None if inp is None else inp.scan,
        points_xy_m=points,
        point_labels=labels,
        track_id=ids,
        track_xy_m=xy,
        track_v_mps=v,
        track_radius_m=radius,
        track_class=names,
        envelopes=outlines,
        envelope_tier=tiers,
        envelope_track=tracks_of,
        path_xy_m=path,
        occupied=None if grid is None else grid.occupied,
        costmap_origin_m=(0.0, 0.0) if grid is None else (grid.origin_x_m, grid.origin_y_m),
        costmap_resolution_m=1.0 if grid is None else grid.resolution_m,
        action=out.command.action,
        speed_mps=out.command.speed_mps,
        reasons=tuple(out.command.reasons),
        verdicts=tuple((v.monitor, v.action, v.reason) for v in out.decision.verdicts),
        record=record.body(),
    )
