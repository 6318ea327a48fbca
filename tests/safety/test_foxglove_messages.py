"""What :class:`safety.foxglove.McapRecorder` writes, message by message and field by field
(SR-RUN-7): cycles built by hand are recorded and read back with rosbags' ``AnyReader``, and
every field of every topic is compared with values worked out here from the scene (stamps split
into sec/nanosec, quaternions checked through the rotation they stand for, the costmap cropped
by hand), including the edges: no scan, an empty or one-beam scan, no tracks, no envelopes,
unknown margin tiers, a free costmap, each command level. Also how the recorder handles its
file: refusing an existing one, assembling it beside the target, closing twice."""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeline.types import Action, Scan
from properties.cycle_scenes import empty_scene
from safety.foxglove import TOPICS, McapRecorder
from safety.foxglove_scene import CycleScene

CODE = ["safety/foxglove.py"]

# ROS message constants, spelled out so that a changed constant in the writer shows.
ARROW, CYLINDER, LINE_STRIP, TEXT_VIEW_FACING = 0, 3, 4, 9
ADD, DELETEALL = 0, 3
OK, WARN, ERROR = 0, 1, 2
FLOAT32 = 7

Messages = dict[str, list[tuple[int, Any]]]


def _f(values: Sequence[Sequence[float]] | Sequence[float]) -> np.ndarray[Any, Any]:
    return np.array(values, dtype=np.float64)


def _i(values: Sequence[int]) -> np.ndarray[Any, Any]:
    return np.array(values, dtype=np.int64)


def _occupied() -> np.ndarray[Any, np.dtype[np.bool_]]:
    """A 6 x 8 grid (rows along y) marked at (1, 2), (2, 4) and (3, 5)."""
    grid = np.zeros((6, 8), dtype=np.bool_)
    grid[1, 2] = grid[2, 4] = grid[3, 5] = True
    return grid


FULL = CycleScene(
    stamp_s=12.75,
    robot_pose=(1.5, -2.25, 0.6),
    mount=(0.3, -0.125, -0.4),
    scan=Scan(
        stamp_s=12.5,
        angles_rad=_f([-0.5, -0.25, 0.0, 0.25, 0.5]),
        ranges_m=_f([1.0, np.nan, 2.5, 3.25, 0.75]),
        beam_period_s=0.001,
    ),
    points_xy_m=_f([[1.0, 2.0, -0.5], [0.5, -1.5, 3.0]]),
    point_labels=_i([0, -1, 2]),
    track_id=_i([7, 11]),
    track_xy_m=_f([[2.0, -1.0], [3.0, 0.5]]),
    track_v_mps=_f([[0.6, -0.3], [0.8, 0.4]]),
    track_radius_m=_f([0.35, 0.5]),
    track_class=("person", ""),
    envelopes=(
        _f([[1.0, 0.0], [2.0, 0.0], [2.0, 1.0]]),
        _f([[-1.0, -1.0], [0.0, -1.0], [0.0, 0.0], [-1.0, 0.0]]),
        _f([[3.0, 3.0], [4.0, 3.0], [3.5, 4.0]]),
    ),
    envelope_tier=_i([0, 1, 2]),
    envelope_track=_i([7, 11, 7]),
    path_xy_m=_f([[0.0, 0.0], [0.5, 0.25], [1.0, 0.5]]),
    occupied=_occupied(),
    costmap_origin_m=(-2.0, -1.5),
    costmap_resolution_m=0.25,
    action=Action.SLOW,
    speed_mps=0.37,
    reasons=("obstacle 7 close", "scan late"),
    verdicts=(
        ("clock", Action.PROCEED, ""),
        ("scan_freshness", Action.SLOW, "stale by 0.2 s"),
        ("governor", Action.STOP, "too close"),
    ),
    record={"cycle": 3, "command": {"action": "SLOW", "speed_mps": 0.37}, "note": "ü"},
)

# A cycle that stopped before perception: nothing but the pose, the command and the verdicts.
BARE = empty_scene(stamp_s=13.0, verdicts=(("clock", Action.PROCEED, ""),))


