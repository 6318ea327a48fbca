"""Recorded logs written for tests: ROS 2 bags (sqlite3, MCAP) by rosbags' own writer, CARMEN.

The scans and poses come from a simulator run (:func:`drive`), so a log written here is what a
robot driving the scenario would have recorded: LaserScan messages stamped at each scan's first
beam and ``nav_msgs/Odometry`` at twice the scan rate, offset from the scans so that every
scan's pose is an interpolation. Serves SR-TRK-5 (logs as sources).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.types import FloatArray, Scan

__all__ = ["Drive", "drive", "write_carmen", "write_ros2_bag"]


@dataclass(frozen=True)
class Drive:
    """Scans of a simulated drive and the robot's odometry ``[stamp_s, x_m, y_m, yaw_rad]``."""

    scans: list[Scan]
    odometry: FloatArray
    poses_at_scans: FloatArray


def drive(config: SafecaseConfig, scenario: str, seed: int, duration_s: float) -> Drive:
    """A scenario driven at the configured constant speed: its scans and odometry."""
    sim = make_simulation(config, scenario, seed, duration_s)
    sim.command(config.sim.ego_speed_mps)
    scans = []
    while (frame := sim.next_frame()) is not None:
        scans.append(frame.scan)
    period = sim.lidar.spec.scan_period_s
    stamps = np.arange(-0.5 * period, sim.duration_s, 0.5 * period) + 0.013
    stamps = stamps[stamps >= 0.0]
    poses = sim.ego.poses_at(stamps)
    at_scans = sim.ego.poses_at(np.array([s.stamp_s for s in scans]))
    return Drive(scans, np.column_stack([stamps, poses]), at_scans)


def _time(stamp_s: float, typestore: Any) -> Any:
    sec = math.floor(stamp_s)
    return typestore.types["builtin_interfaces/msg/Time"](
        sec=sec, nanosec=round((stamp_s - sec) * 1e9)
    )


def _transform(
    store: Any, stamp_s: float, parent: str, child: str, x: float, y: float, yaw: float
) -> Any:
    """A ``geometry_msgs/TransformStamped`` from ``parent`` to ``child`` (planar)."""
    t = store.types
    return t["geometry_msgs/msg/TransformStamped"](
        header=t["std_msgs/msg/Header"](stamp=_time(stamp_s, store), frame_id=parent),
        child_frame_id=child,
        transform=t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=0.0),
            rotation=t["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)
            ),
        ),
    )


def write_ros2_bag(
    path: Path,
    scans: Sequence[Scan],
    odometry: FloatArray | None = None,
    *,
    storage: Literal["sqlite3", "mcap"] = "sqlite3",
    scan_topic: str = "/scan",
    odom_topic: str = "/odom",
    odometry_as: Literal["odometry", "tf"] = "odometry",
    epoch_s: float = 1.7e9,
) -> Path:
    """A ROS 2 bag at ``path`` (a folder) holding the scans and the odometry, every stamp
    shifted by ``epoch_s`` as a robot's clock would be. ``odometry_as="tf"`` writes the
    odometry as ``tf2_msgs/TFMessage`` on ``odom_topic`` instead, each message holding the
    ``odom`` to ``base_footprint`` transform beside two that must be ignored (``map`` to
    ``odom`` and ``base_footprint`` to ``base_link``)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    messages: list[tuple[float, str, Any]] = []
    for scan in scans:
        angles = scan.angles_rad
        step = float(angles[1] - angles[0]) if scan.n_beams > 1 else 0.0
        msg = t["sensor_msgs/msg/LaserScan"](
            header=t["std_msgs/msg/Header"](
                stamp=_time(scan.stamp_s + epoch_s, store), frame_id="laser"
            ),
            angle_min=float(angles[0]),
            angle_max=float(angles[-1]),
            angle_increment=step,
            time_increment=float(scan.beam_period_s),
            scan_time=0.1,
            range_min=0.05,
            range_max=30.0,
            ranges=np.asarray(scan.ranges_m, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32),
        )
        messages.append((scan.stamp_s + epoch_s, scan_topic, msg))
    for stamp, x, y, yaw in [] if odometry is None else odometry.tolist():
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=t["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)
            ),
        )
        zero = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        msg = t["nav_msgs/msg/Odometry"](
            header=t["std_msgs/msg/Header"](stamp=_time(stamp + epoch_s, store), frame_id="odom"),
            child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                covariance=np.zeros(36),
            ),
        )
        if odometry_as == "tf":
            msg = t["tf2_msgs/msg/TFMessage"](
                transforms=[
                    _transform(store, stamp + epoch_s, "map", "odom", 1.0, -2.0, 0.3),
                    _transform(store, stamp + epoch_s, "odom", "base_footprint", x, y, yaw),
                    _transform(store, stamp + epoch_s, "base_footprint", "base_link", 0, 0, 0),
                ]
            )
        messages.append((stamp + epoch_s, odom_topic, msg))
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connections = {
            scan_topic: writer.add_connection(
                scan_topic, "sensor_msgs/msg/LaserScan", typestore=store
            ),
        }
        if odometry is not None:
            msgtype = "tf2_msgs/msg/TFMessage" if odometry_as == "tf" else "nav_msgs/msg/Odometry"
            connections[odom_topic] = writer.add_connection(odom_topic, msgtype, typestore=store)
        for stamp, topic, msg in sorted(messages, key=lambda m: m[0]):
            data = store.serialize_cdr(msg, msg.__msgtype__)
            writer.write(connections[topic], round(stamp * 1e9), data)
    return path


def write_carmen(path: Path, scans: Sequence[Scan], poses: FloatArray) -> Path:
    """A CARMEN log of FLASER lines (180 degree scans resampled to 181 beams), one per scan,
    with the robot's odometry pose of each scan."""
    lines = ["# written by properties/log_cases.py", "PARAM robot_front_laser_max 30.0"]
    wanted = np.linspace(-math.pi / 2.0, math.pi / 2.0, 181)
    for scan, pose in zip(scans, poses, strict=True):
        order = np.argsort(scan.angles_rad)
        ranges = np.interp(wanted, scan.angles_rad[order], scan.ranges_m[order])
        ranges = np.where(np.isfinite(ranges), ranges, 81.91)
        x, y, yaw = (float(v) for v in pose)
        numbers = " ".join(f"{r:.3f}" for r in ranges)
        stamp = f"{scan.stamp_s + 1000.0:.6f}"
        lines.append(
            f"FLASER {ranges.shape[0]} {numbers} {x} {y} {yaw} {x} {y} {yaw} {stamp} test {stamp}"
        )
    path.write_text("\n".join(lines) + "\n")
    return path
