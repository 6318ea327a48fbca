"""A run's MCAP recording read back: its records checked against the audit log, and one cycle
drawn with matplotlib, what Foxglove's 3-D panel shows, from the file alone (SR-RUN-7).

:func:`read_cycle` reads the messages of the cycle nearest a time (every topic of
:data:`safety.foxglove.TOPICS` at one stamp); :func:`cycle_figure` draws them in the tracking
frame (odom): scan points, clusters, track bodies with velocity and label, envelopes by margin
tier, the path, the costmap's marked cells and the command with its reasons.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle

__all__ = ["compare_with_audit", "cycle_figure", "cycle_stamps", "read_cycle", "read_records"]

_TIER_COLOURS = {"high": "tab:green", "medium": "tab:orange", "near_reversal": "tab:red"}


def _reader(path: Path) -> Any:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


def cycle_stamps(path: Path) -> list[int]:
    """The stamps [ns] of the recording's cycles (one ``/safety/record`` each), in order."""
    with _reader(path) as reader:
        chosen = [c for c in reader.connections if c.topic == "/safety/record"]
        return [stamp for _, stamp, _ in reader.messages(connections=chosen)]


def read_cycle(path: Path, at_s: float | None = None) -> dict[str, Any]:
    """Every message of the cycle whose stamp is nearest ``at_s`` (the last cycle when None),
    by topic."""
    stamps = cycle_stamps(path)
    if not stamps:
        raise ValueError(f"{path}: no cycle recorded")
    wanted = stamps[-1] if at_s is None else round(at_s * 1e9)
    stamp = min(stamps, key=lambda s: abs(s - wanted))
    out: dict[str, Any] = {}
    with _reader(path) as reader:
        for connection, _, raw in reader.messages(start=stamp, stop=stamp + 1):
            out[connection.topic] = reader.deserialize(raw, connection.msgtype)
    out["stamp_s"] = stamp * 1e-9
    return out


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _pose(transform: Any) -> tuple[float, float, float]:
    t = transform.transform
    return float(t.translation.x), float(t.translation.y), _yaw(t.rotation)