def _record(path: Path, *scenes: CycleScene) -> Messages:
    with McapRecorder(path) as recorder:
        for scene in scenes:
            recorder.write(scene)
    return _read(path)


def _read(path: Path) -> Messages:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out: Messages = {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for connection, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            out.setdefault(connection.topic, []).append((stamp, msg))
    return out


def _only(messages: Messages, topic: str) -> Any:
    (entry,) = messages[topic]
    return entry[1]


# Per test, not per module: mutation testing credits the code a fixture runs to the test that
# set it up, so a module-scoped recording would be checked by its first test only.
@pytest.fixture
def full(tmp_path_factory: pytest.TempPathFactory) -> Messages:
    return _record(tmp_path_factory.mktemp("full") / "full.mcap", FULL)


def _stamp(header: Any, sec: int, nanosec: int, frame: str) -> None:
    assert (header.stamp.sec, header.stamp.nanosec, header.frame_id) == (sec, nanosec, frame)


def _turns_by(q: Any, yaw: float) -> None:
    """``q`` is a unit quaternion about z whose rotation matrix turns by ``yaw`` (written the
    short way round, w > 0, as ROS tools do for |yaw| < pi)."""
    assert (q.x, q.y) == (0.0, 0.0)
    assert q.x**2 + q.y**2 + q.z**2 + q.w**2 == pytest.approx(1.0)
    r00 = 1.0 - 2.0 * (q.y**2 + q.z**2)
    r10 = 2.0 * (q.x * q.y + q.z * q.w)
    assert (r00, r10) == pytest.approx((math.cos(yaw), math.sin(yaw)), abs=1e-12)
    assert q.w > 0.0


def _xyz(v: Any) -> tuple[float, float, float]:
    return (v.x, v.y, v.z)


def _rgba(c: Any) -> tuple[float, float, float, float]:
    return (c.r, c.g, c.b, c.a)


def _f32(*values: float) -> tuple[float, ...]:
    """What a float32 field reads back as."""
    return tuple(float(np.float32(v)) for v in values)


def _marker(
    m: Any,
    *,
    frame: str,
    ns: str,
    ident: int,
    kind: int,
    action: int = ADD,
    position: tuple[float, float] = (0.0, 0.0),
    scale: tuple[float, float, float] = (0.0, 0.0, 0.0),
    rgba: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
    points: Sequence[tuple[float, float]] = (),
    text: str = "",
    stamp: tuple[int, int] = (12, 750_000_000),
) -> None:
    """Every field of a marker: what it draws and every field it leaves at ROS's defaults."""
    _stamp(m.header, *stamp, frame)
    assert (m.ns, m.id, m.type, m.action) == (ns, ident, kind, action)
    assert _xyz(m.pose.position) == (*position, 0.0)
    assert (*_xyz(m.pose.orientation), m.pose.orientation.w) == (0.0, 0.0, 0.0, 1.0)
    assert _xyz(m.scale) == scale
    assert _rgba(m.color) == _f32(*rgba)
    assert [_xyz(p) for p in m.points] == [(x, y, 0.0) for x, y in points]
    assert m.text == text
    assert (m.lifetime.sec, m.lifetime.nanosec) == (0, 0)
    assert m.frame_locked is False
    assert list(m.colors) == []
    assert m.texture_resource == ""
    _stamp(m.texture.header, 0, 0, "")
    assert m.texture.format == ""
    assert np.asarray(m.texture.data).size == 0
    assert list(m.uv_coordinates) == []
    assert m.mesh_resource == ""
    assert m.mesh_file.filename == ""
    assert np.asarray(m.mesh_file.data).size == 0
    assert m.mesh_use_embedded_materials is False


def _cleared_first(array: Any, frame: str, stamp: tuple[int, int] = (12, 750_000_000)) -> list[Any]:
    """The DELETEALL marker that opens every array, checked whole; the markers after it."""
    clear, *rest = array.markers
    _marker(clear, frame=frame, ns="", ident=0, kind=ARROW, action=DELETEALL, stamp=stamp)
    return list(rest)


# -- the file ---------------------------------------------------------------------------------


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_every_topic_is_written_once_per_cycle_on_the_cycle_stamp(full: Messages) -> None:
    assert TOPICS == {
        "/tf": "tf2_msgs/msg/TFMessage",
        "/scan": "sensor_msgs/msg/LaserScan",
        "/perception/points": "sensor_msgs/msg/PointCloud2",
        "/perception/tracks": "visualization_msgs/msg/MarkerArray",
        "/safety/envelopes": "visualization_msgs/msg/MarkerArray",
        "/safety/path": "nav_msgs/msg/Path",
        "/safety/costmap": "nav_msgs/msg/OccupancyGrid",
        "/safety/command": "geometry_msgs/msg/TwistStamped",
        "/safety/verdicts": "diagnostic_msgs/msg/DiagnosticArray",
        "/safety/record": "std_msgs/msg/String",
    }
    assert sorted(full) == sorted(TOPICS)
    for topic, entries in full.items():
        assert [stamp for stamp, _ in entries] == [12_750_000_000], topic
        assert entries[0][1].__msgtype__ == TOPICS[topic]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_stamp_just_below_a_second_keeps_its_second_and_the_largest_nanosecond(
    tmp_path: Path,
) -> None:
    late = replace(BARE, stamp_s=2.9999999999)
    messages = _record(tmp_path / "late.mcap", late)
    assert [stamp for stamp, _ in messages["/safety/record"]] == [3_000_000_000]
    _stamp(_only(messages, "/safety/command").header, 2, 999_999_999, "base_link")
    whole = replace(BARE, stamp_s=7.0)
    messages = _record(tmp_path / "whole.mcap", whole)
    assert [stamp for stamp, _ in messages["/tf"]] == [7_000_000_000]
    _stamp(_only(messages, "/safety/command").header, 7, 0, "base_link")


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_cycles_follow_one_another_and_are_counted(tmp_path: Path) -> None:
    path = tmp_path / "two.mcap"
    with McapRecorder(path) as recorder:
        assert recorder.cycles == 0
        recorder.write(FULL)
        assert recorder.cycles == 1
        recorder.write(BARE)
        assert recorder.cycles == 2
    messages = _read(path)
    assert [s for s, _ in messages["/safety/record"]] == [12_750_000_000, 13_000_000_000]
    assert [json.loads(m.data) for _, m in messages["/safety/record"]] == [FULL.record, {}]
    # The bare cycle has no scan and no costmap: those topics hold the full cycle's only.
    assert [s for s, _ in messages["/scan"]] == [12_750_000_000]
    assert [s for s, _ in messages["/safety/costmap"]] == [12_750_000_000]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_an_existing_file_is_refused_and_left_alone(tmp_path: Path) -> None:
    path = tmp_path / "taken.mcap"
    path.write_bytes(b"keep me")
    with pytest.raises(FileExistsError) as refused:
        McapRecorder(path)
    assert str(refused.value) == f"{path}: exists; choose a new file for the recording"
    assert path.read_bytes() == b"keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.mcap"]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_file_is_assembled_in_a_hidden_folder_beside_it_and_appears_on_close(
    tmp_path: Path,
) -> None:
    path = tmp_path / "run.mcap"
    recorder = McapRecorder(path)
    recorder.write(BARE)
    (folder,) = tmp_path.iterdir()
    assert folder.is_dir()
    assert folder.name.startswith(".mcap-")
    assert not path.exists()
    recorder.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]
    recorder.close()  # closing again changes nothing
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]
    assert [json.loads(m.data) for _, m in _read(path)["/safety/record"]] == [{}]


