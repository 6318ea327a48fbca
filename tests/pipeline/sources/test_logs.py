"""Recorded logs as sources: every format, odometry poses, the stamp rule, bad files (SR-TRK-5)."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.config import default_config
from pipeline.sources.logs.bags import (
    find_odometry,
    laserscan_topics,
    odometry_topics,
    read_bag,
    read_odometry,
)
from pipeline.sources.logs.source import LogSource, log_kind, poses_at
from pipeline.sources.logs.stamps import LogStampError, StampRule, check_stamps
from pipeline.sources.logs.text import LogFormatError, read_breezyslam, read_carmen
from properties.log_cases import Drive, drive, write_carmen, write_ros2_bag

DATA = Path(__file__).resolve().parents[2] / "data"
POSITIVE = DATA / "leg_tracker" / "positive_2_extracted.bag"
NEGATIVE = DATA / "leg_tracker" / "negative_2.bag"
CODE = ["pipeline/sources/logs/source.py", "pipeline/sources/logs/bags.py"]
STAMPS = ["pipeline/sources/logs/stamps.py"]


@pytest.fixture(scope="module")
def driven() -> Drive:
    """Four seconds of a moving robot in a warehouse aisle (40 scans, odometry at 20 Hz)."""
    return drive(default_config(), "forklift_pass_by", 2, 4.0)


def test_carmen_flaser_lines_become_scans(tmp_path: Path) -> None:
    log = tmp_path / "x.log.gz"
    with gzip.open(log, "wt") as handle:
        handle.write("PARAM a b\nODOM 1 2 3\n")
        handle.write("FLASER 3 1.0 2.0 81.9 0 0 0 0 0 0 12.5 host 12.5\n")
    (scan,) = list(read_carmen(log))
    assert scan.ranges_m.tolist() == [1.0, 2.0, 81.9]
    assert scan.angles_rad[0] == pytest.approx(-np.pi / 2)
    assert scan.stamp_s == 12.5


def test_a_truncated_carmen_line_names_file_and_line(tmp_path: Path) -> None:
    log = tmp_path / "bad.log"
    log.write_text("FLASER 3 1.0 2.0\n")
    with pytest.raises(LogFormatError, match=r"bad.log:1: bad FLASER line"):
        list(read_carmen(log))


def test_breezyslam_error_codes_become_nan(tmp_path: Path) -> None:
    line = " ".join(["1000000"] + ["0"] * 23 + ["5"] + ["1500"] * 681 + [""])
    dat = tmp_path / "e.dat"
    dat.write_text(line + "\n")
    (scan,) = list(read_breezyslam(dat))
    assert np.isnan(scan.ranges_m[0])
    assert scan.ranges_m[1] == pytest.approx(1.5)
    assert scan.n_beams == 682
    assert scan.stamp_s == pytest.approx(1.0)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_a_ros1_bag_reads_through_anyreader() -> None:
    scans = list(read_bag(POSITIVE))
    assert len(scans) == 83
    assert scans[0].n_beams == 768
    assert np.all(np.diff([s.stamp_s for s in scans]) > 0)
    assert laserscan_topics(NEGATIVE) == ["/left_scan", "/rear_scan", "/right_scan"]
    with pytest.raises(LogFormatError, match="3 LaserScan topics"):
        list(read_bag(NEGATIVE))
    frames = list(LogSource(POSITIVE).frames())
    assert len(frames) == 83
    assert all(f.pose is None for f in frames)  # the bag has no odometry


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_ros2_bag_gives_scans_with_interpolated_odometry_poses(
    tmp_path: Path, driven: Drive, storage: str
) -> None:
    bag = write_ros2_bag(tmp_path / "drive", driven.scans, driven.odometry, storage=storage)  # type: ignore[arg-type]
    assert log_kind(bag) == "bag"
    assert odometry_topics(bag) == ["/odom"]
    source = LogSource(bag, odom_topic="/odom")
    frames = list(source.frames())
    # Odometry starts 13 ms after the first scan: that scan has no pose and is skipped.
    assert source.skipped == {"outside the odometry": 1}
    assert len(frames) == len(driven.scans) - 1
    for frame, truth in zip(frames, driven.poses_at_scans[1:], strict=True):
        assert frame.pose is not None
        # Linear interpolation between 20 Hz odometry of a smooth drive: within 1 mm, 0.1 deg.
        assert np.hypot(frame.pose[0] - truth[0], frame.pose[1] - truth[1]) < 1e-3
        assert abs(frame.pose[2] - truth[2]) < math.radians(0.1)
        assert frame.scan is not None
        assert frame.received_s >= frame.scan.stamp_s
    first = frames[0].scan
    assert first is not None
    np.testing.assert_allclose(
        first.ranges_m, driven.scans[1].ranges_m.astype(np.float32), equal_nan=True
    )
    if storage == "mcap":  # a bare MCAP file reads the same as its folder
        (mcap,) = bag.glob("*.mcap")
        assert len(list(LogSource(mcap, odom_topic="/odom").frames())) == len(frames)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_tf_odometry_gives_the_same_poses_as_the_odometry_topic(
    tmp_path: Path, driven: Drive
) -> None:
    odom = write_ros2_bag(tmp_path / "odom", driven.scans, driven.odometry, storage="mcap")
    tf = write_ros2_bag(
        tmp_path / "tf", driven.scans, driven.odometry, odom_topic="/tf", odometry_as="tf"
    )
    # odom -> base_footprint only: the map -> odom and base_footprint -> base_link transforms
    # beside it in every message are not the robot's pose.
    np.testing.assert_array_equal(read_odometry(tf, "/tf"), read_odometry(odom, "/odom"))
    assert find_odometry(odom) == "/odom"
    assert find_odometry(tf) == "/tf"
    assert find_odometry(POSITIVE) is None  # a bag without odometry: the robot stands
    auto = LogSource(tf, odometry=True)  # what safecase run --log does without --odom-topic
    named = LogSource(odom, odom_topic="/odom")
    poses = [f.pose for f in auto.frames()]
    assert auto.odometry_from == "/tf"
    assert poses == [f.pose for f in named.frames()]
    assert None not in poses
    assert all(f.pose is None for f in LogSource(tf).frames())  # asked for none: none


def test_two_odometry_topics_must_be_named(tmp_path: Path, driven: Drive) -> None:
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    one = write_ros2_bag(tmp_path / "one", driven.scans[:3], driven.odometry[:8])
    two = tmp_path / "two"
    # The same bag with its odometry recorded twice, on /odom and /wheel_odom.
    with Reader(one) as reader, Writer(two, version=9) as writer:
        out = {}
        for c in reader.connections:
            out[c.topic] = writer.add_connection(c.topic, c.msgtype, typestore=store)
        out["/wheel_odom"] = writer.add_connection(
            "/wheel_odom", out["/odom"].msgtype, typestore=store
        )
        for c, stamp, raw in reader.messages():
            writer.write(out[c.topic], stamp, raw)
            if c.topic == "/odom":
                writer.write(out["/wheel_odom"], stamp, raw)
    with pytest.raises(LogFormatError, match=r"2 Odometry topics .*name one with --odom-topic"):
        find_odometry(two)
    with pytest.raises(LogFormatError, match="2 Odometry topics"):
        LogSource(two, odometry=True).check()
    assert LogSource(two, odom_topic="/wheel_odom").check()[1] is not None


def test_odometry_interpolates_unwrapped_yaw_and_leaves_nan_outside() -> None:
    odom = np.array([[0.0, 0.0, 0.0, math.pi - 0.1], [1.0, 1.0, 2.0, -math.pi + 0.1]])
    got = poses_at(odom, np.array([-0.1, 0.5, 1.0, 1.5]))
    assert np.isnan(got[0]).all()
    assert np.isnan(got[3]).all()
    assert got[1, :2].tolist() == [0.5, 1.0]
    assert math.cos(got[1, 2]) == pytest.approx(-1.0)  # through pi, not through 0
    assert got[2, 2] == pytest.approx(math.pi + 0.1)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_a_carmen_log_gives_its_odometry_poses(tmp_path: Path, driven: Drive) -> None:
    log = write_carmen(tmp_path / "drive.log", driven.scans, driven.poses_at_scans)
    frames = list(LogSource(log, odometry=True).frames())
    assert len(frames) == len(driven.scans)
    assert frames[5].pose == pytest.approx(tuple(driven.poses_at_scans[5]), abs=1e-9)
    assert all(f.pose is None for f in LogSource(log).frames())


@pytest.mark.requirement("SR-TRK-5", kind="example", code=STAMPS)
@pytest.mark.parametrize(
    ("stamps", "message"),
    [
        ([5.0, 5.0, 5.1], r"log.bag: scan 1 is stamped 5.0, the same as scan 0"),
        ([0.0, 0.1, 0.2], r"log.bag: scan 0 is stamped 0.0: not a usable time"),
        ([5.0, 5.1, 4.9, 5.3], r"scan 2 is stamped 4.9, 0.2 s before scan 1"),
        ([5.0, 5.1, 7205.1], r"scan 2 is stamped 7205.1, 7200 s after scan 1"),
        ([5.0, math.nan], r"scan 1 is stamped nan"),
    ],
)
def test_unusable_stamps_are_refused_naming_the_file_and_the_first_bad_stamp(
    stamps: list[float], message: str
) -> None:
    with pytest.raises(LogStampError, match=message) as info:
        check_stamps(np.array(stamps), "log.bag")
    assert "--restamp" in str(info.value)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=STAMPS)
def test_restamping_spaces_the_scans_evenly_from_the_first(tmp_path: Path, driven: Drive) -> None:
    poses = driven.poses_at_scans
    scans = list(driven.scans)
    scans[3], scans[4] = scans[4], scans[3]  # recorded out of order
    log = write_carmen(tmp_path / "swapped.log", scans, poses)
    with pytest.raises(LogStampError, match=r"swapped.log: scan 4 is stamped .* before scan 3"):
        list(LogSource(log).frames())
    frames = list(LogSource(log, stamps=StampRule(restamp_hz=10.0)).frames())
    stamps = [f.scan.stamp_s for f in frames if f.scan is not None]
    np.testing.assert_allclose(np.diff(stamps), 0.1, atol=1e-9)
    assert stamps[0] == pytest.approx(driven.scans[0].stamp_s + 1000.0, abs=1e-6)
    with pytest.raises(ValueError, match="restamp rate"):
        StampRule(restamp_hz=0.0)


@pytest.mark.requirement("SR-TRK-5", kind="example", code=CODE)
def test_bad_files_get_the_log_format_error_naming_them(tmp_path: Path) -> None:
    corrupt = tmp_path / "corrupt.bag"
    corrupt.write_bytes(POSITIVE.read_bytes()[:5000])
    with pytest.raises(LogFormatError, match=r"corrupt\.bag"):
        list(read_bag(corrupt))
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 4)
    with pytest.raises(LogFormatError, match=r"garbage\.mcap: not a readable bag"):
        list(read_bag(garbage))
    with pytest.raises(LogFormatError, match=r"missing\.bag: no such file"):
        list(read_bag(tmp_path / "missing.bag"))
    with pytest.raises(LogFormatError, match="unknown log format"):
        LogSource(tmp_path / "scan.csv")
    with pytest.raises(LogFormatError, match="no LaserScan topic '/nope'"):
        list(read_bag(POSITIVE, "/nope"))