def _to_odom(
    pose: tuple[float, float, float], x: np.ndarray[Any, Any], y: np.ndarray[Any, Any]
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    px, py, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return px + c * x - s * y, py + s * x + c * y


def _compose(
    a: tuple[float, float, float], b: tuple[float, float, float]
) -> tuple[float, float, float]:
    x, y = _to_odom(a, np.array([b[0]]), np.array([b[1]]))
    return float(x[0]), float(y[0]), a[2] + b[2]


def _markers(msg: Any, ns_prefix: str) -> Iterable[Any]:
    return [m for m in msg.markers if m.action == 0 and m.ns.startswith(ns_prefix)]


def cycle_figure(cycle: dict[str, Any]) -> Figure:
    """The cycle of :func:`read_cycle` drawn in the odom frame."""
    frames = {t.child_frame_id: _pose(t) for t in cycle["/tf"].transforms}
    robot = frames["base_link"]
    laser = _compose(robot, frames["laser"])
    fig, ax = plt.subplots(figsize=(8, 8))
    grid = cycle.get("/safety/costmap")
    if grid is not None:
        info = grid.info
        cells = np.asarray(grid.data).reshape(info.height, info.width) > 0
        rows, cols = np.nonzero(cells)
        r = info.resolution
        cx = info.origin.position.x + (cols + 0.5) * r
        cy = info.origin.position.y + (rows + 0.5) * r
        ox, oy = _to_odom(robot, cx, cy)
        ax.scatter(ox, oy, s=2, marker="s", color="0.85", label="costmap (marked)", zorder=1)
    scan = cycle.get("/scan")
    if scan is not None:
        ranges = np.asarray(scan.ranges, dtype=float)
        angles = scan.angle_min + scan.angle_increment * np.arange(ranges.size)
        ok = np.isfinite(ranges)
        sx, sy = _to_odom(laser, ranges[ok] * np.cos(angles[ok]), ranges[ok] * np.sin(angles[ok]))
        ax.scatter(sx, sy, s=1, color="0.4", label="scan", zorder=2)
    cloud = cycle["/perception/points"]
    points = np.frombuffer(
        bytes(cloud.data), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("cluster", "<f4")]
    )
    clustered = points["cluster"] >= 0
    px, py = _to_odom(robot, points["x"][clustered], points["y"][clustered])
    ax.scatter(
        px, py, s=4, c=points["cluster"][clustered], cmap="tab20", label="clusters", zorder=3
    )
    for marker in _markers(cycle["/safety/envelopes"], "envelope"):
        xy = np.array([(p.x, p.y) for p in marker.points])
        ex, ey = _to_odom(robot, xy[:, 0], xy[:, 1])
        ax.plot(ex, ey, color=_TIER_COLOURS.get(marker.ns.split(" ", 1)[1], "k"), lw=1.2)
    for marker in _markers(cycle["/perception/tracks"], "bodies"):
        p = marker.pose.position
        ax.add_patch(Circle((p.x, p.y), marker.scale.x / 2, color="tab:blue", alpha=0.3))
    for marker in _markers(cycle["/perception/tracks"], "velocity"):
        a, b = marker.points
        ax.annotate("", (b.x, b.y), (a.x, a.y), arrowprops={"arrowstyle": "->", "color": "b"})
    for marker in _markers(cycle["/perception/tracks"], "labels"):
        p = marker.pose.position
        ax.text(p.x, p.y, marker.text, fontsize=6, color="tab:blue", clip_on=True)
    path = np.array([(p.pose.position.x, p.pose.position.y) for p in cycle["/safety/path"].poses])
    if path.size:
        ax.plot(path[:, 0], path[:, 1], "k--", lw=1, label="path ahead")
    ax.plot(*robot[:2], marker=(3, 0, math.degrees(robot[2]) - 90), ms=12, color="k")
    record = json.loads(cycle["/safety/record"].data)
    command = record["command"]
    why = "; ".join(command.get("reasons", [])[:2])
    ax.set_title(
        f"t = {cycle['stamp_s']:.2f} s: {command['action']} {command['speed_mps']:.2f} m/s"
        + (f"\n{why}" if why else ""),
        fontsize=9,
    )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (odom)")
    ax.set_ylabel("y [m] (odom)")
    ax.legend(loc="upper right", fontsize=7)
    x0, y0 = robot[0], robot[1]
    ax.set_xlim(x0 - 4.0, x0 + 14.0)
    ax.set_ylim(y0 - 9.0, y0 + 9.0)
    fig.tight_layout()
    return fig


def read_records(path: Path) -> list[dict[str, Any]]:
    """The ``/safety/record`` bodies of an MCAP file written by :class:`McapRecorder`, in
    order (what a test compares with the audit log)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out = []
    with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        chosen = [c for c in reader.connections if c.topic == "/safety/record"]
        for connection, _, raw in reader.messages(connections=chosen):
            message: Any = reader.deserialize(raw, connection.msgtype)
            out.append(json.loads(message.data))
    return out


def compare_with_audit(mcap: Path, audit: Path) -> list[str]:
    """Where the recording ``mcap`` and the audit log ``audit`` of the same run disagree:
    each cycle's ``/safety/record`` must equal the log's cycle record (without its chain
    fields) in the same order, and both must hold the same number of cycles. The log must
    verify INTACT first (:func:`safety.audit.verify.verify_log`; otherwise that is the one
    problem). Empty when they agree (SR-RUN-7)."""
    from safety.audit.verify import iter_records, verify_log

    checked = verify_log(audit)
    if not checked.ok:
        return [f"{audit}: {checked.describe()}"]
    upto = checked.n_records + 1  # every line: the records and the close record
    cycles = [
        {k: v for k, v in record.items() if k not in ("kind", "seq", "prev", "hash")}
        for _, record in iter_records(audit, upto)
        if record.get("kind") == "cycle"
    ]
    recorded = read_records(mcap)
    differ = [n for n, (a, b) in enumerate(zip(recorded, cycles, strict=False)) if a != b]
    problems = [f"cycle {n}: the recording's record differs from the audit log's" for n in differ]
    if len(problems) > 5:
        problems[5:] = [f"and {len(differ) - 5} more cycles differ"]
    if len(recorded) != len(cycles):
        problems.append(f"{len(recorded)} cycles recorded, {len(cycles)} in the audit log")
    return problems