# -- each topic -------------------------------------------------------------------------------


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_tf_places_the_robot_in_odom_and_the_scanner_on_the_robot(full: Messages) -> None:
    robot, laser = _only(full, "/tf").transforms
    _stamp(robot.header, 12, 750_000_000, "odom")
    assert robot.child_frame_id == "base_link"
    assert _xyz(robot.transform.translation) == (1.5, -2.25, 0.0)
    _turns_by(robot.transform.rotation, 0.6)
    _stamp(laser.header, 12, 750_000_000, "base_link")
    assert laser.child_frame_id == "laser"
    assert _xyz(laser.transform.translation) == (0.3, -0.125, 0.0)
    _turns_by(laser.transform.rotation, -0.4)


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_scan_keeps_its_own_stamp_angles_and_ranges_with_no_return_as_infinity(
    full: Messages,
) -> None:
    scan = _only(full, "/scan")
    _stamp(scan.header, 12, 500_000_000, "laser")
    assert (scan.angle_min, scan.angle_max, scan.angle_increment) == (-0.5, 0.5, 0.25)
    assert (scan.time_increment, scan.scan_time) == _f32(0.001, 0.004)
    assert (scan.range_min, scan.range_max) == (0.0, 3.25)
    ranges = np.asarray(scan.ranges)
    assert ranges.dtype == np.float32
    assert ranges.tolist() == [1.0, math.inf, 2.5, 3.25, 0.75]
    assert np.asarray(scan.intensities).size == 0


