"""What :func:`safety.foxglove_scene.scene_of` takes from one runtime cycle (SR-RUN-7): the
cycles of a short simulated run, whole and cut short (no detail, no perception, no envelopes,
no costmap), each field compared with the cycle's own objects read element by element; tracks
without a prediction or a class; and prediction or class tables whose columns disagree."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from pipeline.config import SafecaseConfig, default_config
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from safety.foxglove_scene import CycleScene, scene_of
from safety.run import run_audited
from safety.runtime import CycleOutput

CODE = ["safety/foxglove_scene.py"]


@pytest.fixture(scope="module")
def mounted() -> SafecaseConfig:
    """The default configuration with the scanner off the robot's centre (x, y, yaw all
    different), so that each part of the mount shows."""
    config = default_config()
    scan = config.scan.model_copy(
        update={"mount_x_m": 0.25, "mount_y_m": -0.125, "mount_yaw_rad": 0.5}
    )
    return config.model_copy(update={"scan": scan})


@pytest.fixture(scope="module")
def outs() -> list[CycleOutput]:
    config = default_config()
    sim = make_simulation(config, "reversing_forklift_aisle", 1, 0.5)
    return list(run_audited(config, SimSource(sim), audit_path=None))


@pytest.fixture(scope="module")
def out(outs: list[CycleOutput]) -> CycleOutput:
    """The third cycle: the robot has moved, and its tracks include scored ones (one of class
    index 0) and unscored ones, and envelopes of every margin tier."""
    chosen = outs[2]
    assert chosen.detail is not None
    assert chosen.detail.perceived is not None
    assert chosen.envelopes is not None
    classes = chosen.detail.perceived.classification.class_index.tolist()
    assert 0 in classes
    assert -1 in classes
    assert set(chosen.envelopes.tier.tolist()) == {0, 1, 2}
    assert chosen.detail.inp.robot_pose[0] > 0.0
    return chosen


def _same(actual: np.ndarray[Any, Any], expected: list[Any], dtype: type) -> None:
    assert actual.dtype == dtype
    assert actual.tolist() == expected


def _command_and_record(scene: CycleScene, out: CycleOutput) -> None:
    assert scene.stamp_s == out.record.observation.now_s
    assert scene.action is out.command.action
    assert scene.speed_mps == out.command.speed_mps
    assert scene.reasons == tuple(out.command.reasons)
    assert scene.verdicts == tuple((v.monitor, v.action, v.reason) for v in out.decision.verdicts)
    assert scene.record == out.record.body()


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_whole_cycle_shows_what_its_stages_read_and_built(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    scene = scene_of(out, mounted)
    detail, envelopes = out.detail, out.envelopes
    assert detail is not None
    assert envelopes is not None
    perceived = detail.perceived
    assert perceived is not None
    assert detail.costmap is not None
    assert scene.robot_pose == detail.inp.robot_pose
    assert scene.mount == (0.25, -0.125, 0.5)
    assert scene.scan is detail.inp.scan
    points = perceived.points
    _same(scene.points_xy_m, [points.x_m.tolist(), points.y_m.tolist()], np.float64)
    _same(scene.point_labels, perceived.clusters.point_labels.tolist(), np.int64)
    tracks = perceived.fused.tracks
    _same(scene.track_id, tracks.track_id.tolist(), np.int64)
    # state rows are (x, y, vx, vy, ...): positions and velocities one column per track
    _same(scene.track_xy_m, [tracks.state[:, 0].tolist(), tracks.state[:, 1].tolist()],
          np.float64)  # fmt: skip
    _same(scene.track_v_mps, [tracks.state[:, 2].tolist(), tracks.state[:, 3].tolist()],
          np.float64)  # fmt: skip
    pred = perceived.predictions
    radius = {int(t): float(r) for t, r in zip(pred.track_id, pred.body_radius_m, strict=True)}
    _same(scene.track_radius_m, [radius[int(t)] for t in tracks.track_id], np.float64)
    cls = perceived.classification
    index = {int(t): int(c) for t, c in zip(cls.track_id, cls.class_index, strict=True)}
    names = [cls.class_names[index[int(t)]] if index[int(t)] != -1 else "" for t in tracks.track_id]
    assert scene.track_class == tuple(names)
    assert "forklift_moving" in names  # class index 0
    assert "" in names
    polys = envelopes.polygons
    assert len(scene.envelopes) == polys.n == envelopes.tier.shape[0]
    for n, outline in enumerate(scene.envelopes):
        k = int(polys.counts[n])
        expected = [[polys.vertices_m[0, i, n], polys.vertices_m[1, i, n]] for i in range(k)]
        _same(outline, expected, np.float64)
    assert len({outline.shape[0] for outline in scene.envelopes}) > 1  # counts differ
    _same(scene.envelope_tier, envelopes.tier.tolist(), np.int64)
    _same(scene.envelope_track, envelopes.track_id.tolist(), np.int64)
    path = detail.inp.path
    _same(scene.path_xy_m, [[x, y] for x, y in zip(path.x_m, path.y_m, strict=True)], np.float64)
    assert scene.occupied is not None
    assert scene.occupied.tolist() == detail.costmap.occupied.tolist()
    assert scene.costmap_origin_m == (detail.costmap.origin_x_m, detail.costmap.origin_y_m)
    assert scene.costmap_resolution_m == detail.costmap.resolution_m == 0.05
    _command_and_record(scene, out)


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_cycle_without_detail_shows_only_its_command_verdicts_and_record(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    scene = scene_of(replace(out, detail=None, envelopes=None), mounted)
    assert scene.robot_pose == (0.0, 0.0, 0.0)
    assert scene.mount == (0.25, -0.125, 0.5)
    assert scene.scan is None
    assert scene.points_xy_m.shape == (2, 0)
    _same(scene.points_xy_m, [[], []], np.float64)
    _same(scene.point_labels, [], np.int64)
    _same(scene.track_id, [], np.int64)
    assert scene.track_xy_m.shape == scene.track_v_mps.shape == (2, 0)
    _same(scene.track_xy_m, [[], []], np.float64)
    _same(scene.track_v_mps, [[], []], np.float64)
    _same(scene.track_radius_m, [], np.float64)
    assert scene.track_class == ()
    assert scene.envelopes == ()
    _same(scene.envelope_tier, [], np.int64)
    _same(scene.envelope_track, [], np.int64)
    assert scene.path_xy_m.shape == (0, 2)
    assert scene.path_xy_m.dtype == np.float64
    assert scene.occupied is None
    assert scene.costmap_origin_m == (0.0, 0.0)
    assert scene.costmap_resolution_m == 1.0
    _command_and_record(scene, out)


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_cycle_that_stopped_before_perception_shows_its_scan_pose_and_path(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    detail = out.detail
    assert detail is not None
    cut = replace(out, detail=replace(detail, perceived=None, costmap=None), envelopes=None)
    scene = scene_of(cut, mounted)
    assert scene.robot_pose == detail.inp.robot_pose
    assert scene.scan is detail.inp.scan
    path = detail.inp.path
    _same(scene.path_xy_m, [[x, y] for x, y in zip(path.x_m, path.y_m, strict=True)], np.float64)
    _same(scene.points_xy_m, [[], []], np.float64)
    _same(scene.point_labels, [], np.int64)
    _same(scene.track_id, [], np.int64)
    _same(scene.track_radius_m, [], np.float64)
    assert scene.track_class == ()
    assert scene.envelopes == ()
    _same(scene.envelope_tier, [], np.int64)
    assert scene.occupied is None
    assert (scene.costmap_origin_m, scene.costmap_resolution_m) == ((0.0, 0.0), 1.0)
    _command_and_record(scene, out)


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_cycle_without_envelopes_still_shows_its_tracks_and_costmap(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    scene = scene_of(replace(out, envelopes=None), mounted)
    assert scene.envelopes == ()
    _same(scene.envelope_tier, [], np.int64)
    _same(scene.envelope_track, [], np.int64)
    assert out.detail is not None
    assert out.detail.perceived is not None
    assert scene.track_id.tolist() == out.detail.perceived.fused.tracks.track_id.tolist()
    assert scene.occupied is not None


def _perceived(out: CycleOutput) -> Any:
    assert out.detail is not None
    assert out.detail.perceived is not None
    return out.detail.perceived


def _with_perceived(out: CycleOutput, perceived: Any) -> CycleOutput:
    assert out.detail is not None
    return replace(out, detail=replace(out.detail, perceived=perceived))


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_track_without_a_prediction_gets_a_20_cm_body(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    perceived = _perceived(out)
    pred = perceived.predictions
    first = int(perceived.fused.tracks.track_id[0])
    ids = [10_000 if int(t) == first else int(t) for t in pred.track_id]
    orphan = replace(perceived, predictions=replace(pred, track_id=np.array(ids)))
    scene = scene_of(_with_perceived(out, orphan), mounted)
    radius = {int(t): float(r) for t, r in zip(pred.track_id, pred.body_radius_m, strict=True)}
    assert scene.track_radius_m.tolist() == [
        0.2 if int(t) == first else radius[int(t)] for t in scene.track_id
    ]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_track_the_classifier_has_no_row_for_has_no_class_name(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    perceived = _perceived(out)
    cls = perceived.classification
    scored = [int(t) for t, c in zip(cls.track_id, cls.class_index, strict=True) if c >= 0]
    gone = scored[0]
    ids = [10_000 if int(t) == gone else int(t) for t in cls.track_id]
    missing = replace(perceived, classification=replace(cls, track_id=np.array(ids)))
    scene = scene_of(_with_perceived(out, missing), mounted)
    whole = scene_of(out, mounted)
    position = scene.track_id.tolist().index(gone)
    assert whole.track_class[position] != ""
    assert scene.track_class == (
        *whole.track_class[:position],
        "",
        *whole.track_class[position + 1 :],
    )


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_prediction_or_class_tables_whose_columns_disagree_are_refused(
    out: CycleOutput, mounted: SafecaseConfig
) -> None:
    perceived = _perceived(out)
    # Past the tables' own checks (object.__setattr__ on a copy): one radius or class short.
    pred = replace(perceived.predictions)
    object.__setattr__(pred, "body_radius_m", pred.body_radius_m[:-1])
    with pytest.raises(ValueError):
        scene_of(_with_perceived(out, replace(perceived, predictions=pred)), mounted)
    cls = replace(perceived.classification)
    object.__setattr__(cls, "class_index", cls.class_index[:-1])
    with pytest.raises(ValueError):
        scene_of(_with_perceived(out, replace(perceived, classification=cls)), mounted)
