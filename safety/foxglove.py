"""A run as an MCAP file Foxglove replays: ROS 2 messages for every cycle (SR-RUN-7).

:class:`McapRecorder` writes, per cycle, on the decision's stamp:

============================ ========================================= ==============
topic                        message                                   frame
============================ ========================================= ==============
``/tf``                      odom -> base_link (the robot's pose),     odom, base_link
                             base_link -> laser (the scanner's mount)
``/scan``                    ``sensor_msgs/LaserScan``                 laser
``/perception/points``       ``sensor_msgs/PointCloud2``: the scan's   base_link
                             points, field ``cluster`` (-1 loose)
``/perception/tracks``       ``MarkerArray``: body disc, velocity      odom
                             arrow, "id class speed" label
``/safety/envelopes``        ``MarkerArray``: each envelope's outline, base_link
                             coloured and namespaced by margin tier
``/safety/path``             ``nav_msgs/Path``                         odom
``/safety/costmap``          ``nav_msgs/OccupancyGrid`` (100 marked),  base_link
                             cropped to the marked cells
``/safety/command``          ``geometry_msgs/TwistStamped``            base_link
``/safety/verdicts``         ``diagnostic_msgs/DiagnosticArray``: one
                             status per verdict (OK PROCEED, WARN
                             SLOW, ERROR STOP)
``/safety/record``           ``std_msgs/String``: the cycle's audit
                             record body as JSON
============================ ========================================= ==============

The file is a ROS 2 bag's MCAP storage written by rosbags (schemas embedded, CDR encoding):
Foxglove opens it directly, and so does rosbags' ``AnyReader``. ``/safety/record`` holds
exactly what the audit log's record of the cycle holds (:meth:`CycleRecord.body`), so the file
can be checked against the log record by record (:func:`safety.foxglove_view.
compare_with_audit`). Marker arrays start with DELETEALL, so a viewer shows one cycle at a
time. What a cycle shows is a :class:`~safety.foxglove_scene.CycleScene`.
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from pipeline.types import Action, Scan
from safety.foxglove_scene import CycleScene

__all__ = ["TOPICS", "McapRecorder"]

TOPICS: dict[str, str] = {
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
_TIER_NAMES = ("high", "medium", "near_reversal")
_TIER_RGBA = ((0.2, 0.7, 0.2, 0.9), (0.95, 0.6, 0.1, 0.9), (0.85, 0.1, 0.1, 0.9))
_LEVEL = {Action.PROCEED: 0, Action.SLOW: 1, Action.STOP: 2}


class McapRecorder:
    """Writes :class:`CycleScene` s to the MCAP file ``path`` (module docstring). Use as a
    context manager; refuses to overwrite an existing file. The file appears complete at
    ``path`` when the recorder closes (it is assembled in a temporary folder beside it)."""

    def __init__(self, path: Path) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"{self.path}: exists; choose a new file for the recording")
        self._tmp = Path(tempfile.mkdtemp(prefix=".mcap-", dir=self.path.parent))
        self._store = get_typestore(Stores.ROS2_HUMBLE)
        self._writer: Any = Writer(self._tmp / "run", version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._conn = {
            topic: self._writer.add_connection(topic, msgtype, typestore=self._store)
            for topic, msgtype in TOPICS.items()
        }
        self.cycles = 0

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Finish the file and move it to ``path``."""
        if self._writer is None:
            return
        self._writer.close()
        self._writer = None
        (written,) = (self._tmp / "run").glob("*.mcap")
        written.replace(self.path)
        shutil.rmtree(self._tmp, ignore_errors=True)

    def write(self, scene: CycleScene) -> None:
        """Every topic's message of one cycle."""
        stamp_ns = round(scene.stamp_s * 1e9)
        for topic, msg in self._messages(scene):
            data = self._store.serialize_cdr(msg, TOPICS[topic])
            self._writer.write(self._conn[topic], stamp_ns, data)
        self.cycles += 1

    # -- messages ----------------------------------------------------------------------
    def _t(self, name: str) -> Any:
        return self._store.types[name]

    def _header(self, stamp_s: float, frame: str) -> Any:
        sec = math.floor(stamp_s)
        stamp = self._t("builtin_interfaces/msg/Time")(
            sec=sec, nanosec=min(round((stamp_s - sec) * 1e9), 999_999_999)
        )
        return self._t("std_msgs/msg/Header")(stamp=stamp, frame_id=frame)

    def _quaternion(self, yaw: float) -> Any:
        return self._t("geometry_msgs/msg/Quaternion")(
            x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)
        )

    def _point(self, x: float, y: float) -> Any:
        return self._t("geometry_msgs/msg/Point")(x=float(x), y=float(y), z=0.0)

    def _pose(self, x: float, y: float, yaw: float) -> Any:
        return self._t("geometry_msgs/msg/Pose")(
            position=self._point(x, y), orientation=self._quaternion(yaw)
        )

    def _transform(self, stamp_s: float, parent: str, child: str, pose: tuple[float, ...]) -> Any:
        x, y, yaw = pose
        return self._t("geometry_msgs/msg/TransformStamped")(
            header=self._header(stamp_s, parent),
            child_frame_id=child,
            transform=self._t("geometry_msgs/msg/Transform")(
                translation=self._t("geometry_msgs/msg/Vector3")(x=float(x), y=float(y), z=0.0),
                rotation=self._quaternion(yaw),
            ),
        )

    def _marker(self, scene: CycleScene, frame: str, ns: str, ident: int, kind: int) -> Any:
        t = self._t
        zero = t("geometry_msgs/msg/Vector3")(x=0.0, y=0.0, z=0.0)
        return t("visualization_msgs/msg/Marker")(
            header=self._header(scene.stamp_s, frame),
            ns=ns,
            id=ident,
            type=kind,
            action=0,
            pose=self._pose(0.0, 0.0, 0.0),
            scale=zero,
            color=t("std_msgs/msg/ColorRGBA")(r=1.0, g=1.0, b=1.0, a=1.0),
            lifetime=t("builtin_interfaces/msg/Duration")(sec=0, nanosec=0),
            frame_locked=False,
            points=[],
            colors=[],
            texture_resource="",
            texture=t("sensor_msgs/msg/CompressedImage")(
                header=self._header(0.0, ""), format="", data=np.zeros(0, np.uint8)
            ),
            uv_coordinates=[],
            text="",
            mesh_resource="",
            mesh_file=t("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, np.uint8)),
            mesh_use_embedded_materials=False,
        )

    def _markers(self, scene: CycleScene, frame: str, markers: list[Any]) -> Any:
        clear = self._marker(scene, frame, "", 0, 0)
        clear.action = 3  # DELETEALL: a viewer shows this cycle's markers only
        return self._t("visualization_msgs/msg/MarkerArray")(markers=[clear, *markers])

    def _rgba(self, rgba: tuple[float, float, float, float]) -> Any:
        return self._t("std_msgs/msg/ColorRGBA")(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])

    def _scale(self, x: float, y: float, z: float) -> Any:
        return self._t("geometry_msgs/msg/Vector3")(x=x, y=y, z=z)

    def _messages(self, scene: CycleScene) -> list[tuple[str, Any]]:
        return [
            ("/tf", self._tf(scene)),
            *([] if scene.scan is None else [("/scan", self._scan(scene, scene.scan))]),
            ("/perception/points", self._points(scene)),
            ("/perception/tracks", self._tracks(scene)),
            ("/safety/envelopes", self._envelopes(scene)),
            ("/safety/path", self._path(scene)),
            *([] if scene.occupied is None else [("/safety/costmap", self._costmap(scene))]),
            ("/safety/command", self._command(scene)),
            ("/safety/verdicts", self._verdicts(scene)),
            ("/safety/record", self._t("std_msgs/msg/String")(data=json.dumps(scene.record))),
        ]

    def _tf(self, scene: CycleScene) -> Any:
        return self._t("tf2_msgs/msg/TFMessage")(
            transforms=[
                self._transform(scene.stamp_s, "odom", "base_link", scene.robot_pose),
                self._transform(scene.stamp_s, "base_link", "laser", scene.mount),
            ]
        )

    def _scan(self, scene: CycleScene, scan: Scan) -> Any:
        angles = scan.angles_rad
        ranges = np.nan_to_num(scan.ranges_m, nan=np.inf)
        step = 0.0
        if scan.n_beams > 1:
            # LaserScan puts beam i at angle_min + i * angle_increment. Each beam goes to the
            # nearest point of a grid at the median spacing, so the beams of dropped frames stay
            # a gap (no return) and later beams keep their direction; where two beams meet one
            # point the nearer return is kept. A scan whose angles turn back (not one sweep) is
            # written beam by beam as it came.
            step = float(np.median(np.diff(angles)))
            index = np.rint((angles - angles[0]) / step).astype(np.int64) if step else None
            if index is not None and np.all(np.diff(index) >= 0):
                grid = np.full(int(index[-1]) + 1, np.inf)
                np.minimum.at(grid, index, ranges)
                ranges = grid
        first = float(angles[0]) if scan.n_beams else 0.0
        return self._t("sensor_msgs/msg/LaserScan")(
            header=self._header(scan.stamp_s, "laser"),
            angle_min=first,
            angle_max=first + step * max(ranges.shape[0] - 1, 0),
            angle_increment=step,
            time_increment=float(scan.beam_period_s),
            scan_time=float(scan.beam_period_s * max(ranges.shape[0] - 1, 0)),
            range_min=0.0,
            range_max=float(np.nanmax(scan.ranges_m, initial=0.0)),
            ranges=ranges.astype(np.float32),
            intensities=np.zeros(0, dtype=np.float32),
        )

    def _points(self, scene: CycleScene) -> Any:
        t = self._t
        n = scene.point_labels.shape[0]
        cloud = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("cluster", "<f4")])
        cloud["x"], cloud["y"] = scene.points_xy_m[0], scene.points_xy_m[1]
        cloud["cluster"] = scene.point_labels
        fields = [
            t("sensor_msgs/msg/PointField")(name=name, offset=4 * k, datatype=7, count=1)
            for k, name in enumerate(("x", "y", "z", "cluster"))  # datatype 7: FLOAT32
        ]
        return t("sensor_msgs/msg/PointCloud2")(
            header=self._header(scene.stamp_s, "base_link"),
            height=1,
            width=n,
            fields=fields,
            is_bigendian=False,
            point_step=16,
            row_step=16 * n,
            data=cloud.view(np.uint8),
            is_dense=True,
        )

    def _tracks(self, scene: CycleScene) -> Any:
        markers = []
        for i, ident in enumerate(scene.track_id.tolist()):
            x, y = (float(v) for v in scene.track_xy_m[:, i])
            vx, vy = (float(v) for v in scene.track_v_mps[:, i])
            disc = self._marker(scene, "odom", "bodies", ident, 3)  # CYLINDER
            disc.pose = self._pose(x, y, 0.0)
            d = 2.0 * float(scene.track_radius_m[i])
            disc.scale = self._scale(d, d, 0.1)
            disc.color = self._rgba((0.2, 0.4, 0.9, 0.5))
            arrow = self._marker(scene, "odom", "velocity", ident, 0)  # ARROW
            arrow.points = [self._point(x, y), self._point(x + vx, y + vy)]
            arrow.scale = self._scale(0.05, 0.1, 0.1)
            arrow.color = self._rgba((0.2, 0.4, 0.9, 1.0))
            label = self._marker(scene, "odom", "labels", ident, 9)  # TEXT_VIEW_FACING
            label.pose = self._pose(x, y + 0.4, 0.0)
            label.scale = self._scale(0.0, 0.0, 0.25)
            name = scene.track_class[i] or "unscored"
            label.text = f"{ident} {name} {math.hypot(vx, vy):.1f} m/s"
            markers += [disc, arrow, label]
        return self._markers(scene, "odom", markers)

    def _envelopes(self, scene: CycleScene) -> Any:
        markers = []
        for i, outline in enumerate(scene.envelopes):
            tier = int(scene.envelope_tier[i])
            name = _TIER_NAMES[tier] if 0 <= tier < len(_TIER_NAMES) else f"tier {tier}"
            marker = self._marker(scene, "base_link", f"envelope {name}", i, 4)  # LINE_STRIP
            marker.scale = self._scale(0.03, 0.0, 0.0)
            marker.color = self._rgba(_TIER_RGBA[min(max(tier, 0), 2)])
            ring = np.vstack([outline, outline[:1]])
            marker.points = [self._point(x, y) for x, y in ring]
            marker.text = f"track {int(scene.envelope_track[i])}"
            markers.append(marker)
        return self._markers(scene, "base_link", markers)

    def _path(self, scene: CycleScene) -> Any:
        poses = [
            self._t("geometry_msgs/msg/PoseStamped")(
                header=self._header(scene.stamp_s, "odom"), pose=self._pose(x, y, 0.0)
            )
            for x, y in scene.path_xy_m
        ]
        return self._t("nav_msgs/msg/Path")(header=self._header(scene.stamp_s, "odom"), poses=poses)

    def _costmap(self, scene: CycleScene) -> Any:
        assert scene.occupied is not None
        occupied, (x0, y0) = _cropped(
            scene.occupied, scene.costmap_origin_m, scene.costmap_resolution_m
        )
        rows, cols = occupied.shape
        info = self._t("nav_msgs/msg/MapMetaData")(
            map_load_time=self._header(scene.stamp_s, "").stamp,
            resolution=float(scene.costmap_resolution_m),
            width=cols,
            height=rows,
            origin=self._pose(x0, y0, 0.0),
        )
        # OccupancyGrid is row-major from the origin with x fastest: rows along y, as here.
        data = np.where(occupied, 100, 0).astype(np.int8).ravel()
        return self._t("nav_msgs/msg/OccupancyGrid")(
            header=self._header(scene.stamp_s, "base_link"), info=info, data=data
        )

    def _command(self, scene: CycleScene) -> Any:
        t = self._t
        zero = t("geometry_msgs/msg/Vector3")(x=0.0, y=0.0, z=0.0)
        linear = t("geometry_msgs/msg/Vector3")(x=float(scene.speed_mps), y=0.0, z=0.0)
        return t("geometry_msgs/msg/TwistStamped")(
            header=self._header(scene.stamp_s, "base_link"),
            twist=t("geometry_msgs/msg/Twist")(linear=linear, angular=zero),
        )

    def _verdicts(self, scene: CycleScene) -> Any:
        t = self._t
        command = t("diagnostic_msgs/msg/DiagnosticStatus")(
            level=_LEVEL[scene.action],
            name="command",
            message=f"{scene.action.value} {scene.speed_mps:.2f} m/s",
            hardware_id="safecase",
            values=[
                t("diagnostic_msgs/msg/KeyValue")(key="reason", value=reason)
                for reason in scene.reasons
            ],
        )
        statuses = [
            t("diagnostic_msgs/msg/DiagnosticStatus")(
                level=_LEVEL[action],
                name=monitor,
                message=reason or action.value,
                hardware_id="safecase",
                values=[],
            )
            for monitor, action, reason in scene.verdicts
        ]
        return t("diagnostic_msgs/msg/DiagnosticArray")(
            header=self._header(scene.stamp_s, "base_link"), status=[command, *statuses]
        )


def _cropped(
    occupied: np.ndarray[Any, np.dtype[np.bool_]], origin_m: tuple[float, float], cell_m: float
) -> tuple[np.ndarray[Any, np.dtype[np.bool_]], tuple[float, float]]:
    """The smallest part of the grid holding every marked cell (one free cell when none is
    marked) and its origin: the marked cells are the costmap's content, and a 20 m grid at
    5 cm is 160 kB a cycle when written whole."""
    rows = np.flatnonzero(occupied.any(axis=1))
    cols = np.flatnonzero(occupied.any(axis=0))
    if rows.size == 0:
        return occupied[:1, :1], origin_m
    r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    return occupied[r0:r1, c0:c1], (origin_m[0] + c0 * cell_m, origin_m[1] + r0 * cell_m)