def _scan_of(tmp_path: Path, name: str, angles: list[float], ranges: list[float]) -> Any:
    scan = Scan(stamp_s=4.25, angles_rad=_f(angles), ranges_m=_f(ranges), beam_period_s=0.002)
    return _only(_record(tmp_path / f"{name}.mcap", replace(BARE, scan=scan)), "/scan")


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_an_empty_a_one_beam_a_two_beam_and_a_blind_scan_are_written_as_they_are(
    tmp_path: Path,
) -> None:
    empty = _scan_of(tmp_path, "empty", [], [])
    _stamp(empty.header, 4, 250_000_000, "laser")
    assert (empty.angle_min, empty.angle_max, empty.angle_increment) == (0.0, 0.0, 0.0)
    assert (empty.time_increment, empty.scan_time) == _f32(0.002, 0.0)
    assert (empty.range_min, empty.range_max) == (0.0, 0.0)
    assert np.asarray(empty.ranges).size == 0
    one = _scan_of(tmp_path, "one", [0.75], [0.5])
    assert (one.angle_min, one.angle_max, one.angle_increment) == (0.75, 0.75, 0.0)
    assert (one.time_increment, one.scan_time) == _f32(0.002, 0.0)
    assert (one.range_min, one.range_max) == (0.0, 0.5)
    assert np.asarray(one.ranges).tolist() == [0.5]
    two = _scan_of(tmp_path, "two", [0.25, 0.75], [0.5, 0.25])
    assert (two.angle_min, two.angle_max, two.angle_increment) == (0.25, 0.75, 0.5)
    assert (two.time_increment, two.scan_time) == _f32(0.002, 0.002)
    assert two.range_max == 0.5
    blind = _scan_of(tmp_path, "blind", [0.0, 0.5, 1.0], [np.nan, np.nan, np.nan])
    assert (blind.angle_increment, blind.scan_time) == _f32(0.5, 0.004)
    assert blind.range_max == 0.0
    assert np.asarray(blind.ranges).tolist() == [math.inf] * 3


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_every_beam_of_an_unevenly_spaced_scan_keeps_its_direction(tmp_path: Path) -> None:
    # Beams at 0.0 and 0.25 rad, then the frame holding 0.5 and 0.75 rad was dropped.
    angles = [0.0, 0.25, 1.0, 1.25]
    scan = _scan_of(tmp_path, "gap", angles, [1.0, 1.5, 2.0, 2.5])
    ranges = np.asarray(scan.ranges)
    # ROS reads beam i of a LaserScan at angle_min + i * angle_increment, up to angle_max.
    read = [scan.angle_min + i * scan.angle_increment for i in range(ranges.size)]
    finite = [(a, float(r)) for a, r in zip(read, ranges, strict=True) if math.isfinite(r)]
    assert finite == [(0.0, 1.0), (0.25, 1.5), (1.0, 2.0), (1.25, 2.5)]
    assert scan.angle_max == pytest.approx(read[-1])


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_clockwise_scan_and_a_scan_that_turns_back_are_written_beam_by_beam(
    tmp_path: Path,
) -> None:
    clockwise = _scan_of(tmp_path, "cw", [0.5, 0.25, 0.0], [1.0, 2.0, 3.0])
    assert (clockwise.angle_min, clockwise.angle_increment) == (0.5, -0.25)
    assert clockwise.angle_max == 0.0
    assert np.asarray(clockwise.ranges).tolist() == [1.0, 2.0, 3.0]
    # Two beams meeting one grid point: the nearer return is kept.
    close = _scan_of(tmp_path, "close", [0.0, 0.25, 0.5, 0.52], [4.0, 5.0, 6.0, 3.0])
    assert np.asarray(close.ranges).tolist() == [4.0, 5.0, 3.0]
    assert close.angle_max == 0.5  # the grid's last point, not the last beam's 0.52
    back = _scan_of(tmp_path, "back", [0.0, 0.25, 0.5, 0.1], [1.0, 2.0, 3.0, 4.0])
    assert (back.angle_min, back.angle_increment, back.angle_max) == (0.0, 0.25, 0.75)
    assert np.asarray(back.ranges).tolist() == [1.0, 2.0, 3.0, 4.0]
    # Most beams at one angle (a median spacing of 0): no grid to place them on.
    stuck = _scan_of(tmp_path, "stuck", [0.0, 0.0, 0.0, 0.25], [1.0, 2.0, 3.0, 4.0])
    assert (stuck.angle_min, stuck.angle_increment, stuck.angle_max) == (0.0, 0.0, 0.0)
    assert np.asarray(stuck.ranges).tolist() == [1.0, 2.0, 3.0, 4.0]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_cycle_without_a_scan_or_costmap_writes_neither(tmp_path: Path) -> None:
    messages = _record(tmp_path / "bare.mcap", BARE)
    assert sorted(messages) == sorted(set(TOPICS) - {"/scan", "/safety/costmap"})


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_point_cloud_holds_x_y_z_and_cluster_as_little_endian_float32(
    full: Messages, tmp_path: Path
) -> None:
    cloud = _only(full, "/perception/points")
    _stamp(cloud.header, 12, 750_000_000, "base_link")
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ("x", 0, FLOAT32, 1),
        ("y", 4, FLOAT32, 1),
        ("z", 8, FLOAT32, 1),
        ("cluster", 12, FLOAT32, 1),
    ]
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step) == (1, 3, 16, 48)
    assert cloud.is_bigendian is False
    assert cloud.is_dense is True
    expected = b"".join(
        struct.pack("<ffff", x, y, 0.0, label)
        for x, y, label in [(1.0, 0.5, 0), (2.0, -1.5, -1), (-0.5, 3.0, 2)]
    )
    assert bytes(np.asarray(cloud.data)) == expected
    none = _only(_record(tmp_path / "bare.mcap", BARE), "/perception/points")
    assert (none.height, none.width, none.row_step, len(none.fields)) == (1, 0, 0, 4)
    assert bytes(np.asarray(none.data)) == b""


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_each_track_is_a_body_disc_a_velocity_arrow_and_a_label(full: Messages) -> None:
    array = _only(full, "/perception/tracks")
    disc, arrow, label, disc2, arrow2, label2 = _cleared_first(array, "odom")
    blue, see_through = (0.2, 0.4, 0.9, 1.0), (0.2, 0.4, 0.9, 0.5)
    _marker(disc, frame="odom", ns="bodies", ident=7, kind=CYLINDER, position=(2.0, 3.0),
            scale=(0.7, 0.7, 0.1), rgba=see_through)  # fmt: skip
    _marker(arrow, frame="odom", ns="velocity", ident=7, kind=ARROW, scale=(0.05, 0.1, 0.1),
            rgba=blue, points=[(2.0, 3.0), (2.6, 3.8)])  # fmt: skip
    _marker(label, frame="odom", ns="labels", ident=7, kind=TEXT_VIEW_FACING,
            position=(2.0, 3.4), scale=(0.0, 0.0, 0.25), text="7 person 1.0 m/s")  # fmt: skip
    _marker(disc2, frame="odom", ns="bodies", ident=11, kind=CYLINDER, position=(-1.0, 0.5),
            scale=(1.0, 1.0, 0.1), rgba=see_through)  # fmt: skip
    _marker(arrow2, frame="odom", ns="velocity", ident=11, kind=ARROW, scale=(0.05, 0.1, 0.1),
            rgba=blue, points=[(-1.0, 0.5), (-1.3, 0.9)])  # fmt: skip
    _marker(label2, frame="odom", ns="labels", ident=11, kind=TEXT_VIEW_FACING,
            position=(-1.0, 0.9), scale=(0.0, 0.0, 0.25), text="11 unscored 0.5 m/s")  # fmt: skip


