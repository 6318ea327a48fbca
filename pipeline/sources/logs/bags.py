"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP) and bare MCAP files, read with rosbags' AnyReader.

One reader for every bag format (:class:`rosbags.highlevel.AnyReader`), so a log recorded on
ROS 1 or ROS 2 replays the same way. Scans come from one ``sensor_msgs/LaserScan`` topic:
angles from ``angle_min + i * angle_increment``, ``beam_period_s`` from ``time_increment``,
the stamp from the message header. Odometry comes from one ``nav_msgs/Odometry`` topic (the
pose's position and the yaw of its orientation quaternion, stamped by its header) or from a
``tf2_msgs/TFMessage`` topic (``/tf``): the transforms from ``odom`` to the robot's base frame
(``base_footprint``, else ``base_link``), each stamped by its own header; frame names are
compared without a leading slash (ROS 1 writes ``/odom``). :func:`find_odometry` picks the
source a bag offers when none is named. A bag that
rosbags cannot open or decode raises :class:`~pipeline.sources.logs.text.LogFormatError` naming
the file and what went wrong, never rosbags' own error.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.sources.logs.text import LogFormatError
from pipeline.types import FloatArray, Scan

__all__ = [
    "BASE_FRAMES",
    "LASERSCAN",
    "ODOMETRY",
    "ODOM_FRAME",
    "TFMESSAGE",
    "find_odometry",
    "is_bag",
    "laserscan_topics",
    "odometry_topics",
    "read_bag",
    "read_odometry",
]

LASERSCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TFMESSAGE = "tf2_msgs/msg/TFMessage"
ODOM_FRAME = "odom"
BASE_FRAMES = ("base_footprint", "base_link")  # the robot's planar pose, in this preference


def is_bag(path: Path) -> bool:
    """True for a ROS 1 bag, a bare MCAP file or a ROS 2 bag folder (``metadata.yaml``)."""
    return path.suffix in (".bag", ".mcap") or (path / "metadata.yaml").is_file()


@contextmanager
def _reader(path: Path) -> Iterator[Any]:
    """An open AnyReader on ``path``; rosbags' errors become :class:`LogFormatError`."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if not path.exists():
        raise LogFormatError(f"{path}: no such file or folder")
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises many types; all mean "not a readable bag"
        raise LogFormatError(f"{path}: not a readable bag ({type(exc).__name__}: {exc})") from None
    try:
        yield reader
    finally:
        reader.close()


def _topics(path: Path, msgtype: str) -> list[str]:
    with _reader(path) as reader:
        return sorted({c.topic for c in reader.connections if c.msgtype == msgtype})


def laserscan_topics(path: Path | str) -> list[str]:
    """The topics of a bag that carry ``sensor_msgs/LaserScan`` messages."""
    return _topics(Path(path), LASERSCAN)


def odometry_topics(path: Path | str) -> list[str]:
    """The topics of a bag that carry ``nav_msgs/Odometry`` messages."""
    return _topics(Path(path), ODOMETRY)


def tf_topics(path: Path | str) -> list[str]:
    """The topics of a bag that carry ``tf2_msgs/TFMessage`` messages."""
    return _topics(Path(path), TFMESSAGE)


def _topic_types(path: Path) -> dict[str, str]:
    with _reader(path) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def find_odometry(path: Path | str) -> str | None:
    """The odometry topic of a bag when none is named: its only ``nav_msgs/Odometry`` topic,
    else its ``/tf`` topic when that holds ``odom`` to base-frame transforms, else None. Two
    Odometry topics are ambiguous: a :class:`LogFormatError` asks for one to be named."""
    file = Path(path)
    odometry = odometry_topics(file)
    if len(odometry) > 1:
        raise LogFormatError(
            f"{file}: {len(odometry)} Odometry topics {odometry}; name one with --odom-topic"
        )
    if odometry:
        return odometry[0]
    for topic in tf_topics(file):
        if read_tf_odometry(file, topic).shape[0] >= 2:
            return topic
    return None


def _choose(path: Path, topics: list[str], topic: str | None, what: str) -> str:
    if topic is None:
        if len(topics) != 1:
            raise LogFormatError(
                f"{path}: {len(topics)} {what} topics {topics}; expected exactly one, or name one"
            )
        return topics[0]
    if topic not in topics:
        raise LogFormatError(f"{path}: no {what} topic {topic!r}; found {topics}")
    return topic


def _messages(path: Path, msgtype: str, topic: str | None, what: str) -> Iterator[tuple[int, Any]]:
    """(index, message) of one topic of ``msgtype``, in recording order."""
    with _reader(path) as reader:
        topics = sorted({c.topic for c in reader.connections if c.msgtype == msgtype})
        chosen_topic = _choose(path, topics, topic, what)
        chosen = [c for c in reader.connections if c.topic == chosen_topic]
        try:
            for index, (connection, _, raw) in enumerate(reader.messages(connections=chosen)):
                yield index, reader.deserialize(raw, connection.msgtype)
        except LogFormatError:
            raise
        except Exception as exc:
            raise LogFormatError(
                f"{path}: {chosen_topic}: unreadable message ({type(exc).__name__}: {exc})"
            ) from None


def _stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def read_bag(path: Path | str, topic: str | None = None) -> Iterator[Scan]:
    """Scans of one LaserScan topic of a bag (the only one when ``topic`` is None)."""
    file = Path(path)
    for index, msg in _messages(file, LASERSCAN, topic, "LaserScan"):
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        n = ranges.shape[0]
        if not (math.isfinite(msg.angle_min) and math.isfinite(msg.angle_increment)):
            raise LogFormatError(f"{file}: message {index}: non-finite angle_min/increment")
        intensities = np.asarray(msg.intensities, dtype=np.float64)
        yield Scan(
            stamp_s=_stamp_s(msg),
            angles_rad=msg.angle_min + msg.angle_increment * np.arange(n),
            ranges_m=ranges,
            intensities=intensities if intensities.shape[0] == n else None,
            beam_period_s=max(float(msg.time_increment), 0.0),
            seq=int(getattr(msg.header, "seq", index)),
            source=f"{file.name}:{topic or ''}".rstrip(":"),
        )


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def read_odometry(path: Path | str, topic: str | None = None) -> FloatArray:
    """Odometry of a bag as an (n, 4) array ``[stamp_s, x_m, y_m, yaw_rad]``, in recording
    order: from ``topic`` (an Odometry or a TFMessage topic), or the only Odometry topic when
    ``topic`` is None."""
    file = Path(path)
    if topic is not None and _topic_types(file).get(topic) == TFMESSAGE:
        return read_tf_odometry(file, topic)
    rows = []
    for _, msg in _messages(file, ODOMETRY, topic, "Odometry"):
        p = msg.pose.pose.position
        rows.append((_stamp_s(msg), float(p.x), float(p.y), _yaw(msg.pose.pose.orientation)))
    out: FloatArray = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return out


def read_tf_odometry(path: Path | str, topic: str = "/tf") -> FloatArray:
    """The robot's pose from the transforms of a TFMessage topic, as :func:`read_odometry`:
    ``odom`` to ``base_footprint`` when the topic has any, else ``odom`` to ``base_link``.
    A TF topic without either gives an empty array."""
    file = Path(path)
    rows: dict[str, list[tuple[float, float, float, float]]] = {b: [] for b in BASE_FRAMES}
    for _, msg in _messages(file, TFMESSAGE, topic, "TFMessage"):
        for tf in msg.transforms:
            child = tf.child_frame_id.lstrip("/")
            if tf.header.frame_id.lstrip("/") == ODOM_FRAME and child in rows:
                p = tf.transform.translation
                rows[child].append(
                    (_stamp_s(tf), float(p.x), float(p.y), _yaw(tf.transform.rotation))
                )
    chosen = next((rows[b] for b in BASE_FRAMES if rows[b]), [])
    out: FloatArray = np.array(chosen, dtype=np.float64).reshape(-1, 4)
    return out