def _ring(outline: list[tuple[float, float]]) -> list[tuple[float, float]]:
    return [*outline, outline[0]]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_each_envelope_is_a_closed_outline_coloured_and_named_by_its_tier(
    full: Messages,
) -> None:
    array = _only(full, "/safety/envelopes")
    high, medium, near = _cleared_first(array, "base_link")
    _marker(high, frame="base_link", ns="envelope high", ident=0, kind=LINE_STRIP,
            scale=(0.03, 0.0, 0.0), rgba=(0.2, 0.7, 0.2, 0.9), text="track 7",
            points=_ring([(1.0, 0.0), (2.0, 0.0), (2.0, 1.0)]))  # fmt: skip
    _marker(medium, frame="base_link", ns="envelope medium", ident=1, kind=LINE_STRIP,
            scale=(0.03, 0.0, 0.0), rgba=(0.95, 0.6, 0.1, 0.9), text="track 11",
            points=_ring([(-1.0, -1.0), (0.0, -1.0), (0.0, 0.0), (-1.0, 0.0)]))  # fmt: skip
    _marker(near, frame="base_link", ns="envelope near_reversal", ident=2, kind=LINE_STRIP,
            scale=(0.03, 0.0, 0.0), rgba=(0.85, 0.1, 0.1, 0.9), text="track 7",
            points=_ring([(3.0, 3.0), (4.0, 3.0), (3.5, 4.0)]))  # fmt: skip


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_an_unknown_tier_is_named_by_its_number_and_coloured_like_the_nearest_known_one(
    tmp_path: Path,
) -> None:
    square = _f([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    scene = replace(FULL, envelopes=(square, square), envelope_tier=_i([3, -1]),
                    envelope_track=_i([4, 5]))  # fmt: skip
    array = _only(_record(tmp_path / "tiers.mcap", scene), "/safety/envelopes")
    above, below = _cleared_first(array, "base_link")
    ring = _ring([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
    _marker(above, frame="base_link", ns="envelope tier 3", ident=0, kind=LINE_STRIP,
            scale=(0.03, 0.0, 0.0), rgba=(0.85, 0.1, 0.1, 0.9), text="track 4",
            points=ring)  # fmt: skip
    _marker(below, frame="base_link", ns="envelope tier -1", ident=1, kind=LINE_STRIP,
            scale=(0.03, 0.0, 0.0), rgba=(0.2, 0.7, 0.2, 0.9), text="track 5",
            points=ring)  # fmt: skip


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_cycle_without_tracks_or_envelopes_only_clears_the_markers(tmp_path: Path) -> None:
    messages = _record(tmp_path / "bare.mcap", BARE)
    for topic, frame in (("/perception/tracks", "odom"), ("/safety/envelopes", "base_link")):
        assert _cleared_first(_only(messages, topic), frame, stamp=(13, 0)) == []


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_path_is_a_list_of_poses_in_odom(full: Messages, tmp_path: Path) -> None:
    path = _only(full, "/safety/path")
    _stamp(path.header, 12, 750_000_000, "odom")
    for pose, xy in zip(path.poses, [(0.0, 0.0), (0.5, 0.25), (1.0, 0.5)], strict=True):
        _stamp(pose.header, 12, 750_000_000, "odom")
        assert _xyz(pose.pose.position) == (*xy, 0.0)
        _turns_by(pose.pose.orientation, 0.0)
    assert list(_only(_record(tmp_path / "bare.mcap", BARE), "/safety/path").poses) == []


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_costmap_is_cropped_to_its_marked_cells_with_the_origin_moved_along(
    full: Messages,
) -> None:
    grid = _only(full, "/safety/costmap")
    _stamp(grid.header, 12, 750_000_000, "base_link")
    info = grid.info
    assert (info.map_load_time.sec, info.map_load_time.nanosec) == (12, 750_000_000)
    # Marked rows 1..3 and columns 2..5 of the 6 x 8 grid: 3 rows of 4 cells from cell (1, 2),
    # whose corner is 2 cells right of and 1 cell above the grid's origin (-2.0, -1.5).
    assert (info.resolution, info.width, info.height) == (0.25, 4, 3)
    assert _xyz(info.origin.position) == (-1.5, -1.25, 0.0)
    _turns_by(info.origin.orientation, 0.0)
    data = np.asarray(grid.data)
    assert data.dtype == np.int8
    assert data.tolist() == [100, 0, 0, 0, 0, 0, 100, 0, 0, 0, 0, 100]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_costmap_without_marks_is_one_free_cell_at_the_grid_origin(tmp_path: Path) -> None:
    free = replace(BARE, occupied=np.zeros((3, 5), dtype=np.bool_), costmap_origin_m=(0.5, 0.75),
                   costmap_resolution_m=0.125)  # fmt: skip
    grid = _only(_record(tmp_path / "free.mcap", free), "/safety/costmap")
    assert (grid.info.resolution, grid.info.width, grid.info.height) == (0.125, 1, 1)
    assert _xyz(grid.info.origin.position) == (0.5, 0.75, 0.0)
    assert np.asarray(grid.data).tolist() == [0]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_costmap_marked_in_its_last_row_and_column_is_cropped_to_that_corner(
    tmp_path: Path,
) -> None:
    occupied = np.zeros((4, 3), dtype=np.bool_)
    occupied[3, 2] = occupied[2, 1] = True
    corner = replace(BARE, occupied=occupied, costmap_origin_m=(1.0, 2.0),
                     costmap_resolution_m=0.5)  # fmt: skip
    grid = _only(_record(tmp_path / "corner.mcap", corner), "/safety/costmap")
    assert (grid.info.width, grid.info.height) == (2, 2)
    assert _xyz(grid.info.origin.position) == (1.5, 3.0, 0.0)
    assert np.asarray(grid.data).tolist() == [100, 0, 0, 100]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_command_is_the_speed_limit_straight_ahead(full: Messages) -> None:
    command = _only(full, "/safety/command")
    _stamp(command.header, 12, 750_000_000, "base_link")
    assert _xyz(command.twist.linear) == (0.37, 0.0, 0.0)
    assert _xyz(command.twist.angular) == (0.0, 0.0, 0.0)


def _statuses(array: Any) -> list[tuple[int, str, str, str, list[tuple[str, str]]]]:
    return [
        (s.level, s.name, s.message, s.hardware_id, [(v.key, v.value) for v in s.values])
        for s in array.status
    ]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_verdicts_are_one_status_per_monitor_after_the_command_ok_warn_error(
    full: Messages, tmp_path: Path
) -> None:
    array = _only(full, "/safety/verdicts")
    _stamp(array.header, 12, 750_000_000, "base_link")
    assert _statuses(array) == [
        (WARN, "command", "SLOW 0.37 m/s", "safecase",
         [("reason", "obstacle 7 close"), ("reason", "scan late")]),
        (OK, "clock", "PROCEED", "safecase", []),
        (WARN, "scan_freshness", "stale by 0.2 s", "safecase", []),
        (ERROR, "governor", "too close", "safecase", []),
    ]  # fmt: skip
    stop = replace(BARE, action=Action.STOP, speed_mps=0.0, reasons=("stale scan",))
    stopped = _only(_record(tmp_path / "stop.mcap", stop), "/safety/verdicts")
    assert _statuses(stopped)[0] == (ERROR, "command", "STOP 0.00 m/s", "safecase",
                                     [("reason", "stale scan")])  # fmt: skip
    go = _only(_record(tmp_path / "go.mcap", BARE), "/safety/verdicts")
    assert _statuses(go) == [
        (OK, "command", "PROCEED 1.00 m/s", "safecase", []),
        (OK, "clock", "PROCEED", "safecase", []),
    ]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_record_is_the_cycle_body_as_json(full: Messages) -> None:
    text = _only(full, "/safety/record").data
    assert text == json.dumps(FULL.record)
    assert json.loads(text) == FULL.record
